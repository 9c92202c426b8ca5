"""monitor_node: per-plant predictions from measured motion, and the MCAP recording.

Subscribes `ground_speed` (TwistStamped), `joint_states` (JointState) and the latched `design`
(String JSON); publishes each plant on `plants` (std_msgs/Float64MultiArray, labelled layout,
fields in `PLANT_FIELDS`, SI) and the rolling rate on `uprightness_rate` (std_msgs/Float64,
fraction 0..1), and `/diagnostics` at 1 Hz. It records its inputs (plus `speed_command` and
`/diagnostics`) as the CDR bytes that arrived (raw subscriptions) and its own outputs, through
the one recorder (planter_ros.recording.recorder).

The model is `planter_ros.kinematics.plant_prediction`; this node only turns messages into
calls of it. Inputs stamped 0 are timed by their receive time. Samples before the first design
are recorded but not predicted (replay does the same), and a changed design starts a new row.
"""

import json
import math

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.serialization import deserialize_message

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import TwistStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray, MultiArrayDimension, String

from planter_ros import interfaces
from planter_ros.nodes import qos
from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.plant_prediction import (
    PLANT_FIELDS, PlantPredictor, PredictionSettings, planting_model_from_design)

STALE_AFTER = 2.0          # s without input samples before the status says STALE
PLANTS_LABEL = ','.join(PLANT_FIELDS)


def input_qos():
    """QoS of the monitor's subscriptions (recorded as the topics' offered profiles): the
    graph's profiles (planter_ros.nodes.qos) with queues deep enough for a recorder."""
    return {'design': qos.DESIGN_QOS, 'speed': qos.deep(qos.GROUND_SPEED_QOS),
            'stream': qos.deep(qos.STATE_QOS)}


def plants_message(plants):
    """Float64MultiArray of a Plants batch: dim[0] 'plant' × dim[1] = the field names."""
    table = plants.table()
    n, f = table.shape
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label='plant', size=n, stride=n * f),
                      MultiArrayDimension(label=PLANTS_LABEL, size=f, stride=f)]
    msg.data = table.ravel().tolist()
    return msg


def _stamp_ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _descriptor(description, floating=None, integer=None, read_only=False):
    d = ParameterDescriptor(description=description, read_only=read_only)
    if floating is not None:
        d.floating_point_range = [FloatingPointRange(from_value=floating[0],
                                                     to_value=floating[1], step=0.0)]
    if integer is not None:
        d.integer_range = [IntegerRange(from_value=integer[0], to_value=integer[1], step=1)]
    return d


