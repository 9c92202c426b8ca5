"""The Foxglove layout shipped in config/ opens a monitor's bag: every panel reads a topic the
monitor records, and every plotted array element is the field its label names."""
import json
import re

from planter_ros import interfaces
from planter_ros.prediction import PLANT_FIELDS
from planter_ros.prediction import QUALITY_FIELDS
from planter_ros.nodes.markers import FRAME

from cli_helpers import REPO

LAYOUT = REPO / 'config' / 'foxglove_layout.json'


def _panels(node):
    if isinstance(node, str):
        return [node]
    return _panels(node['first']) + _panels(node['second'])


def test_the_layout_shows_recorded_topics_and_the_fields_its_labels_name():
    layout = json.loads(LAYOUT.read_text())
    panels = layout['configById']
    assert sorted(_panels(layout['layout'])) == sorted(panels)
    recorded = {topic.resolved(): topic for topic in interfaces.RECORDED}
    fields = {interfaces.PLANTS.resolved(): PLANT_FIELDS,
              interfaces.SPACING_QUALITY.resolved(): ('row',) + QUALITY_FIELDS}
    plotted = set()
    for key, config in panels.items():
        kind = key.split('!')[0]
        if kind == '3D':
            assert config['followTf'] == FRAME
            assert list(config['topics']) == [interfaces.PLANT_MARKERS.resolved()]
        elif kind == 'Plot':
            for path in config['paths']:
                topic, index = re.fullmatch(r'(/[\w/]+)\.data\[(\d+)\]', path['value']).groups()
                assert topic in recorded
                assert fields[topic][int(index)] == path['label'], path
                plotted.add(path['label'])
        elif kind == 'DiagnosticSummary':
            assert config['topicToRender'] == interfaces.DIAGNOSTICS.resolved()
    # what the issue asks to see: spacing, lambda and the indices
    assert {'spacing_error', 'speed_ratio', 'quality_of_feed_index'} <= plotted
    assert {key.split('!')[0] for key in panels} >= {'3D', 'Plot', 'DiagnosticSummary'}
