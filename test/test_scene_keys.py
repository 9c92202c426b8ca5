"""A scene is read strictly, whichever command reads it: a misspelled key at any depth (a row's
block, a node's own entry, an entry's node name) or a value out of its range is exit 2 and one
line naming the key and the file, and for a misspelling the closest valid key. (It used to be
ignored: `plant_spcing: 0.3` ran at the default 0.2 m and the demo said PASS.)

Each case runs the command line in-process; a scene accepted by mistake cannot start any work:
the demo's --bag names an existing file, analyze's path holds no bag, the optimiser has
0.01 s."""
import re

import pytest

from cli_helpers import REPO
from test_cli_bad_input import assert_one_line_refusal, run

SAMPLE = REPO / 'bags' / 'sample_tomato.mcap'
BASES = {name: (REPO / 'config' / f'{name}.yaml').read_text()
         for name in ('tomato_five_bar', 'tomato_4row', 'rice_three_arm')}


def demo(scene, tmp):
    taken = tmp / 'taken.mcap'
    taken.write_text('')
    return ['demo', '--scene', scene, '--duration', '8', '--bag', taken]


def three_arm(scene, tmp):
    return ['design', 'three-arm', '--params', scene]


def replay(scene, tmp):
    return ['replay', SAMPLE, '--scene', scene]


def optimize(scene, tmp):
    return ['optimize', 'three-arm', '--base', scene, '--max-time', '0.01', '--out',
            tmp / 'out.yaml']


def analyze(scene, tmp):
    (tmp / 'none').mkdir(exist_ok=True)
    return ['analyze', tmp / 'none', '--out', tmp / 'tables', '--scene', scene]


def setting(key, value):
    """Edit: the scene's line `key: ...` (under /**) set to `value`, or added."""
    def edit(text):
        line = re.compile(rf'^(\s+){re.escape(key)}:[^\n]*$', re.M)
        if line.search(text):
            return line.sub(lambda m: f'{m.group(1)}{key}: {value}', text, count=1)
        return text + f'    {key}: {value}\n'
    return edit


def added(text_to_add):
    """Edit: raw YAML added at the end (under /**' parameters when indented by 4)."""
    return lambda text: text + text_to_add


def renamed(old, new):
    """Edit: the first `old` in the file written `new` (a misspelled key, row or entry)."""
    return lambda text: text.replace(old, new, 1)


