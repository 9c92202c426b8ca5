"""The Foxglove layouts shipped in config/ open a monitor's bag: they are what the layout maker
gives for their scenes today (no drift); every panel id names a panel type Foxglove registers
(case-sensitive: the Map panel is `map`) and every config key, down to the Plot's series, the
3D panel's camera, topics and grid layer, is one that panel persists: both checked against
facts taken from Foxglove's and Lichtblick's source (test/data/foxglove_panels.json, dated, with
the commits they were read at). Every panel reads a topic the monitor records, the Map panel
shows the GNSS antenna and the planted plants (NavSatFix, a schema the Map panel takes), and
each plot has one series per planting row. A 4-row demo's bag is checked against its layout
(check_the_4_row_layout_opens, run on the 4-row demo of test_demo.py): the Map's topics are
NavSatFix channels of the bag whose fixes the Map draws as fixes, every plant is a fix, and
every row's series finds that row's plants."""
import json
import re

import pytest

from planter_ros import interfaces
from planter_ros.nodes.foxglove_layout import MAP, layout, layout_text
from planter_ros.nodes.markers import FRAME
from planter_ros.prediction import QUALITY_FIELDS
from planter_ros.scene import open_scene

from cli_helpers import REPO

FOXGLOVE = json.loads((REPO / 'test' / 'data' / 'foxglove_panels.json').read_text())
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
        if kind == 'map':
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
    assert {'map', '3D', 'Plot', 'DiagnosticSummary'} <= {k.split('!')[0] for k in panels}


def _keys_known(config, known, where):
    """The keys of `config` that `known` (a list of keys) does not have, named `where.key`."""
    return [f'{where}.{key}' for key in config if key not in known]


def foxglove_problems(config):
    """What Foxglove would not open or would not read in a layout (a dict): an unknown panel
    type, a key a panel does not persist, a value outside a panel's choices (lists)."""
    facts = FOXGLOVE['configs']
    problems = _keys_known(config, FOXGLOVE['layout_keys'], 'layout')
    problems += _keys_known(config['playbackConfig'], FOXGLOVE['playback_config_keys'],
                            'playbackConfig')

    def nodes(node):
        if isinstance(node, str):
            return [node]
        problems.extend(_keys_known(node, FOXGLOVE['layout_node_keys'], 'layout node'))
        if node['direction'] not in FOXGLOVE['layout_directions']:
            problems.append(f'layout node direction {node["direction"]}')
        return nodes(node['first']) + nodes(node['second'])
    placed = nodes(config['layout'])
    if sorted(placed) != sorted(config['configById']):
        problems.append(f'panels placed {sorted(placed)} != configured '
                        f'{sorted(config["configById"])}')
    for panel_id, panel in config['configById'].items():
        kind = panel_id.split(FOXGLOVE['panel_id_separator'])[0]
        for source, types in FOXGLOVE['panel_types'].items():
            if kind not in types:
                problems.append(f'{panel_id}: panel type {kind!r} is not registered in {source}')
        if kind not in facts:
            problems.append(f'{panel_id}: no facts of panel type {kind!r} to check it against')
            continue
        fact = facts[kind]
        problems += _keys_known(panel, fact['keys'] + [FOXGLOVE['panel_title_key']], panel_id)
        if kind == 'map' and panel.get('layer', 'map') not in fact['layer']:
            problems.append(f'{panel_id}.layer = {panel["layer"]}')
        if kind == 'Plot':
            for k, path in enumerate(panel.get('paths', [])):
                problems += _keys_known(path, fact['path_keys'], f'{panel_id}.paths[{k}]')
                if path.get('timestampMethod') not in fact['timestampMethod']:
                    problems.append(f'{panel_id}.paths[{k}].timestampMethod')
            for key in ('xAxisVal', 'legendDisplay'):
                if key in panel and panel[key] not in fact[key]:
                    problems.append(f'{panel_id}.{key} = {panel[key]}')
        if kind == '3D':
            problems += _keys_known(panel.get('cameraState', {}), fact['cameraState'],
                                    f'{panel_id}.cameraState')
            problems += _keys_known(panel.get('scene', {}), fact['scene'], f'{panel_id}.scene')
            if panel.get('followMode', 'follow-none') not in fact['followMode']:
                problems.append(f'{panel_id}.followMode = {panel["followMode"]}')
            for topic, settings in panel.get('topics', {}).items():
                problems += _keys_known(settings, fact['topic_settings'],
                                        f'{panel_id}.topics[{topic}]')
            for name, layer in panel.get('layers', {}).items():
                problems += _keys_known(layer, fact['grid_layer'], f'{panel_id}.layers[{name}]')
                if layer.get('layerId') != fact['grid_layer_id']:
                    problems.append(f'{panel_id}.layers[{name}].layerId')
    return problems


@pytest.mark.parametrize('name', sorted(SHIPPED))
def test_every_panel_and_key_of_a_shipped_layout_is_one_foxglove_has(name):
    config = json.loads((REPO / 'config' / name).read_text())
    assert foxglove_problems(config) == []
    assert MAP in config['configById'] and MAP.startswith('map!')


def test_the_check_finds_what_foxglove_would_not_open():
    """The check itself: the layout of the issue (the Map panel as `Map`, a deprecated Plot
    `title`, a misspelt camera key, a wrong timestamp method) is caught, each by name."""
    config = layout(['row'])
    panels = config['configById']
    panels['Map!old'] = panels.pop(MAP)
    config['layout'] = json.loads(json.dumps(config['layout']).replace(MAP, 'Map!old'))
    plot = next(k for k in panels if k.startswith('Plot!'))
    panels[plot]['title'] = 'old title'
    panels[plot]['paths'][0]['timestampMethod'] = 'publishTime'
    panels['3D!planter3d']['cameraState']['fov'] = 45
    problems = foxglove_problems(config)
    assert "Map!old: panel type 'Map' is not registered in lichtblick" in problems
    assert "Map!old: panel type 'Map' is not registered in foxglove_studio" in problems
    assert f'{plot}.title' in problems
    assert f'{plot}.paths[0].timestampMethod' in problems
    assert '3D!planter3d.cameraState.fov' in problems


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
    from sensor_msgs.msg import NavSatFix
    config = json.loads((REPO / 'config' / 'foxglove_layout_4row.json').read_text())
    the_map = config['configById'][MAP]
    drawn = {}                  # Map topic -> fixes the Map panel draws as fixes
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
        for _, channel, message in reader.iter_messages(topics=list(the_map['topicColors'])):
            fix = deserialize_message(message.data, NavSatFix)
            drawn.setdefault(channel.topic, 0)
            drawn[channel.topic] += (fix.status.status in FOXGLOVE['configs']['map'][
                'fix_statuses'] and abs(fix.latitude) <= 90 and abs(fix.longitude) <= 180)
    for topic in the_map['topicColors']:
        assert types.get(topic) in FOXGLOVE['configs']['map']['schemas'] and counts[topic] > 0, \
            topic
    assert counts[interfaces.PLANT_FIXES.resolved()] == counts[interfaces.PLANT_ROWS.resolved()]
    # every message of either Map topic is a fix the Map panel draws as one (its hasFix)
    assert {t: drawn.get(t, 0) for t in the_map['topicColors']} == {
        t: counts[t] for t in the_map['topicColors']}
    wanted = [ROW_SERIES.fullmatch(p['value']).group(2)
              for p in config['configById']['Plot!spacing']['paths']
              if not _is_number(p['value'])]
    assert sorted(rows_seen) == sorted(wanted) and min(rows_seen.values()) >= 2
