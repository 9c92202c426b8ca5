"""Launch a transplanter on a tractor: several rows from a machine file, ground speed from the
tractor's ISOBUS with GNSS as the fallback (doc/deploy.md).

    ros2 launch planter_ros tractor.launch.py machine:=/etc/planter/machine.yaml \
        scene:=/etc/planter/scene.yaml

Every node reads the scene file; on top, each gets its share of the machine file (the CAN bus,
the rows, their drives and lever arms: planter_ros.scene.machine_file.deployment_parameters, which
checks both files and the scene's plausibility on this machine first and refuses to launch
otherwise). ground_speed_node gets the ISOBUS channel from the machine file and its sources
from `speed_sources`; the sync node the service manager's note of how the last run ended
(`last_stop_file`: after an automatic restart the rows wait at zero for an operator's
enable_rows). Topics live in the /planter namespace.

Stopping: SIGINT to `ros2 launch --noninteractive` (systemd/planter.service) passes SIGINT to
every node, and each stops cleanly (rows ramped to 0, drives disabled, bag finalised); in a
terminal, Ctrl-C reaches every node itself and launch sends no SIGINT of its own. Launch's own
escalation (SIGTERM, then SIGKILL, to a node still running) waits STOP_TIMEOUTS: its default
of 5 s would cut a stop short (a second signal forces a node's exit), these stay inside the
unit's TimeoutStopSec. (SIGTERM to `ros2 launch` alone makes it cancel its run without stopping
the nodes: launch's behaviour, hence SIGINT.)
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from planter_ros.interfaces import NAMESPACE

PACKAGE = 'planter_ros'
NODES = ('ground_speed_node', 'design_node', 'sync_node', 'monitor_node')
# launch argument -> (node, parameter) it sets; `machine` and `scene` are files
ARGUMENT_PARAMETERS = {
    'speed_sources': ('ground_speed_node', 'sources'),
    'yaw_rate_source': ('ground_speed_node', 'yaw_rate_source'),
    'last_stop_file': ('sync_node', 'last_stop_file'),
}
# s launch waits after its SIGINT before SIGTERM, then before SIGKILL (each node)
STOP_TIMEOUTS = {'sigterm_timeout': '20', 'sigkill_timeout': '5'}


def _nodes(context):
    from planter_ros.scene.machine_file import deployment_parameters
    machine = LaunchConfiguration('machine').perform(context)
    scene = LaunchConfiguration('scene').perform(context)
    overrides = {'ground_speed_node': {
        'sources': [s.strip() for s in
                    LaunchConfiguration('speed_sources').perform(context).split(',')],
        'yaw_rate_source': LaunchConfiguration('yaw_rate_source').perform(context)},
        'sync_node': {'last_stop_file': LaunchConfiguration('last_stop_file').perform(context)}}
    params, warnings = deployment_parameters(machine, scene, overrides)
    actions = [LogInfo(msg=f'planter: warning: {w}') for w in warnings]
    for name in NODES:
        files = [] if name == 'ground_speed_node' else [scene]
        actions.append(Node(package=PACKAGE, executable=name, namespace=NAMESPACE,
                            output='screen', parameters=files + [params[name]],
                            **STOP_TIMEOUTS))
    return actions


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('machine', default_value='/etc/planter/machine.yaml',
                              description='machine file (doc/machine_file.md)'),
        DeclareLaunchArgument('scene', default_value='/etc/planter/scene.yaml',
                              description='scene parameter file (crop + mechanism)'),
        DeclareLaunchArgument('speed_sources', default_value='isobus_selected,isobus_ground,gnss',
                              description='ground-speed sources in order of preference, comma '
                                          'separated (doc/ground_speed.md)'),
        DeclareLaunchArgument('yaw_rate_source', default_value='gnss',
                              description='yaw rate from gnss, imu or none'),
        DeclareLaunchArgument('last_stop_file', default_value='',
                              description='how the last run ended, as the service manager '
                                          'noted it (systemd/planter.service: '
                                          '/run/planter/last-stop); after a run that did not '
                                          'end with success the rows wait for enable_rows'),
        OpaqueFunction(function=_nodes),
    ])
