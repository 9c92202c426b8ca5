"""Launch the planting unit on a ROS machine: design, sync (CAN drive), monitor and ground-speed
nodes.

    ros2 launch planter_ros planter.launch.py scene:=/path/to/scene.yaml can_channel:=can0

Every node reads the same scene file (`/**` parameters); the sync node additionally gets the
CAN interface and channel, the ground-speed node its sources (ISOBUS on `isobus_channel`, empty:
none; the GNSS velocity on /planter/gnss/vel). Topics live in the /planter namespace
(planter_ros.interfaces). Stopping as launch/tractor.launch.py says (STOP_TIMEOUTS).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from planter_ros.interfaces import NAMESPACE

PACKAGE = 'planter_ros'
# s launch waits after its SIGINT before SIGTERM, then before SIGKILL (each node)
STOP_TIMEOUTS = {'sigterm_timeout': '20', 'sigkill_timeout': '5'}


def generate_launch_description():
    scene = LaunchConfiguration('scene')
    return LaunchDescription([
        DeclareLaunchArgument(
            'scene', description='scene parameter file (crop + mechanism)',
            default_value=PathJoinSubstitution([FindPackageShare(PACKAGE), 'config',
                                                'tomato_five_bar.yaml'])),
        DeclareLaunchArgument('can_interface', default_value='socketcan',
                              description="python-can interface ('socketcan' on the machine)"),
        DeclareLaunchArgument('can_channel', default_value='can0', description='CAN channel'),
        DeclareLaunchArgument('drive_node_id', default_value='1',
                              description='CANopen node id of the servo drive'),
        DeclareLaunchArgument('isobus_channel', default_value='',
                              description="the tractor's ISOBUS CAN channel (e.g. can1); empty: "
                                          'ground speed from the GNSS velocity only'),
        Node(package=PACKAGE, executable='ground_speed_node', namespace=NAMESPACE,
             output='screen', **STOP_TIMEOUTS,
             parameters=[{'isobus_channel': LaunchConfiguration('isobus_channel')}]),
        Node(package=PACKAGE, executable='design_node', namespace=NAMESPACE,
             parameters=[scene], output='screen', **STOP_TIMEOUTS),
        Node(package=PACKAGE, executable='sync_node', namespace=NAMESPACE, output='screen',
             **STOP_TIMEOUTS,
             parameters=[scene, {'can_interface': LaunchConfiguration('can_interface'),
                                 'can_channel': LaunchConfiguration('can_channel'),
                                 'drive_node_id': LaunchConfiguration('drive_node_id')}]),
        Node(package=PACKAGE, executable='monitor_node', namespace=NAMESPACE,
             parameters=[scene], output='screen', **STOP_TIMEOUTS),
    ])
