"""The Foxglove layouts shipped in config/ open a monitor's bag: they are what the layout maker
gives for their scenes today (no drift), every panel reads a topic the monitor records with
the keys Foxglove's panels persist (no deprecated Plot `title`), the Map panel shows the GNSS
antenna and the planted plants (NavSatFix), and each plot has one series per planting row.
A 4-row demo's bag is checked against its layout (check_the_4_row_layout_opens, run on the
4-row demo of test_demo.py): the Map's topics are NavSatFix channels of the bag, every plant is a
fix, and every row's series finds that row's plants."""
import json
import re

import pytest

from planter_ros import interfaces
from planter_ros.nodes.foxglove_layout import layout, layout_text
from planter_ros.nodes.markers import FRAME
from planter_ros.prediction import QUALITY_FIELDS
from planter_ros.scene import open_scene

from cli_helpers import REPO

SHIPPED = {'foxglove_layout.json': 'tomato_five_bar.yaml',
           'foxglove_layout_4row.json': 'tomato_4row.yaml'}
ROW_SERIES = re.compile(r'(/[\w/]+)\{header\.frame_id=="([^"]*)"\}\.vector\.([xyz])')


def labels_of(scene):
    return [row.label for row in open_scene(REPO / 'config' / scene).rows() if row.enabled]


def _panels(node):
    if isinstance(node, str):
        return [node]
    return _panels(node['first']) + _panels(node['second'])


@pytest.mark.parametrize('name', sorted(SHIPPED))
def test_a_shipped_layout_is_what_the_maker_gives_for_its_scene(name):
    assert (REPO / 'config' / name).read_text() == layout_text(labels_of(SHIPPED[name])), \
        f'regenerate: python -m planter_ros.nodes.foxglove_layout config/{SHIPPED[name]} ' \
        f'config/{name}'


@pytest.mark.parametrize('labels', [['row'], ['left_outer', 'left_inner', 'right_inner',
                                              'right_outer']])
def test_the_layout_has_a_map_and_one_series_per_row(labels):
    config = layout(labels)
    panels = config['configById']
    assert sorted(_panels(config['layout'])) == sorted(panels)
    recorded = {topic.resolved(): topic for topic in interfaces.RECORDED}
    fixes = {name for name, topic in recorded.items()
             if topic.type_name == 'sensor_msgs/msg/NavSatFix'}
    plot_fields = {'x': 'spacing error', 'y': 'speed ratio'}
    for key, panel in panels.items():
        kind = key.split('!')[0]
        assert 'title' not in panel and panel.get('foxglovePanelTitle', '').strip() or \
            kind == 'DiagnosticSummary', key
        if kind == 'Map':
            assert set(panel['topicColors']) == fixes == {
                interfaces.GNSS_FIX.resolved(), interfaces.PLANT_FIXES.resolved()}
            assert panel['followTopic'] == interfaces.GNSS_FIX.resolved()
        elif kind == '3D':
            assert panel['followTf'] == FRAME
            assert list(panel['topics']) == [interfaces.PLANT_MARKERS.resolved()]
        elif kind == 'Plot':
            series = [p for p in panel['paths'] if not _is_number(p['value'])]
            targets = [p for p in panel['paths'] if _is_number(p['value'])]
            rows = [ROW_SERIES.fullmatch(p['value']) for p in series]
            if all(rows):                  # spacing error and λ: one series per row, a target
                assert [m.group(2) for m in rows] == labels == [p['label'] for p in series]
                assert {m.group(1) for m in rows} == {interfaces.PLANT_ROWS.resolved()}
                assert len({m.group(3) for m in rows}) == 1
                assert plot_fields[rows[0].group(3)] in panel['foxglovePanelTitle']
                assert len(targets) == 1
            else:                          # quality of feed: each row's line, the machine's
                assert [p['label'] for p in series] == labels + ['machine']
                width = 1 + len(QUALITY_FIELDS)
                feed = 1 + QUALITY_FIELDS.index('quality_of_feed_index')
                assert [p['value'] for p in series] == [
                    f'{interfaces.SPACING_QUALITY.resolved()}.data[{(k + 1) * width + feed}]'
                    for k in range(len(labels))] + [
                    f'{interfaces.SPACING_QUALITY.resolved()}.data[{feed}]']
        elif kind == 'DiagnosticSummary':
            assert panel['topicToRender'] == interfaces.DIAGNOSTICS.resolved()
    assert {'Map', '3D', 'Plot', 'DiagnosticSummary'} <= {k.split('!')[0] for k in panels}


def _is_number(text):
    try:
        float(text)
    except ValueError:
        return False
    return True


def check_the_4_row_layout_opens(bag):
    """The 4-row layout against a 4-row demo's bag (test_demo.py runs that demo once for its
    own checks and this one: test_the_4_row_layout_opens_the_4_row_demo_bag)."""
    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message
    from geometry_msgs.msg import Vector3Stamped
    config = json.loads((REPO / 'config' / 'foxglove_layout_4row.json').read_text())
    with open(bag, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        types = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        counts = {c.topic: summary.statistics.channel_message_counts.get(c.id, 0)
                  for c in summary.channels.values()}
        rows_seen = {}
        for _, _channel, message in reader.iter_messages(
                topics=[interfaces.PLANT_ROWS.resolved()]):
            key = deserialize_message(message.data, Vector3Stamped).header.frame_id
            rows_seen[key] = rows_seen.get(key, 0) + 1
    the_map = config['configById']['Map!planter-map']
    for topic in the_map['topicColors']:
        assert types.get(topic) == 'sensor_msgs/msg/NavSatFix' and counts[topic] > 0, topic
    assert counts[interfaces.PLANT_FIXES.resolved()] == counts[interfaces.PLANT_ROWS.resolved()]
    wanted = [ROW_SERIES.fullmatch(p['value']).group(2)
              for p in config['configById']['Plot!spacing']['paths']
              if not _is_number(p['value'])]
    assert sorted(rows_seen) == sorted(wanted) and min(rows_seen.values()) >= 2
