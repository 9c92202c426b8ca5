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


def test_node_entry_overrides_wildcard(tmp_path):
    f = tmp_path / 's.yaml'
    f.write_text('/**:\n  ros__parameters:\n    a: 1\n    b: 2\n'
                 'sync_node:\n  ros__parameters:\n    b: 3\n')
    assert load_scene(f, 'sync_node') == {'a': 1, 'b': 3}


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
