"""A scene's rows: the 4-row scene file, nested blocks flattened as ROS does, one implicit row
for a scene without rows, bad rows refused in one line naming the parameter, joint names."""
from pathlib import Path

import pytest

from planter_ros import interfaces
from planter_ros.config import ConfigError
from planter_ros.rows import rows_from_record, rows_from_scene, rows_record
from planter_ros.scene import load_scene

CONFIG = Path(__file__).resolve().parents[1] / 'config'


def test_the_four_row_scene_names_rows_offsets_and_drives():
    scene = load_scene(CONFIG / 'tomato_4row.yaml')
    assert scene['left_outer.lateral_offset'] == 0.75          # nested block, flattened
    rows = rows_from_scene(scene)
    assert [r.name for r in rows] == ['left_outer', 'left_inner', 'right_inner', 'right_outer']
    assert [r.lateral_offset for r in rows] == [0.75, 0.25, -0.25, -0.75]
    assert [r.drive_node_id for r in rows] == [1, 2, 3, 4]
    assert all(r.enabled for r in rows) and [r.index for r in rows] == [0, 1, 2, 3]
    assert rows[0].joint('five_bar') == 'left_outer/sun_bar'
    assert rows[0].joint('three_arm') == 'left_outer/carrier'


def test_a_scene_without_rows_is_one_implicit_row_with_the_old_joint_names():
    rows = rows_from_scene(load_scene(CONFIG / 'tomato_five_bar.yaml'), default_node_id=7)
    assert len(rows) == 1
    row = rows[0]
    assert (row.name, row.lateral_offset, row.drive_node_id, row.enabled) == ('', 0.0, 7, True)
    assert row.joint('five_bar') == 'sun_bar' and row.joint('three_arm') == 'carrier'
    assert interfaces.RESET_FAULT.for_row(row.name) == 'reset_fault'
    assert interfaces.SECTION.for_row('left') == 'left/section'


def test_enabled_defaults_to_true_and_can_be_false(tmp_path):
    f = tmp_path / 's.yaml'
    f.write_text('/**:\n  ros__parameters:\n    rows: [a, b]\n'
                 '    a: {lateral_offset: 0.5, drive_node_id: 3}\n'
                 '    b:\n      lateral_offset: -0.5\n      drive_node_id: 4\n'
                 '      enabled: false\n')
    rows = rows_from_scene(load_scene(f))
    assert [(r.name, r.enabled) for r in rows] == [('a', True), ('b', False)]


@pytest.mark.parametrize('params, words', [
    ({'rows': ['a', 'a'], 'a.lateral_offset': 0.0, 'a.drive_node_id': 1},
     ["rows = 'a' is named twice"]),
    ({'rows': ['left row']}, ["rows = 'left row' is not a row name", 'letters, digits']),
    ({'rows': ['a'], 'a.drive_node_id': 1}, ['a.lateral_offset is required']),
    ({'rows': ['a'], 'a.lateral_offset': 0.1, 'a.drive_node_id': 200},
     ['a.drive_node_id = 200 is out of range', '1..127']),
    ({'rows': ['a', 'b'], 'a.lateral_offset': 0.1, 'a.drive_node_id': 2,
      'b.lateral_offset': -0.1, 'b.drive_node_id': 2},
     ['b.drive_node_id = 2 is also row a', 'no other row uses']),
    ({'rows': ['a'], 'a.lateral_offset': 'left', 'a.drive_node_id': 2},
     ["a.lateral_offset = 'left' is out of range", 'number -20..20 m']),
])
def test_bad_rows_are_one_line_errors_naming_the_parameter(params, words):
    with pytest.raises(ConfigError) as info:
        rows_from_scene(params)
    message = str(info.value)
    assert '\n' not in message
    for word in words:
        assert word in message


def test_the_rows_record_round_trips():
    rows = rows_from_scene(load_scene(CONFIG / 'tomato_4row.yaml'))
    assert rows_from_record(rows_record(rows)) == rows
    assert rows_from_record({'rows': 'not json'}) is None
