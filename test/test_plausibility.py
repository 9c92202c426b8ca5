"""Plausibility before work (planter_ros.plausibility): 40+ implausible values, each refused or
warned with the limit (or the typical range) named; the same checks at the command line and in the
scene loader."""
import functools
import math

import pytest

from cli_helpers import REPO, run_planter
from planter_ros.scene import SceneError, load_scene, open_scene
from planter_ros.plausibility import RowLimits, judge

TOMATO = {'mechanism': 'five_bar', 'planting_depth': 0.045, 'plant_spacing': 0.2,
          'hole_ratio': 0.05, 'nominal_ground_speed': 0.2, 'nozzle_width': 0.04}
RICE = {'scene': 'rice_three_arm.yaml'}     # its design_node parameters (read by the test)


@functools.lru_cache
def scene_parameters(name):
    return load_scene(REPO / 'config' / name, 'design_node')


def rows(n, bitrate=None, **extra):
    names = [f'r{i}' for i in range(n)]
    out = {'rows': names, **{f'{r}.lateral_offset': 0.5 * i for i, r in enumerate(names)},
           **{f'{r}.drive_node_id': i + 1 for i, r in enumerate(names)}, **extra}
    if bitrate:
        out['can_bitrate'] = bitrate
    return out


R, W = 'refused', 'warning'
CASES = [
    # ground speed
    ('speed 3 m/s', {'nominal_ground_speed': 3.0}, (), R, 'max_speed = 20 rad/s'),
    ('speed 0.7 m/s', {'nominal_ground_speed': 0.7}, (), R,
     'allowed nominal_ground_speed <= 0.637 m/s'),
    ('speed 5 m/s', {'nominal_ground_speed': 5.0}, (), R, 'allowed number 0.01..3 m/s'),
    ('speed negative', {'nominal_ground_speed': -0.2}, (), R, 'allowed number 0.01..3 m/s'),
    ('speed NaN', {'nominal_ground_speed': math.nan}, (), R, 'allowed number 0.01..3 m/s'),
    ('speed 3 m/s, fast drive', {'nominal_ground_speed': 3.0, 'max_speed': 100.0,
                                 'max_acceleration': 100.0}, (), W, '0.05..1.5 m/s'),
    ('speed 0.02 m/s', {'nominal_ground_speed': 0.02}, (), W, '0.05..1.5 m/s'),
    ('accepted top speed 5 m/s', {'max_ground_speed': 5.0}, (), W, 'above 0.637 m/s'),
    ('accepted top speed 20 m/s', {'max_ground_speed': 20.0}, (), R, '0.1..10 m/s'),
    # the law's and the drives' limits
    ('max_speed 0.5 rad/s', {'max_speed': 0.5}, (), R, 'over max_speed = 0.5 rad/s'),
    ('max_speed 200 rad/s', {'max_speed': 200.0}, (), R, 'allowed number 0.1..100 rad/s'),
    ('max_acceleration 10', {'max_acceleration': 10.0}, (), R,
     'over max_acceleration = 10 rad/s²'),
    ('max_acceleration 0', {'max_acceleration': 0.0}, (), R, 'allowed number 0.1..1000'),
    ('machine file row max_speed 5', {}, (RowLimits('left', max_speed=5.0),), R,
     'max_speed = 5 rad/s (48 r/min) of row left of the machine file'),
    ('machine file motor 100 rad/s at 20:1', {},
     (RowLimits('left', motor_max_speed=100.0, gear_ratio=20.0),), R, 'motor_max_speed = 100'),
    ('machine file row acceleration 5', {}, (RowLimits('left', max_acceleration=5.0),), R,
     'max_acceleration = 5 rad/s² of row left'),
    # depth
    ('depth 0.3 m', {'planting_depth': 0.3}, (), W, '0.01..0.15 m'),
    ('depth 0.6 m', {'planting_depth': 0.6}, (), R, 'allowed number 0.001..0.5 m'),
    ('depth 5 mm', {'planting_depth': 0.005}, (), W, '0.01..0.15 m'),
    ('depth 0', {'planting_depth': 0.0}, (), R, 'allowed number 0.001..0.5 m'),
    ('depth 0.3 m, k = 1', {'planting_depth': 0.3, 'hole_ratio': 1.0}, (), R, 'needs k·D < d'),
    ('depth 0.2 m, k = 1.9', {'planting_depth': 0.2, 'hole_ratio': 1.9}, (), R,
     'needs k·D < d'),
    # spacing
    ('spacing 1 cm', {'plant_spacing': 0.01}, (), R, 'allowed number 0.05..2 m'),
    ('spacing 6 cm', {'plant_spacing': 0.06}, (), R, 'allowed nominal_ground_speed <= 0.191'),
    ('spacing 10 cm', {'plant_spacing': 0.1}, (), R, 'allowed plant_spacing >= 0.157 m'),
    ('spacing 1.5 m', {'plant_spacing': 1.5}, (), W, '0.1..1 m'),
    ('spacing 3 m', {'plant_spacing': 3.0}, (), R, 'allowed number 0.05..2 m'),
    ('rice spacing 5 cm', {**RICE, 'plant_spacing': 0.05}, (), R,
     'needs the carrier at 22.6 rad/s'),
    ('spacing 0.1 m, slow tractor ok but k·D', {'plant_spacing': 0.05, 'planting_depth': 0.1,
                                                'hole_ratio': 0.6}, (), R, 'k·D < d'),
    # CAN bit rate and bus load
    ('4 rows at 125 kbit/s', rows(4, 125_000), (), R, 'allowed <= 70 %'),
    ('1 row at 50 kbit/s', {'can_bitrate': 50_000}, (), R, 'allowed <= 70 %'),
    ('300 kbit/s', {'can_bitrate': 300_000}, (), W, 'not a CiA 301 bit rate'),
    ('2 Mbit/s', {'can_bitrate': 2_000_000}, (), R, 'allowed integer 10000..1000000 bit/s'),
    ('5 kbit/s', {'can_bitrate': 5_000}, (), R, 'allowed integer 10000..1000000 bit/s'),
    ('8 rows, 2 ms control period', rows(8, control_period=0.002), (), R, 'allowed <= 70 %'),
    ('4 rows, 1 ms feedback', rows(4, feedback_period=0.001), (), R, 'allowed <= 70 %'),
    # rows
    ('9 rows at 1 Mbit/s', rows(9, 1_000_000), (), W, 'typically carries 1..8'),
    ('12 rows at 500 kbit/s', rows(12), (), R, 'at most 9 rows fit'),
    ('two rows on one drive', {**rows(2), 'r1.drive_node_id': 1}, (), R,
     'a node id no other row uses'),
    ('row 30 m to the side', {**rows(2), 'r1.lateral_offset': 30.0}, (), R, '-20..20 m'),
    ('row named 1a', {'rows': ['1a']}, (), R, 'starting with a letter'),
    ('drive node id 0', {'drive_node_id': 0}, (), R, 'allowed integer 1..127'),
    # issue 32: where the machine file meets the scene
    ('top speed over the law', {'nominal_ground_speed': 0.45}, (), R,
     'top_ground_speed (0: 1.5 × nominal_ground_speed) = 0.675 m/s needs the sun bar at 21.2'),
    ('top speed given', {'top_ground_speed': 0.7}, (), R,
     'top_ground_speed = 0.7 m/s needs the sun bar at 22 rad/s'),
    ('top speed under nominal', {'top_ground_speed': 0.1}, (), R,
     'allowed 0 or >= nominal_ground_speed = 0.2 m/s'),
    ('gear ratio 1000', {}, (RowLimits('left', motor_max_speed=1047.0, gear_ratio=1000.0),), R,
     'needs the motor (1000 turns per sun bar turn) at 6.28e+03 rad/s (60000 r/min)'),
    ('encoder 1 count per turn', {}, (RowLimits('left', gear_ratio=20.0, encoder_counts=1),),
     R, 'encoder_counts = 1 per motor turn through gear_ratio = 20 is 20 counts per sun bar '
        'turn (18 deg, 10 mm of the row)'),
    ('a drive on the master\'s id', {**rows(2), 'r1.drive_node_id': 127}, (), R,
     "r1.drive_node_id = 127 is the master's own node id (master_node_id = 127)"),
    ('implicit row on the master\'s id', {'drive_node_id': 127}, (), R,
     'allowed 1..127 except drive_node_id=127'),
    ('rice 300 mm deep', {**RICE, 'planting_depth': 0.3}, (), R,
     "planting_depth = 0.3 m is beyond the three-arm's reach: its gearbox would turn 0.223 m "
     'deep in the soil (arm_length = 0.145 m); allowed planting_depth <= 0.077 m'),
    ('two rows on one line', {**rows(2), 'r1.lateral_offset': 0.0}, (), W,
     'rows r0 and r1 have the same lateral_offset = 0 m'),
    ('two rows 20 mm apart', {**rows(2), 'r1.lateral_offset': 0.02}, (), W,
     'rows r0 and r1 are 0.02 m apart'),
    ('a 30 m wide machine', {**rows(2), 'r0.lateral_offset': -15.0, 'r1.lateral_offset': 15.0},
     (), W, 'the rows span 30 m (r0 to r1): unusual, transplanters are typically at most 12 m'),
    ('ground speed timeout 10 s', {'ground_speed_timeout': 10.0}, (), R,
     'ground_speed_timeout = 10 is out of range: allowed number 0.05..2 s'),
]


