"""Launch a transplanter on a tractor: several rows from a machine file, ground speed from the
tractor's ISOBUS with GNSS as the fallback (doc/deploy.md).

    ros2 launch planter_ros tractor.launch.py machine:=/etc/planter/machine.yaml \
        scene:=/etc/planter/scene.yaml

Every node reads the scene file; on top, each gets its share of the machine file (the CAN bus,
the rows, their drives and lever arms: planter_ros.scene.machine.deployment_parameters, which
checks both files and the scene's plausibility on this machine first and refuses to launch
otherwise). ground_speed_node gets the ISOBUS channel from the machine file and its sources
from `speed_sources`; the sync node the service manager's note of how the last run ended
(`last_stop_file`: after an automatic restart the rows wait at zero for an operator's
enable_rows). Topics live in the /planter namespace. Stopped (SIGINT or SIGTERM), launch passes
the signal to every node: each stops cleanly (rows ramped to 0, drives disabled, bag finalised).
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


def _nodes(context):
    from planter_ros.scene.machine import deployment_parameters
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
                            output='screen', parameters=files + [params[name]]))
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