class MonitorNode(Node):
    """Predicts every plant from measured motion and records the run (see module doc)."""

    def __init__(self, node_name='monitor_node', *, namespace=interfaces.NAMESPACE, **kwargs):
        super().__init__(node_name, namespace=namespace, **kwargs)
        defaults = PredictionSettings()
        self.declare_parameter('record', True, _descriptor(
            'record inputs and predictions to an MCAP bag (rosbag2 layout)', read_only=True))
        self.declare_parameter('bag_path', '', _descriptor(
            'bag to write: a directory (rosbag2 layout) or a .mcap file; empty = '
            'bags/planter_<date-time>; an existing bag is never overwritten', read_only=True))
        self.declare_parameter('split_size', 0, _descriptor(
            'start a new bag file after this many bytes (0 = never)', integer=(0, 2 ** 40),
            read_only=True))
        self.declare_parameter('split_duration', 0.0, _descriptor(
            'start a new bag file after this many seconds of log time (0 = never)',
            floating=(0.0, 86400.0), read_only=True))
        self.declare_parameter('flush_period', 1.0, _descriptor(
            'seconds between MCAP chunk flushes: the most a killed recorder loses',
            floating=(0.05, 10.0), read_only=True))
        self.declare_parameter('upright_threshold', defaults.upright_threshold, _descriptor(
            'minimum stem angle to the ground (rad) for an upright plant; the literature '
            'counts < 30 deg as fallen, no standard value is confirmed',
            floating=(0.0, 0.5 * math.pi)))
        self.declare_parameter('nozzle_width', defaults.nozzle_width, _descriptor(
            'width of the nozzle along the row (m), added to the tip\'s swept hole extent',
            floating=(0.0, 0.5)))
        self.declare_parameter('window', defaults.window, _descriptor(
            'plants in the rolling uprightness rate', integer=(1, 10000)))
        self.settings = self._settings_from_parameters()
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.recorder = None
        self.record_error = ''
        self.has_design = False
        self.samples_taken = 0
        self._design_text = None
        self._model = None
        self._predictor = None
        self._joint_name = None
        self._tables = []
        self._plants = 0
        self._last = None
        self._last_input = None
        self._rate = None

        qos_in = input_qos()
        self._out_qos = qos.deep(qos.STATE_QOS)
        self._pub_plants = self.create_publisher(Float64MultiArray, interfaces.PLANTS,
                                                 self._out_qos)
        self._pub_rate = self.create_publisher(Float64, interfaces.UPRIGHTNESS_RATE,
                                               self._out_qos)
        self._pub_diag = self.create_publisher(DiagnosticArray, interfaces.DIAGNOSTICS, 10)
        if self.get_parameter('record').value:
            self._start_recorder(qos_in)
        # (topic, type, QoS, handler, time source for publish time)
        subs = [
            (interfaces.DESIGN, String, qos_in['design'], self._on_design),
            (interfaces.GROUND_SPEED, TwistStamped, qos_in['speed'], self._on_speed),
            (interfaces.JOINT_STATES, JointState, qos_in['stream'], self._on_joint),
            (interfaces.SPEED_COMMAND, Float64, qos_in['stream'], self._on_command),
            (interfaces.DIAGNOSTICS, DiagnosticArray, qos_in['stream'], self._on_diagnostics),
        ]
        self._subs = [self.create_subscription(
            msg_type, topic, self._raw_callback(topic, msg_type, handler), q, raw=True)
            for topic, msg_type, q, handler in subs]
        period = self.get_parameter('flush_period').value
        self.create_timer(0.25 * period, self._on_flush_timer)
        self.create_timer(1.0, self._publish_diagnostics)

    # -- parameters ----------------------------------------------------------------------
    def _settings_from_parameters(self, overrides=None):
        values = {name: self.get_parameter(name).value
                  for name in ('nozzle_width', 'upright_threshold', 'window')}
        values.update(overrides or {})
        return PredictionSettings(nozzle_width=float(values['nozzle_width']),
                                  upright_threshold=float(values['upright_threshold']),
                                  window=int(values['window']))

    def _on_set_parameters(self, params):
        wanted = {p.name: p.value for p in params
                  if p.name in ('nozzle_width', 'upright_threshold', 'window')}
        if not wanted:
            return SetParametersResult(successful=True)
        try:
            settings = self._settings_from_parameters(wanted)
        except (DesignError, TypeError, ValueError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.settings = settings
        if self._model is not None:
            self._predictor = PlantPredictor(self._model, settings)
            self.get_logger().info('prediction settings changed: a new row starts')
        return SetParametersResult(successful=True)

    # -- recording -----------------------------------------------------------------------
    def _start_recorder(self, qos_in):
        from planter_ros.recording.recorder import Recorder, RecorderError
        try:
            self.recorder = Recorder(
                self.get_parameter('bag_path').value or None,
                split_size=int(self.get_parameter('split_size').value),
                split_duration=float(self.get_parameter('split_duration').value),
                flush_period=float(self.get_parameter('flush_period').value))
        except RecorderError as exc:
            self.record_error = str(exc)
            self.get_logger().error(f'not recording: {exc}')
            return
        topics = [
            (interfaces.DESIGN, 'std_msgs/msg/String', qos_in['design']),
            (interfaces.GROUND_SPEED, 'geometry_msgs/msg/TwistStamped', qos_in['speed']),
            (interfaces.JOINT_STATES, 'sensor_msgs/msg/JointState', qos_in['stream']),
            (interfaces.SPEED_COMMAND, 'std_msgs/msg/Float64', qos_in['stream']),
            (interfaces.DIAGNOSTICS, 'diagnostic_msgs/msg/DiagnosticArray', qos_in['stream']),
            (interfaces.PLANTS, 'std_msgs/msg/Float64MultiArray', self._out_qos),
            (interfaces.UPRIGHTNESS_RATE, 'std_msgs/msg/Float64', self._out_qos),
        ]
        for topic, type_name, q in topics:
            self.recorder.add_topic(self.resolve_topic_name(topic), type_name, q)
        # the settings replay needs to reproduce these predictions
        self.recorder.add_metadata('planter_monitor', {
            'nozzle_width': repr(self.settings.nozzle_width),
            'upright_threshold': repr(self.settings.upright_threshold),
            'window': str(self.settings.window)})
        self.get_logger().info(f'recording to {self.recorder.path}')

    def _record(self, topic, data, log_ns, publish_ns=None, message=None):
        if self.recorder is None or self.recorder.closed:
            return
        try:
            name = self.resolve_topic_name(topic)
            if message is not None:
                self.recorder.write_message(name, message, log_ns, publish_ns)
            else:
                self.recorder.write(name, data, log_ns, publish_ns)
        except OSError as exc:
            # disk full or gone: stop recording, keep predicting, say so in diagnostics
            self.record_error = f'recording stopped: {exc}'
            self.get_logger().error(self.record_error)
            self.recorder = None

    def _on_flush_timer(self):
        if self.recorder is not None and not self.recorder.closed:
            try:
                self.recorder.tick()
            except OSError as exc:
                self.record_error = f'recording stopped: {exc}'
                self.get_logger().error(self.record_error)
                self.recorder = None

    # -- inputs --------------------------------------------------------------------------
    def _raw_callback(self, topic, msg_type, handler):
        def callback(raw):
            now = self.get_clock().now().nanoseconds
            msg = deserialize_message(raw, msg_type)
            stamp = _stamp_ns(msg.header.stamp) if hasattr(msg, 'header') else 0
            self._record(topic, raw, now, stamp or now)
            handler(msg, (stamp or now) * 1e-9, now)
        return callback

    def _on_design(self, msg, _t, _now):
        if msg.data == self._design_text:
            return
        try:
            design = json.loads(msg.data)
            model = planting_model_from_design(design)
        except (ValueError, DesignError) as exc:
            self.get_logger().error(f'design ignored: {str(exc).splitlines()[0]}')
            return
        self._design_text = msg.data
        self._model = model
        self._joint_name = interfaces.MECHANISM_JOINT.get(design.get('mechanism', 'five_bar'))
        self._predictor = PlantPredictor(model, self.settings)
        self.has_design = True
        self.get_logger().info(f'design received: {design.get("mechanism", "five_bar")}, '
                               f'd = {model.spacing:.4g} m, D = {model.depth:.4g} m')

    def _on_speed(self, msg, t, now):
        self.samples_taken += 1
        self._last_input = now
        if self._predictor is not None:
            self._publish_plants(self._predictor.add_speed(t, msg.twist.linear.x), now)

    def _on_joint(self, msg, t, now):
        self.samples_taken += 1
        self._last_input = now
        if self._predictor is None:
            return
        i = joint_index(msg, self._joint_name)
        if i is None:
            return
        velocity = msg.velocity[i] if len(msg.velocity) > i else math.nan
        self._publish_plants(self._predictor.add_joint(t, msg.position[i], velocity), now)

    def _on_command(self, _msg, _t, _now):
        self.samples_taken += 1

    def _on_diagnostics(self, _msg, _t, _now):
        pass

    # -- outputs -------------------------------------------------------------------------
    def _publish_plants(self, plants, now):
        if not len(plants):
            return
        msg = plants_message(plants)
        self._pub_plants.publish(msg)
        self._record(interfaces.PLANTS, None, now, now, message=msg)
        rate = Float64(data=float(plants.uprightness_rate[-1]))
        self._pub_rate.publish(rate)
        self._record(interfaces.UPRIGHTNESS_RATE, None, now, now, message=rate)
        self._tables.append(plants.table())
        self._plants += len(plants)
        self._last = plants
        self._rate = rate.data

    def published_tables(self):
        """Every plant table published so far (for the sample generator and tests)."""
        return list(self._tables)

    def _publish_diagnostics(self):
        now = self.get_clock().now()
        status = DiagnosticStatus(name=f'{self.get_name()}: prediction', hardware_id='planter')
        stale = (self._last_input is None
                 or (now.nanoseconds - self._last_input) * 1e-9 > STALE_AFTER)
        if not self.has_design:
            status.level, status.message = DiagnosticStatus.WARN, 'waiting for design'
        elif stale:
            status.level, status.message = DiagnosticStatus.STALE, 'no measured motion'
        else:
            status.level, status.message = DiagnosticStatus.OK, 'predicting'
        values = {'plants': self._plants,
                  'uprightness_rate': '' if self._rate is None else f'{self._rate:.4f}',
                  'upright_threshold_rad': f'{self.settings.upright_threshold:.6g}'}
        if self._last is not None:
            values.update({
                'last_spacing_error_m': f'{self._last.spacing_error[-1]:.6g}',
                'last_hole_width_m': f'{self._last.hole_width[-1]:.6g}',
                'last_tilt_rad': f'{self._last.tilt[-1]:.6g}',
                'last_speed_ratio': f'{self._last.speed_ratio[-1]:.6g}'})
        status.values = [KeyValue(key=k, value=str(v)) for k, v in values.items()]
        rec = DiagnosticStatus(name=f'{self.get_name()}: recording', hardware_id='planter')
        if self.recorder is not None:
            rec.level, rec.message = DiagnosticStatus.OK, 'recording'
            rec.values = [KeyValue(key='bag', value=str(self.recorder.path)),
                          KeyValue(key='messages', value=str(self.recorder.message_count)),
                          KeyValue(key='files', value=str(len(self.recorder.files)))]
        elif self.record_error:
            rec.level, rec.message = DiagnosticStatus.ERROR, self.record_error
        else:
            rec.level, rec.message = DiagnosticStatus.OK, 'recording off'
        self._pub_diag.publish(DiagnosticArray(header=_header(now), status=[status, rec]))

    def destroy_node(self):
        """Finalise the bag (summary, statistics, metadata) before the node goes."""
        if self.recorder is not None:
            try:
                self.recorder.close()
            except OSError as exc:
                self.get_logger().error(f'bag not finalised: {exc}')
        return super().destroy_node()


def _header(now):
    from std_msgs.msg import Header
    return Header(stamp=now.to_msg())


def joint_index(msg, name):
    """Index of the mechanism joint in a JointState (the only one if unnamed), or None."""
    if name in msg.name:
        i = msg.name.index(name)
    elif not msg.name and len(msg.position) == 1:
        i = 0
    else:
        return None
    return i if len(msg.position) > i else None


def main(args=None):
    rclpy.init(args=args)
    node = None
    try:
        node = MonitorNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


__all__ = ['MonitorNode', 'input_qos', 'joint_index', 'main', 'plants_message']
