"""A node started with `--ros-args --params-file FILE` refuses a parameter it does not declare
(rclpy alone ignores it): keys under the node's own entry must be its parameters, keys under a
shared entry (`/**`) a parameter of some planter node, and an override (`-p`) must be one it
declares. The one scene file still serves all three nodes. Each node, in-process and as its
console script (exit 2, one line naming the key, the file and the closest valid key)."""
import os
import subprocess
import sys

import pytest

from planter_ros.nodes.design_node import DesignNode
from planter_ros.nodes.monitor_node import MonitorNode
from planter_ros.nodes.sync_node import SyncNode
from planter_ros.scene import SceneError
from planter_ros.scene.schema import node_specs

from cli_helpers import REPO
from ros_fixtures import unique_channel

pytestmark = pytest.mark.realtime          # (test/conftest.py)

TOMATO = (REPO / 'config' / 'tomato_five_bar.yaml').read_text()
FOUR_ROWS = REPO / 'config' / 'tomato_4row.yaml'
RICE = REPO / 'config' / 'rice_three_arm.yaml'


def start(node, *args):
    """`node` built in a context started with the ROS arguments `args` as its main builds it
    (in /planter; the sync node on a virtual bus, the monitor not recording), then destroyed."""
    import rclpy
    from rclpy.context import Context
    argv = ['test', '--ros-args', *map(str, args)]
    if issubclass(node, SyncNode):
        argv += ['-p', 'can_interface:=virtual', '-p', f'can_channel:={unique_channel()}']
    if issubclass(node, MonitorNode):
        argv += ['-p', 'record:=false']
    context = Context()
    rclpy.init(args=argv, context=context)
    built = None
    try:
        built = node(context=context, namespace='planter', arguments=argv)
    finally:
        if built is not None:
            built.destroy_node()
        rclpy.try_shutdown(context=context)


def scene(tmp_path, text):
    path = tmp_path / 'scene.yaml'
    path.write_text(text)
    return path


NODES = [DesignNode, SyncNode, MonitorNode]


@pytest.mark.parametrize('node', NODES, ids=lambda n: n.__name__)
@pytest.mark.parametrize('path', [REPO / 'config' / 'tomato_five_bar.yaml', FOUR_ROWS, RICE],
                         ids=lambda p: p.name)
def test_one_scene_serves_every_node(node, path):
    """Each node takes the whole shared scene: the other nodes' parameters under /** are not
    its business."""
    start(node, '--params-file', path)


@pytest.mark.parametrize('node, entry, key, words', [
    (DesignNode, '/**', 'plant_spcing: 0.3', 'did you mean `plant_spacing`?'),
    (SyncNode, '/**', 'phase_gane: 2.0', 'did you mean `phase_gain`?'),
    (MonitorNode, '/**', 'windw: 40', 'did you mean `window`?'),
    (DesignNode, '/planter/design_node', 'can_channel: can1',
     'can_channel under /planter/design_node is not a parameter of design_node'),
    (SyncNode, '/**/sync_node', 'nozzle_width: 0.04',
     'nozzle_width under /**/sync_node is not a parameter of sync_node'),
    (MonitorNode, '/planter/monitor_node', 'phase_gain: 2.0',
     'phase_gain under /planter/monitor_node is not a parameter of monitor_node'),
])
def test_a_key_the_node_does_not_take_is_refused_naming_it(tmp_path, node, entry, key, words):
    path = scene(tmp_path, TOMATO + f'{entry}:\n  ros__parameters:\n    {key}\n'
                 if entry != '/**' else TOMATO + f'    {key}\n')
    with pytest.raises(SceneError) as err:
        start(node, '--params-file', path)
    message = str(err.value)
    assert words in message and str(path) in message and '\n' not in message, message


@pytest.mark.parametrize('node, name', [(DesignNode, 'plant_spcing'), (SyncNode, 'rowz'),
                                        (MonitorNode, 'bag_pth')])
def test_an_override_it_does_not_declare_is_refused(tmp_path, node, name):
    path = scene(tmp_path, TOMATO)
    with pytest.raises(SceneError, match=f'parameter {name} given to'):
        start(node, '--params-file', path, '-p', f'{name}:=1.0')


@pytest.mark.parametrize('node, scene_path', [
    (DesignNode, REPO / 'config' / 'tomato_five_bar.yaml'), (DesignNode, RICE),
    (SyncNode, FOUR_ROWS), (MonitorNode, FOUR_ROWS)], ids=str)
def test_the_scene_rule_knows_exactly_what_each_node_declares(node, scene_path):
    """scene.schema's list of each node's parameters is the node's own (a parameter added to a
    node without the schema knowing would be refused in every scene)."""
    from planter_ros.scene import open_scene
    opened = open_scene(scene_path)
    params = opened.parameters()
    built = {}

    class Probe(node):
        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            built['names'] = set(self._parameters)

    start(Probe, '--params-file', scene_path)
    name = {DesignNode: 'design_node', SyncNode: 'sync_node', MonitorNode: 'monitor_node'}[node]
    assert built['names'] == set(node_specs(name, params.get('mechanism', 'five_bar'),
                                            params.get('rows', [])))


@pytest.mark.parametrize('main, name', [('design_node', 'design_node'),
                                        ('sync_node', 'sync_node'),
                                        ('monitor_node', 'monitor_node')])
def test_the_console_script_exits_2_with_one_line(tmp_path, main, name):
    path = scene(tmp_path, TOMATO + '    plant_spcing: 0.3\n')
    env = dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    code = f'from planter_ros.nodes.{main} import main; raise SystemExit(main())'
    out = subprocess.run([sys.executable, '-c', code, '--ros-args', '--params-file', str(path)],
                         capture_output=True, text=True, timeout=60, env=env, cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    assert lines[0].startswith(f'{name}: error: scene file {path}: plant_spcing ')
    assert 'did you mean `plant_spacing`?' in lines[0]