def test_the_table_holds_at_least_forty_values():
    assert len(CASES) >= 40


@pytest.mark.parametrize('what, values, limits, level, named', CASES,
                         ids=[c[0] for c in CASES])
def test_each_implausible_value_is_refused_or_warned_naming_the_limit(what, values, limits,
                                                                       level, named):
    values = dict(values)
    scene = values.pop('scene', None)
    verdict = judge({**TOMATO, **(scene_parameters(scene) if scene else {}), **values}, limits)
    if level == R:
        assert verdict.refused, verdict
        assert named in verdict.refused[0], verdict.refused
    else:
        assert verdict.refused == [], verdict.refused
        assert any(named in w for w in verdict.warnings), verdict.warnings


@pytest.mark.parametrize('scene', sorted((REPO / 'config').glob('*.yaml')),
                         ids=lambda p: p.name)
def test_the_shipped_scenes_are_plausible_without_a_word(scene):
    s = open_scene(scene)
    assert s.warnings == ()
    assert judge({**s.parameters('design_node'), **s.parameters('sync_node')}).refused == []


def test_design_five_bar_at_3_m_s_is_refused_naming_the_drive_limit():
    out = run_planter('design', 'five-bar', '--depth', 0.045, '--spacing', 0.35, '--speed', 3)
    assert out.returncode == 2 and out.stdout == '' and out.stderr.count('\n') == 1
    assert '514 r/min' in out.stderr and 'max_speed = 20 rad/s' in out.stderr
    assert 'allowed nominal_ground_speed <= 1.11 m/s' in out.stderr


