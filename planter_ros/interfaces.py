"""The user's contract in one table: every topic's name, message type and QoS, and the joints.

Standard message types only (no custom interfaces package). Every publisher, subscriber,
recorder channel and replay lookup takes its topic from here, so a rename is one edit. Topics
are relative (default namespace /planter) except the ROS-wide ones (/diagnostics, /clock).

QoS, chosen on purpose:
* design: reliable + transient_local + depth 1 ("latched"): a node that starts late (the sync
  node after a restart, the monitor, a recorder) still gets the active design at once.
* sections: reliable + transient_local + depth 10. Latched like the design, so a late monitor
  or recorder gets the rows' states at once; but the monitor needs every change, not only the
  last (a row off and on again is a break in its spacing sequence): ten keep a burst of switches
  from overwriting each other in the sync node's and a busy reader's queue, and a late joiner
  gets the last few switches (each message stamped at its switch, so the breaks they make
  still fall where they were). Each message holds every row's state, so a lost one never
  leaves a row's state wrong, only a break unseen.
* ground_speed: the sensor-data profile (best effort, volatile, keep last 5). A late or resent
  speed sample is worse than none (the law integrates distance from receive times and holds the
  last sample), a best-effort subscription also matches a reliable publisher, and a lost sample
  costs one 20-50 ms update. The sync node never waits on a retransmission.
* joint_states: reliable, keep last 100. The monitor computes plant positions from joint
  states (losing one loses a plant crossing), and after a stall of the sync node's shell every
  feedback sample queued meanwhile goes out at once, each with its own stamp (a second at
  10 ms per sample fits the writer's history; doc/command.md).
* speed_command, /diagnostics: reliable, keep last 10.
* plants, uprightness_rate, spacing_quality, plant_markers: reliable, keep last 100 (a viewer
  that falls behind for a second still gets every plant).
A recorder subscribes with the same reliability and durability but a deeper queue
(`Topic.recording_qos`), so it rides out a busy second at 100 Hz.

The sections topic is a sensor_msgs/JointState on purpose: no standard message is a list of
named switches, and JointState comes closest. It names each row (a reader matches rows by
name, never by place), carries a stamp (the instant of the switch, which the breaks in the
spacing sequence need), and its position array holds one number per row (1 on, 0 off), so
Foxglove plots a row's section as a step next to its plants (`/planter/sections.position[i]`,
i the row's place in the scene's rows) and replay reads it in bulk with the CDR reader it
already has for joint_states, without rclpy. The others fall short: diagnostic_msgs/KeyValue
pairs are health for people (text values, no stamp of their own; the section state used to
travel there and be parsed back), std_msgs/*MultiArray has no stamp and no names but a label
string, sensor_msgs/Joy has no names, rcl_interfaces/ParameterEvent means a parameter changed.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
import importlib
import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:                 # rclpy where a node uses the contract: the pure core needs none
    from rclpy.node import Node
    from rclpy.publisher import Publisher
    from rclpy.qos import QoSProfile
    from rclpy.subscription import Subscription

NAMESPACE = 'planter'
RECORDING_DEPTH = 100


@dataclass(frozen=True)
class Qos:
    """A QoS profile as plain data (keep-last history); `profile()` gives rclpy's."""

    reliability: str            # 'reliable' | 'best_effort'
    durability: str             # 'volatile' | 'transient_local'
    depth: int

    def deeper(self, depth: int = RECORDING_DEPTH) -> Qos:
        return replace(self, depth=depth)

    def profile(self) -> QoSProfile:
        # lazy: rclpy.qos costs 70 ms, and replay and analyze read the topic names here
        # without rclpy (test_offline_imports)
        from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile,
                               ReliabilityPolicy)
        return QoSProfile(depth=self.depth, history=HistoryPolicy.KEEP_LAST,
                          reliability=ReliabilityPolicy[self.reliability.upper()],
                          durability=DurabilityPolicy[self.durability.upper()])


