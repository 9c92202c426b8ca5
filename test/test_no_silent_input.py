"""No silent input (issue 32, item 3): a scene that leaves out a value its design is made of is
told the default it got; a value of the wrong type is refused, not read; an empty `--only`
runs nothing; a recording whose joint positions are unusable says so."""
import dataclasses

import numpy as np
import pytest

from cli_helpers import REPO, run_planter
from planter_ros.scene import SceneError, open_scene
from test_cli_bad_input import assert_one_line_refusal, run


def scene_file(tmp_path, lines, name='scene.yaml'):
    path = tmp_path / name
    path.write_text('/**:\n  ros__parameters:\n' + ''.join(f'    {line}\n' for line in lines))
    return path


def test_a_scene_without_its_depth_names_the_default_it_got(tmp_path):
    scene = open_scene(scene_file(tmp_path, ['plant_spacing: 0.3', 'nozzle_width: 0.04']))
    warnings = '\n'.join(scene.warnings)
    assert ('planting_depth is not set: the design uses the default 0.045 m; set it for the '
            'crop and machine') in warnings
    assert 'mechanism is not set: the design uses the default five_bar' in warnings
    assert 'plant_spacing' not in warnings                # it is set
    assert scene.design().planting_depth == 0.045


def test_simulate_prints_the_defaults_a_scene_got(tmp_path):
    scene = scene_file(tmp_path, ['plant_spacing: 0.3', 'nozzle_width: 0.04'])
    out = run_planter('simulate', tmp_path / 'season', '--bags', 1, '--duration', 10,
                      '--scene', scene, '--workers', 1, timeout=300)
    assert out.returncode == 0, out.stderr
    assert 'planter: warning: planting_depth is not set: the design uses the default 0.045 m' \
        in out.stderr


@pytest.mark.parametrize('line, message', [
    ('plant_spacing: "0.3"', "plant_spacing = '0.3' is text: allowed number 0.05..2 m"),
    ("planting_depth: '0.045'", "planting_depth = '0.045' is text: allowed number 0.001..0.5"),
    ('phase_lock: "true"', "phase_lock = 'true' is text: allowed true or false"),
])
def test_a_number_written_as_text_is_refused_naming_it(tmp_path, line, message):
    with pytest.raises(SceneError) as caught:
        open_scene(scene_file(tmp_path, ['nozzle_width: 0.04', line]))
    assert message in str(caught.value) and '\n' not in str(caught.value)


def test_a_machine_file_number_written_as_text_is_refused():
    from planter_ros.scene.machine import MachineFileError, parse_machine
    text = (REPO / 'config' / 'machines' / 'tomato_4row_tractor.yaml').read_text()
    with pytest.raises(MachineFileError) as caught:
        parse_machine(text.replace('gear_ratio: 20.0', 'gear_ratio: "20"', 1), 'm.yaml')
    assert "gear_ratio = '20' is text: allowed number" in str(caught.value)


@pytest.mark.parametrize('only', ['', '   '])
def test_an_empty_only_runs_no_bench(only):
    argv = ['bench', '--quick', '--only', only]
    code, out, err, caught = run(argv)
    assert_one_line_refusal(argv, code, out, err, caught)
    assert 'is empty: allowed text a case name contains' in err


def test_a_recording_whose_joint_positions_are_all_nan_says_so(tmp_path):
    from planter_ros.recording.replay import replay
    from planter_ros.sim.season import machine_rows, simulate_plan, write_monitor_bag
    from test_simulate import eventful_plan
    plan = eventful_plan(2)
    machine = simulate_plan(plan)
    broken = dataclasses.replace(machine, joint_pos=np.full_like(machine.joint_pos, np.nan))
    write_monitor_bag(broken, tmp_path / 'nan.mcap')
    result = replay(tmp_path / 'nan.mcap')
    assert len(result.plants) == 0
    named = [w for w in result.warnings if 'are NaN: no plant can be predicted' in w]
    assert [w.split(':')[0] for w in named] == [row.name for row in machine_rows(2)]
    assert 'recorded positions of joint row_1/sun_bar' in named[0]