def test_design_five_bar_warns_of_an_unusual_but_possible_speed():
    out = run_planter('design', 'five-bar', '--depth', 0.045, '--spacing', 0.9, '--speed', 1.6,
                      '--json')
    assert out.returncode == 0 and '"sun_bar_speed"' in out.stdout
    assert out.stderr.startswith('planter: warning: nominal_ground_speed = 1.6 m/s is unusual')
    assert '0.05..1.5 m/s' in out.stderr


def test_design_without_a_speed_judges_the_mechanism_only():
    """A design asked without --speed is geometry: no speed or acceleration refusal."""
    out = run_planter('design', 'five-bar', '--depth', 0.045, '--spacing', 0.06)
    assert out.returncode == 0, out.stderr
    assert 'plant_spacing = 0.06 m is unusual' in out.stderr


def scene_file(tmp_path, extra):
    path = tmp_path / 'scene.yaml'
    text = '/**:\n  ros__parameters:\n' + ''.join(
        f'    {k}: {v}\n' for k, v in {**TOMATO, **extra}.items())
    path.write_text(text)
    return path


def test_the_scene_loader_refuses_naming_the_file_and_the_limit(tmp_path):
    path = scene_file(tmp_path, {'can_bitrate': 50_000})
    with pytest.raises(SceneError, match=r'scene file .*scene\.yaml: CAN bus load .* allowed '
                                         r'<= 70 %'):
        open_scene(path)


def test_the_scene_loader_keeps_the_warnings(tmp_path):
    scene = open_scene(scene_file(tmp_path, {'plant_spacing': 1.5}))
    assert len(scene.warnings) == 1 and '0.1..1 m' in scene.warnings[0]


def test_demo_refuses_an_implausible_scene_before_it_starts(tmp_path):
    out = run_planter('demo', '--scene', scene_file(tmp_path, {'nominal_ground_speed': 2.0}))
    assert out.returncode == 2 and out.stderr.count('\n') == 1
    assert 'max_speed = 20 rad/s' in out.stderr and 'Traceback' not in out.stderr


def test_simulate_checks_the_bus_load_of_the_rows_it_builds(tmp_path):
    """16 rows on one 500 kbit/s bus need 115 % of it (the sync node refuses above 70 %):
    refused before any work, nothing written."""
    out = run_planter('simulate', tmp_path / 'season', '--bags', 1, '--rows', 16)
    assert out.returncode == 2 and out.stdout == '' and out.stderr.count('\n') == 1
    assert '--rows = 16: CAN bus load 114.8 % is out of range: allowed <= 70 %' in out.stderr
    assert 'at most 9 rows fit' in out.stderr
    assert not (tmp_path / 'season').exists()