LATCHED = Qos('reliable', 'transient_local', 1)
SENSOR_DATA = Qos('best_effort', 'volatile', 5)
STATE = Qos('reliable', 'volatile', 10)
OUTPUT = Qos('reliable', 'volatile', 100)
FEEDBACK = Qos('reliable', 'volatile', 100)


@dataclass(frozen=True)
class Topic:
    """One topic of the contract: `name` (relative unless it starts with '/'), `type_name`
    (`pkg/msg/Type`), the QoS its publishers offer and its subscribers ask for."""

    name: str
    type_name: str
    qos: Qos
    doc: str

    def msg_class(self) -> type[Any]:
        """The generated message class (its fields are not typed: rosidl writes no hints)."""
        package, kind, base = self.type_name.split('/')
        cls: type[Any] = getattr(importlib.import_module(f'{package}.{kind}'), base)
        return cls

    def recording_qos(self) -> Qos:
        """What a recorder subscribes with: a latched topic's last sample, else a deep queue."""
        return self.qos if self.qos.durability == 'transient_local' else self.qos.deeper()

    def publisher(self, node: Node, qos: Qos | None = None) -> Publisher:
        """`node`'s publisher of this topic (the contract's QoS unless `qos` is given)."""
        return node.create_publisher(self.msg_class(), self.name, (qos or self.qos).profile())

    def subscribe(self, node: Node, callback: Callable[[Any], None], qos: Qos | None = None,
                  **kwargs: Any) -> Subscription:
        """`node`'s subscription to this topic (kwargs: raw, callback_group, ...)."""
        return node.create_subscription(self.msg_class(), self.name, callback,
                                        (qos or self.qos).profile(), **kwargs)

    def resolved(self, namespace: str = NAMESPACE) -> str:
        """The absolute name in `namespace` (as recorded in bags)."""
        return self.name if self.name.startswith('/') else f'/{namespace}/{self.name}'


GROUND_SPEED = Topic(
    'ground_speed', 'geometry_msgs/msg/TwistStamped', SENSOR_DATA,
    'input: twist.linear.x = measured ground speed (m/s, forward > 0), twist.angular.z = yaw '
    'rate (rad/s, + counter-clockwise; 0 from a source without one); published by '
    'ground_speed_node on a machine, by the simulation in the demo')
DESIGN = Topic(
    'design', 'std_msgs/msg/String', LATCHED,
    'JSON of the active design in SI units; keys at least mechanism (five_bar | three_arm), '
    'plants_per_revolution (1 | 3), plant_spacing (m), planting_depth (m), then the '
    "mechanism's own fields")
JOINT_STATES = Topic(
    'joint_states', 'sensor_msgs/msg/JointState', FEEDBACK,
    'drive feedback, one joint per enabled row: name = row_joint(row, mechanism), position = '
    'mechanism shaft angle (rad, unwrapped, increasing forward), velocity (rad/s), stamped '
    'when the drive measured it')
SPEED_COMMAND = Topic(
    'speed_command', 'std_msgs/msg/Float64', STATE,
    'commanded mechanism shaft speed (rad/s) sent to the drive (a scene without rows)')
SPEED_COMMANDS = Topic(
    'speed_commands', 'sensor_msgs/msg/JointState', STATE,
    'a scene with rows: commanded mechanism shaft speed (rad/s) of each row in velocity, name '
    '= row_joint(row, mechanism), position empty, stamped when sent')
PLANTS = Topic(
    'plants', 'std_msgs/msg/Float64MultiArray', OUTPUT,
    "per-plant predictions: dim[0] 'plant' x dim[1] labelled with the field names (SI); the "
    "field 'row' is the row's index in the bag's rows record")
GNSS_FIX = Topic(
    'gnss/fix', 'sensor_msgs/msg/NavSatFix', SENSOR_DATA,
    "input: the machine's GNSS antenna position (WGS 84), status and covariance as the "
    'receiver reports them; a fix without position (status NO_FIX) is not used')