# (command, base scene, edit, the key the one line must name, the closest valid key or None)
CASES = [
    # misspelled keys under /** (every node's parameters), through the demo
    (demo, 'tomato_five_bar', renamed('plant_spacing:', 'plant_spcing:'), 'plant_spcing',
     'plant_spacing'),
    (demo, 'tomato_five_bar', renamed('planting_depth:', 'planting_dept:'), 'planting_dept',
     'planting_depth'),
    (demo, 'tomato_five_bar', renamed('hole_ratio:', 'hole_ratoi:'), 'hole_ratoi',
     'hole_ratio'),
    (demo, 'tomato_five_bar', renamed('nozzle_width:', 'nozle_width:'), 'nozle_width',
     'nozzle_width'),
    (demo, 'tomato_five_bar', renamed('nominal_ground_speed:', 'nominal_ground_sped:'),
     'nominal_ground_sped', 'nominal_ground_speed'),
    (demo, 'tomato_five_bar', renamed('design_method:', 'design_metod:'), 'design_metod',
     'design_method'),
    (demo, 'tomato_five_bar', renamed('dyad_ratios:', 'dyad_ratio:'), 'dyad_ratio',
     'dyad_ratios'),
    (demo, 'tomato_five_bar', renamed('antenna_position:', 'antena_position:'),
     'antena_position', 'antenna_position'),
    (demo, 'tomato_five_bar', renamed('crop:', 'crops:'), 'crops', 'crop'),
    (demo, 'tomato_five_bar', renamed('mechanism:', 'mechanisms:'), 'mechanisms', 'mechanism'),
    (demo, 'tomato_five_bar', setting('phase_gian', 2.0), 'phase_gian', 'phase_gain'),
    (demo, 'tomato_five_bar', setting('max_acceleraton', 100.0), 'max_acceleraton',
     'max_acceleration'),
    (demo, 'tomato_five_bar', setting('can_bitrat', 250000), 'can_bitrat', 'can_bitrate'),
    (demo, 'tomato_five_bar', setting('windw', 40), 'windw', 'window'),
    (demo, 'tomato_five_bar', setting('upright_treshold', 0.5), 'upright_treshold',
     'upright_threshold'),
    (demo, 'tomato_five_bar', setting('bag_pth', 'x.mcap'), 'bag_pth', 'bag_path'),
    (demo, 'tomato_five_bar', setting('control_perod', 0.02), 'control_perod',
     'control_period'),
    (demo, 'tomato_five_bar', setting('use_sim_tme', 'false'), 'use_sim_tme', 'use_sim_time'),
    # inside a row's block, and the rows themselves
    (demo, 'tomato_4row', renamed('left_outer: {lateral_offset', 'left_outer: {lateral_ofset'),
     'left_outer.lateral_ofset', 'left_outer.lateral_offset'),
    (demo, 'tomato_4row', renamed('drive_node_id: 2', 'drive_nod_id: 2'),
     'left_inner.drive_nod_id', 'left_inner.drive_node_id'),
    (demo, 'tomato_4row', renamed('enabled: true}', 'enable: true}'), 'left_outer.enable',
     'left_outer.enabled'),
    (demo, 'tomato_4row', renamed('    left_outer: {', '    left_outr: {'),
     'left_outr.lateral_offset', 'left_outer.lateral_offset'),
    (demo, 'tomato_4row', renamed('rows: [', 'rowz: ['), 'rowz', 'rows'),
    (demo, 'tomato_five_bar', added('    left: {lateral_offset: 0.5, drive_node_id: 1}\n'),
     'left.lateral_offset', 'rows: [left]'),
    (demo, 'tomato_five_bar', setting('antenna_position', '{x: 2.5, y: 0.0}'),
     'antenna_position.x: antenna_position is a block: allowed a value', None),
    # entries: a node name rcl applies to no planter node, another node's key in a node's own
    (demo, 'tomato_five_bar', added('sync_node:\n  ros__parameters:\n    can_channel: can1\n'),
     'sync_node', '/planter/sync_node'),
    (demo, 'tomato_five_bar',
     added('/planter/sync_nod:\n  ros__parameters:\n    can_channel: can1\n'),
     'sync_nod', '/planter/sync_node'),
    (demo, 'tomato_five_bar',
     added('/planter/sync_node:\n  ros__parameters:\n    plant_spacing: 0.3\n'),
     'plant_spacing', None),
    (demo, 'tomato_five_bar',
     added('/**/design_node:\n  ros__parameters:\n    can_channel: can1\n'),
     'can_channel', None),
    (demo, 'tomato_five_bar',
     added('/planter/monitor_node:\n  ros__parameters:\n    windw: 40\n'),
     'windw is not a parameter of monitor_node', 'window'),
    (demo, 'tomato_five_bar', added('  parameters: {window: 40}\n'),
     'parameters beside ros__parameters', None),
    (demo, 'tomato_five_bar', setting('arm_length', 0.145), 'arm_length', None),
    (demo, 'tomato_five_bar', added('    plant_spacing: 0.3\n'),
     'plant_spacing is given twice', None),
    # the three-arm scene, through design, the optimiser, replay and analyze
    (three_arm, 'rice_three_arm', renamed('control_radii:', 'control_radi:'), 'control_radi',
     'control_radii'),
    (three_arm, 'rice_three_arm', renamed('arm_length:', 'arm_lenght:'), 'arm_lenght',
     'arm_length'),
    (three_arm, 'rice_three_arm', renamed('pusher_offset:', 'pusher_ofset:'), 'pusher_ofset',
     'pusher_offset'),
    (three_arm, 'rice_three_arm', renamed('interpolant:', 'interpolent:'), 'interpolent',
     'interpolant'),
    (three_arm, 'rice_three_arm', renamed('seedling_height:', 'seedling_heigth:'),
     'seedling_heigth', 'seedling_height'),
    (three_arm, 'rice_three_arm', setting('picking_phse', 0.35), 'picking_phse',
     'picking_phase'),
    (optimize, 'rice_three_arm', renamed('carrier_initial_angle:', 'carrier_initial_angel:'),
     'carrier_initial_angel', 'carrier_initial_angle'),
    (optimize, 'rice_three_arm', renamed('planet_carrier_angle:', 'planet_carier_angle:'),
     'planet_carier_angle', 'planet_carrier_angle'),
    (replay, 'tomato_five_bar', renamed('plant_spacing:', 'plant_spcing:'), 'plant_spcing',
     'plant_spacing'),
    (replay, 'tomato_five_bar', renamed('nozzle_width:', 'nozzle_widht:'), 'nozzle_widht',
     'nozzle_width'),
    (analyze, 'tomato_five_bar', renamed('hole_ratio:', 'hole_ration:'), 'hole_ration',
     'hole_ratio'),
    # values out of their range (unit and range from config.py's one table)
    (demo, 'tomato_five_bar', setting('plant_spacing', 5.0), 'plant_spacing = 5', None),
    (demo, 'tomato_five_bar', setting('planting_depth', 0.0), 'planting_depth = 0', None),
    (demo, 'tomato_five_bar', setting('hole_ratio', -1), 'hole_ratio = -1', None),
    (demo, 'tomato_five_bar', setting('nozzle_width', 0.7), 'nozzle_width = 0.7', None),
    (demo, 'tomato_five_bar', setting('nominal_ground_speed', 10), 'nominal_ground_speed = 10',
     None),
    (demo, 'tomato_five_bar', setting('design_method', 'magic'), "design_method = 'magic'",
     None),
    (demo, 'tomato_five_bar', setting('mechanism', 'four_bar'), "mechanism = 'four_bar'", None),
    (demo, 'tomato_five_bar', setting('dyad_ratios', '[1.4, 1.5, 1000]'), 'dyad_ratios', None),
    (demo, 'tomato_five_bar', setting('phase_gain', -1.0), 'phase_gain = -1', None),
    (demo, 'tomato_five_bar', setting('can_bitrate', 5), 'can_bitrate = 5', None),
    (demo, 'tomato_five_bar', setting('window', 0), 'window = 0', None),
    (demo, 'tomato_five_bar', setting('upright_threshold', 2.0), 'upright_threshold = 2', None),
    (demo, 'tomato_five_bar', setting('antenna_position', '[.nan, 0.0]'), 'antenna_position',
     None),
    (demo, 'tomato_five_bar', setting('use_sim_time', 'maybe'), 'use_sim_time', None),
    (demo, 'tomato_five_bar', setting('crop', 12), 'crop = 12', None),
    (demo, 'tomato_4row', renamed('lateral_offset: 0.75', 'lateral_offset: 50'),
     'left_outer.lateral_offset = 50', None),
    (demo, 'tomato_4row', renamed('drive_node_id: 4', 'drive_node_id: 200'),
     'right_outer.drive_node_id = 200', None),
    (demo, 'tomato_4row', renamed('rows: [left_outer, left_inner, right_inner, right_outer]',
                                  'rows: left_outer'), "rows = 'left_outer'", None),
    (three_arm, 'rice_three_arm', setting('arm_length', 5.0), 'arm_length = 5', None),
    (three_arm, 'rice_three_arm', renamed('0.021, 0.028', '-0.021, 0.028'), 'control_radii',
     None),
    (three_arm, 'rice_three_arm', setting('interpolant', 'cubic'), "interpolant = 'cubic'",
     None),
    (replay, 'tomato_five_bar', setting('nozzle_width', -0.1), 'nozzle_width = -0.1', None),
    (optimize, 'rice_three_arm', setting('pusher_offset', 0.9), 'pusher_offset = 0.9', None),
    (analyze, 'tomato_five_bar', setting('max_input_gap', 0), 'max_input_gap = 0', None),
]


def test_the_table_has_sixty_cases_or_more():
    assert len(CASES) >= 60
    assert len({(c[0], c[1], c[3]) for c in CASES}) == len(CASES)      # no case twice


@pytest.mark.parametrize('command, base, edit, key, closest', CASES,
                         ids=[f'{c[0].__name__}-{c[3]}' for c in CASES])
def test_a_bad_scene_key_is_exit_2_naming_the_key_and_the_file(tmp_path, command, base, edit,
                                                                 key, closest):
    scene = tmp_path / 'scene.yaml'
    text = edit(BASES[base])
    assert text != BASES[base]
    scene.write_text(text)
    argv = command(scene, tmp_path)
    code, out, err, caught = run(argv)
    assert_one_line_refusal(argv, code, out, err, caught)
    assert key in err and str(scene) in err, err
    if closest is not None:
        assert f'did you mean `{closest}`?' in err, err
