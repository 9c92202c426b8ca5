"""Scenes are ROS 2 parameter files; every shipped one loads and names its mechanism."""
from pathlib import Path

import pytest

from planter_ros.kinematics.mechanisms import PLANTS_PER_REVOLUTION
from planter_ros.scene import SceneError, load_scene

CONFIG = Path(__file__).resolve().parents[1] / 'config'


@pytest.mark.parametrize('path', sorted(CONFIG.glob('*.yaml')), ids=lambda p: p.name)
def test_shipped_scenes_load(path):
    params = load_scene(path)
    assert params['mechanism'] in PLANTS_PER_REVOLUTION
    assert params['plant_spacing'] > 0 and params['crop']


@pytest.mark.parametrize('entry', ['/planter/sync_node', '/**/sync_node'])
def test_a_nodes_own_entry_overrides_the_wildcard_as_rcl_does(tmp_path, entry):
    f = tmp_path / 's.yaml'
    f.write_text('/**:\n  ros__parameters:\n    can_channel: can0\n    plant_spacing: 0.3\n'
                 f'{entry}:\n  ros__parameters:\n    can_channel: can1\n')
    assert load_scene(f, 'sync_node') == {'can_channel': 'can1', 'plant_spacing': 0.3}
    assert load_scene(f, 'design_node') == {'can_channel': 'can0', 'plant_spacing': 0.3}


@pytest.mark.parametrize('text', ['- 1\n- 2\n', 'x: [unclosed\n', '/**:\n  foo: 1\n'])
def test_bad_scene_files_give_one_line_errors(tmp_path, text):
    f = tmp_path / 'bad.yaml'
    f.write_text(text)
    with pytest.raises(SceneError) as info:
        load_scene(f)
    assert '\n' not in str(info.value)


def test_missing_scene_file(tmp_path):
    with pytest.raises(SceneError, match='does not exist'):
        load_scene(tmp_path / 'nope.yaml')
