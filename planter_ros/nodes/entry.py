"""The nodes' console scripts (setup.py): `--help` and `--version` answered here, before the node's
module is imported, so they touch no CAN bus, no DDS and no file (rclpy, python-can and canopen
are not even loaded); anything else starts the node (`<node>.main()`).

Only the arguments before `--ros-args` are the program's own (`ros2 run planter_ros sync_node
--help`); what follows belongs to ROS. The help lists the node's parameters from the same
declarations the node declares them from (scene.schema.node_specs), with range and default.
"""

from dataclasses import MISSING
import importlib
import sys

from planter_ros.config import specs
from planter_ros.scene.schema import ROS_PARAMETERS, node_specs
from planter_ros.sensing.ground_speed_sources import GroundSpeedSourceConfig
from planter_ros.shipped import package_version

HELP = ('-h', '--help')
VERSION = ('--version',)

# node -> (module, what it does)
NODES = {
    'design_node': ('planter_ros.nodes.design_node',
                    "scene parameters -> the mechanism's design, published latched on "
                    '/planter/design; infeasible updates are refused with the reason'),
    'sync_node': ('planter_ros.nodes.sync_node',
                  'ground speed -> each row\'s sun-bar (carrier) speed, phase-locked to the '
                  'travelled distance, sent to the CiA 402 drives on CAN'),
    'monitor_node': ('planter_ros.nodes.monitor_node',
                     'ground speed + measured shaft motion -> per-plant predictions (position, '
                     'spacing, hole, tilt), the as-planted map, recorded to MCAP'),
    'ground_speed_node': ('planter_ros.nodes.ground_speed_node',
                          "the tractor's sensors (ISOBUS speed on a second CAN channel, GNSS "
                          'velocity, a wheel or radar pulse count; yaw rate from the GNSS course '
                          'or an IMU) -> /planter/ground_speed, falling back when a source goes '
                          'quiet'),
}


def own_arguments(argv):
    """The program's own arguments: those before `--ros-args` (argv without the program)."""
    argv = list(argv)
    return argv[:argv.index('--ros-args')] if '--ros-args' in argv else argv


def help_text(node):
    """The node's --help: usage, purpose, every parameter with its range and default."""
    _, purpose = NODES[node]
    lines = [f'usage: {node} [-h] [--version] [--ros-args --params-file SCENE.yaml '
             '[-p NAME:=VALUE ...]]', '', f'{node}: {purpose}.', '',
             'Started by `ros2 run planter_ros ' + node + '`, a launch file or the systemd unit '
             '(doc/deploy.md); parameters come from a scene file (config/*.yaml).', '',
             'options:', '  -h, --help   show this help and exit (opens nothing)',
             '  --version    print the version and exit', '', 'parameters:']
    specs = parameter_specs(node)
    width = max(map(len, specs))
    for name, spec in specs.items():
        default = '(required)' if spec.default is MISSING else f'default {spec.default!r}'
        flag = ', read-only' if spec.read_only else ''
        lines.append(f'  {name:<{width}}  {spec.allowed()}; {default}{flag}')
    if node in ('sync_node', 'monitor_node'):
        lines.append(f'  {"<row>.<setting>":<{width}}  one block per name in rows '
                     '(lateral_offset, drive_node_id, enabled)')
    return '\n'.join(lines)


def parameter_specs(node):
    """{name: Spec} of every parameter `node` declares (ROS's own too; rows aside)."""
    if node == 'ground_speed_node':
        return {**ROS_PARAMETERS, **{s.name: s for s in specs(GroundSpeedSourceConfig)}}
    return node_specs(node)


def answered(node, argv):
    """Print the help or the version if `argv` (without the program) asks; True if it did."""
    own = own_arguments(argv)
    if any(a in HELP for a in own):
        print(help_text(node))
        return True
    if any(a in VERSION for a in own):
        print(f'{node} (planter_ros) {package_version()}')
        return True
    return False


def run(node):
    """The console script of `node`: help/version, else the node's main()."""
    if answered(node, sys.argv[1:]):
        return 0
    module, _ = NODES[node]
    return importlib.import_module(module).main()


def design_node():
    return run('design_node')


def sync_node():
    return run('sync_node')


def monitor_node():
    return run('monitor_node')


def ground_speed_node():
    return run('ground_speed_node')