GNSS_VELOCITY = Topic(
    'gnss/vel', 'geometry_msgs/msg/TwistWithCovarianceStamped', SENSOR_DATA,
    "input of ground_speed_node: the GNSS receiver's velocity, twist.linear.x east and .y "
    'north (m/s), as nmea_navsat_driver publishes it; |v| is the speed, its course the yaw rate')
IMU = Topic(
    'imu/data', 'sensor_msgs/msg/Imu', SENSOR_DATA,
    'input of ground_speed_node (yaw_rate_source imu): angular_velocity.z = yaw rate (rad/s, + '
    'counter-clockwise, REP 103 z up)')
WHEEL_PULSES = Topic(
    'wheel_pulses', 'std_msgs/msg/UInt32', SENSOR_DATA,
    'input of ground_speed_node (source pulses): a wheel or radar pulse counter (wraps at 2^32), '
    'read at its receive time; pulses_per_metre turns it into a speed')
SPACING_QUALITY = Topic(
    'spacing_quality', 'std_msgs/msg/Float64MultiArray', OUTPUT,
    "ISO 7256-1 spacing-quality indices since the start: dim[0] 'row' (the machine first, "
    "row -1, then one line per planting row) x dim[1] labelled 'row,multiple_index,miss_index,"
    "quality_of_feed_index,precision,spacings' (fractions 0..1, NaN when undefined)")
PLANT_MARKERS = Topic(
    'plant_markers', 'visualization_msgs/msg/MarkerArray', OUTPUT,
    "3D view of the planted plants (stems with their predicted tilt) and each row's tip path, "
    "in the frame 'field' (east, north, up of the as-planted map)")
PLANT_FIXES = Topic(
    'plant_fixes', 'sensor_msgs/msg/NavSatFix', OUTPUT,
    "one message per plant placed on the earth (the as-planted map), for map views (Foxglove's "
    "Map panel reads NavSatFix): latitude and longitude (deg WGS 84) of the plant, altitude "
    "NaN, status FIX, covariance unknown; header.stamp = its planting instant, header.frame_id "
    "= its row's name ('row' for a machine without rows)")
PLANT_ROWS = Topic(
    'plant_rows', 'geometry_msgs/msg/Vector3Stamped', OUTPUT,
    "one message per plant, a key per row for per-row plots: header.frame_id = its row's name "
    "('row' without rows), header.stamp = its planting instant, vector.x = spacing error (m, NaN "
    "for a row's first plant), vector.y = speed ratio lambda (1 = in sync), vector.z = tilt "
    "(rad from vertical)")
UPRIGHTNESS_RATE = Topic(
    'uprightness_rate', 'std_msgs/msg/Float64', OUTPUT,
    'rolling fraction (0..1) of upright plants over the last `window` plants')
SECTIONS = Topic(
    'sections', 'sensor_msgs/msg/JointState', Qos('reliable', 'transient_local', 10),
    "each row's section, published by the sync node at start and at every switch: name = the "
    "rows enabled in the scene (the implicit row of a scene without rows: ''), position = 1 on "
    '(planting), 0 off (section_fields / section_states), velocity and effort empty, stamped '
    'at the switch')
SEEDLINGS = Topic(
    'seedlings', 'sensor_msgs/msg/JointState', SENSOR_DATA,
    "input (optional): each row's seedling sensor (an optical cup / drop-tube sensor), one "
    'reading per planting cycle before the planting point: name = row_joint(row, mechanism), '
    'position = seedlings counted (0 empty cup, 1, 2 a double), velocity and effort empty, '
    'stamped when read (prediction.seedlings)')
DIAGNOSTICS = Topic(
    '/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', STATE,
    'node health, ~1 Hz, absolute as diagnostic_aggregator expects (planter_ros.diagnostics)')
CLOCK = Topic(
    '/clock', 'rosgraph_msgs/msg/Clock', Qos('reliable', 'volatile', 100),
    'simulated time, published only by the lock-step sample feeder (use_sim_time)')

TOPICS = (GROUND_SPEED, DESIGN, JOINT_STATES, SPEED_COMMAND, SPEED_COMMANDS, GNSS_FIX, PLANTS,
          UPRIGHTNESS_RATE, SPACING_QUALITY, PLANT_MARKERS, PLANT_FIXES, PLANT_ROWS, SECTIONS,
          DIAGNOSTICS, CLOCK, SEEDLINGS, GNSS_VELOCITY, IMU, WHEEL_PULSES)
# what the monitor records: its inputs as they arrived, then its own outputs
MONITOR_INPUTS = (DESIGN, GROUND_SPEED, JOINT_STATES, SPEED_COMMAND, SPEED_COMMANDS, GNSS_FIX,
                  SECTIONS, DIAGNOSTICS, SEEDLINGS)
MONITOR_OUTPUTS = (PLANTS, UPRIGHTNESS_RATE, SPACING_QUALITY, PLANT_MARKERS, PLANT_FIXES,
                   PLANT_ROWS)
RECORDED = MONITOR_INPUTS + MONITOR_OUTPUTS
# MCAP metadata record of a monitor's bag holding its prediction settings (name -> repr)
PREDICTION_SETTINGS_RECORD = 'planter_monitor'
# MCAP metadata record of the monitor's as-planted map: its MapSettings and the scene's
# antenna_position, each value as JSON text. Absent: the defaults, the antenna at [0, 0].
MAP_RECORD = 'planter_map'
# MCAP metadata record naming the rows: key 'rows' = JSON list of {index, name, lateral_offset,
# drive_node_id, enabled}; a plant's `row` field is the index. Absent: one implicit row.
ROWS_RECORD = 'planter_rows'
# MCAP metadata record of the crop's acceptance limits the run was judged by
# (prediction.AcceptanceLimits, name -> repr). Absent: the defaults.
ACCEPTANCE_RECORD = 'planter_acceptance'


@dataclass(frozen=True)
class Service:
    """A service of the contract; a row's own is `<row>/<name>` (`for_row`)."""

    name: str
    type_name: str
    doc: str

    def srv_class(self) -> type[Any]:
        package, kind, base = self.type_name.split('/')
        cls: type[Any] = getattr(importlib.import_module(f'{package}.{kind}'), base)
        return cls

    def for_row(self, row_name: str) -> str:
        """The service's name for one row (the plain name for a scene without rows)."""
        return f'{row_name}/{self.name}' if row_name else self.name


RESET_FAULT = Service('reset_fault', 'std_srvs/srv/Trigger',
                      "sync node, per row: the only way out of the row's drive fault")
SECTION = Service('section', 'std_srvs/srv/SetBool',
                  'sync node, per row: data false = switch the row off (stops within one plant '
                  'pitch, plants nothing more), true = on (a new grid from the switch-on point)')

ENABLE_ROWS = Service('enable_rows', 'std_srvs/srv/Trigger',
                      'sync node: an operator enables the rows held at zero after an automatic '
                      'restart (of the command process or of the service; doc/command.md)')

# the mechanism's shaft in joint_states, per mechanism
MECHANISM_JOINT = {'five_bar': 'sun_bar', 'three_arm': 'carrier'}


def row_joint(row_name: str, mechanism: str) -> str:
    """A row's joint name in joint_states: `<row>/sun_bar` (`<row>/carrier`), or the plain
    `sun_bar` (`carrier`) for the implicit row of a scene without rows."""
    joint = MECHANISM_JOINT[mechanism]
    return f'{row_name}/{joint}' if row_name else joint


# a row's position in `sections`: on (planting) or off; a reader takes >= 0.5 as on
SECTION_ON, SECTION_OFF = 1.0, 0.0


def section_fields(states: Mapping[str, bool]) -> tuple[list[str], list[float]]:
    """The `sections` message's name and position of the rows' states {row name: on}."""
    return list(states), [SECTION_ON if on else SECTION_OFF for on in states.values()]


def section_states(names: Sequence[str], positions: Sequence[float]) -> dict[str, bool]:
    """{row name: on} of a `sections` message's name and position (a NaN position, or none,
    says nothing of its row)."""
    return {name: position >= 0.5 for name, position in zip(names, positions)
            if not math.isnan(position)}
