"""monitor_node: per-plant predictions from measured motion, and the MCAP recording.

Subscribes `ground_speed` (TwistStamped), `joint_states` (JointState), the latched `design`
(String JSON), `gnss/fix` (NavSatFix) and the latched `sections` (JointState: every row's section);
publishes each plant on `plants` (std_msgs/Float64MultiArray, labelled layout, fields in
`PLANT_FIELDS`, SI), the rolling rate on `uprightness_rate` (std_msgs/Float64, fraction 0..1,
over the last `window` plants of the whole machine), the ISO 7256-1 spacing-quality indices on
`spacing_quality`, the 3D view on `plant_markers` (visualization_msgs/MarkerArray), each plant
on `plant_fixes` (NavSatFix, for map views) and on `plant_rows` (Vector3Stamped keyed by row,
for per-row plots) and `/diagnostics` at 1 Hz. Each plant is placed on the earth from the GNSS
fixes (sensing.plant_map: held until the fixes that place it are in) before it is published.
It records its inputs (plus the speed commands and /diagnostics) as the CDR bytes that arrived
(raw subscriptions) and its own outputs, through the one recorder
(planter_ros.recording.recorder); the topics are interfaces.RECORDED, and the bag's rows record
names each row index.

A machine with several rows (the scene's `rows`, planter_ros.rows) is predicted row by row:
each row from its own joint and its own travelled distance, from the ground speed v, the yaw
rate ω_z and its lateral offset y (v − ω_z·y, sensing.row_speed: what the row's ground really
did, whether or not the sync node compensated the turn). The prediction is
`planter_ros.prediction.pipeline.MonitorPipeline`, the same one the season simulator records
(sim.season); this node only turns messages into calls of it and its batches into messages
(recording.monitor_topics builds `plants` and `spacing_quality`).
Inputs stamped 0 are timed by their receive time. Samples before the first design are recorded
but not predicted (replay does the same). A changed design is logged with the node that
published it (scene.design_sources), counted in /diagnostics, and scores plants from each
row's next planting instant on (the plant set next is still the old design's, as in the sync
law); a design of another mechanism starts a new sequence.
"""

import numpy as np

from rclpy.node import Node
from rclpy.serialization import deserialize_message

from std_msgs.msg import Float64

from planter_ros import diagnostics, interfaces
from planter_ros.config import ConfigError, as_dict
from planter_ros.design import from_json
from planter_ros.scene.design_sources import DesignSources
from planter_ros.geo import AntennaSettings
from planter_ros.prediction import (
    AcceptanceLimits, PredictionSettings, QUALITY_FIELDS, format_quality)
from planter_ros.prediction.pipeline import MACHINE, MonitorPipeline
from planter_ros.nodes import graph
from planter_ros.nodes.markers import marker_array, plant_fixes, plant_rows
from planter_ros.nodes.parameters import ParameterGroup, declare_rows, refuse_undeclared
from planter_ros.nodes.run import run_node
from planter_ros.recording.errors import BagWriteError
from planter_ros.recording.monitor_topics import plants_message, quality_message
from planter_ros.recording.recorder import BagLayout, Recorder, RecorderConfig
from planter_ros.recording.replay import map_record
from planter_ros.rows import rows_record
from planter_ros.sensing.plant_map import GnssFix, MapSettings

STALE_AFTER = 2.0          # s without input samples before the status says STALE
HARDWARE_ID = 'planter'    # the hardware_id of the monitor's statuses


def _stamp_ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


class MonitorNode(Node):
    """Predicts every plant from measured motion and records the run (see module doc)."""

    def __init__(self, node_name='monitor_node', *, namespace=interfaces.NAMESPACE,
                 arguments=None, **kwargs):
        super().__init__(node_name, namespace=namespace, **kwargs)
        recording = ParameterGroup(self, RecorderConfig).value
        self._settings = ParameterGroup(self, PredictionSettings,
                                        on_change=self._on_settings)
        self._map_settings = ParameterGroup(self, MapSettings, on_change=self._on_map_settings)
        self.antenna = ParameterGroup(self, AntennaSettings).value
        # the crop's acceptance limits: recorded, so replay judges the bag by them
        self.acceptance = ParameterGroup(self, AcceptanceLimits).value
        self.rows = declare_rows(self)
        refuse_undeclared(self, arguments)       # a name the scene got wrong: refused
        self._labels = {row.index: row.label for row in self.rows}
        # the prediction itself: the one pipeline the season simulator records too
        self.pipeline = MonitorPipeline(self.rows, self.settings, self._map_settings.value,
                                        self.antenna.antenna_position)
        self._drawn = {}                    # row index -> plants drawn (marker ids)

        self.recorder = None
        self.record_error = ''
        # topic name -> its name in the graph (the node's namespace and remappings, fixed
        # when the node was made): resolved once, not per recorded message
        self._resolved = {}
        self.samples_taken = 0
        self._design_text = None
        self.design_sources = DesignSources()
        self._tables = []
        self._last_input = None

        self._pub_plants = interfaces.PLANTS.publisher(self)
        self._pub_rate = interfaces.UPRIGHTNESS_RATE.publisher(self)
        self._pub_quality = interfaces.SPACING_QUALITY.publisher(self)
        self._pub_markers = interfaces.PLANT_MARKERS.publisher(self)
        self._pub_fixes = interfaces.PLANT_FIXES.publisher(self)
        self._pub_rows = interfaces.PLANT_ROWS.publisher(self)
        self._pub_diag = interfaces.DIAGNOSTICS.publisher(self)
        if recording.record:
            self._start_recorder(recording)
        self._handlers = {interfaces.DESIGN: self._on_design,
                          interfaces.GROUND_SPEED: self._on_speed,
                          interfaces.JOINT_STATES: self._on_joint,
                          interfaces.SPEED_COMMAND: self._on_command,
                          interfaces.SPEED_COMMANDS: self._on_command,
                          interfaces.GNSS_FIX: self._on_fix,
                          interfaces.SECTIONS: self._on_sections,
                          interfaces.DIAGNOSTICS: self._on_diagnostics,
                          interfaces.SEEDLINGS: self._on_seedlings}
        self._subs = [topic.subscribe(self, self._raw_callback(topic, self._handlers[topic]),
                                      qos=topic.recording_qos(), raw=True)
                      for topic in interfaces.MONITOR_INPUTS]
        self.create_timer(0.25 * recording.flush_period, self._on_flush_timer)
        self.create_timer(1.0, self._publish_diagnostics)

    @property
    def settings(self):
        return self._settings.value

    @property
    def has_design(self):
        return self.pipeline.has_design

    def _on_settings(self, settings):
        self.pipeline.set_settings(settings)
        if self.pipeline.has_design:
            self.get_logger().info('prediction settings changed: a new sequence starts')

    def _on_map_settings(self, settings):
        """A new map from here on: the plants held so far are placed with the old one."""
        self._publish(self.pipeline.set_map(settings), self.get_clock().now().nanoseconds)
        self.get_logger().info('map settings changed: a new map starts')

    # -- recording -----------------------------------------------------------------------
    def _start_recorder(self, recording):
        try:
            self.recorder = Recorder(recording.bag_path or None, BagLayout(
                split_size=recording.split_size, split_duration=recording.split_duration,
                flush_period=recording.flush_period))
        except BagWriteError as exc:
            self.record_error = str(exc)
            self.get_logger().error(f'not recording: {exc}')
            return
        for topic in interfaces.RECORDED:
            self.recorder.add_topic(self.resolve_topic_name(topic.name), topic.type_name,
                                    topic.recording_qos())
        # the settings replay needs to reproduce these predictions
        self.recorder.add_metadata(interfaces.PREDICTION_SETTINGS_RECORD, {k: repr(v) for k, v in
                                                     as_dict(self.settings).items()})
        self.recorder.add_metadata(interfaces.ROWS_RECORD, rows_record(self.rows))
        self.recorder.add_metadata(interfaces.ACCEPTANCE_RECORD, {
            k: repr(v) for k, v in as_dict(self.acceptance).items()})
        self.recorder.add_metadata(interfaces.MAP_RECORD,
                                   map_record(self._map_settings.value, self.antenna))
        self.get_logger().info(f'recording to {self.recorder.path}')

    def _record(self, topic, data, log_ns, publish_ns=None, message=None):
        if self.recorder is None or self.recorder.closed:
            return
        try:
            name = self._resolved.get(topic.name)
            if name is None:
                name = self._resolved[topic.name] = self.resolve_topic_name(topic.name)
            if message is not None:
                self.recorder.write_message(name, message, log_ns, publish_ns)
            else:
                self.recorder.write(name, data, log_ns, publish_ns)
        except OSError as exc:
            self._recording_failed(exc)

    def _recording_failed(self, exc):
        """Disk full or gone: stop recording, keep predicting, say so in diagnostics."""
        self.record_error = f'recording stopped: {exc}'
        self.get_logger().error(self.record_error)
        self.recorder = None

    def _on_flush_timer(self):
        if self.recorder is not None and not self.recorder.closed:
            try:
                self.recorder.tick()
            except OSError as exc:
                self._recording_failed(exc)

    # -- inputs --------------------------------------------------------------------------
    def _raw_callback(self, topic, handler):
        msg_type = topic.msg_class()

        def callback(raw):
            self.receive(topic, raw, self.get_clock().now().nanoseconds, handler, msg_type)
        return callback

    def receive(self, topic, raw, now, handler=None, msg_type=None):
        """One input message `raw` (CDR bytes) of `topic` (one of interfaces.MONITOR_INPUTS)
        received at `now` (ns): recorded, then handled, timed by its stamp (its receive time
        when it has none or 0). The subscriptions call it with the node's clock; replaying a
        recording into the node, with the recorded log time."""
        msg = deserialize_message(raw, msg_type or topic.msg_class())
        stamp = _stamp_ns(msg.header.stamp) if hasattr(msg, 'header') else 0
        self._record(topic, raw, now, stamp or now)
        (handler or self._handlers[topic])(msg, (stamp or now) * 1e-9, now)

    def _on_design(self, msg, t, _now):
        if msg.data == self._design_text:
            return
        try:
            design = from_json(msg.data)
            self.pipeline.set_design(t, design)
        except (ValueError, ConfigError) as exc:
            self.get_logger().error(f'design ignored: {str(exc).splitlines()[0]}')
            return
        self._design_text = msg.data
        self._log_design(design.mechanism, self.pipeline.model)

    def _log_design(self, mechanism, model):
        """Log an accepted design with the node that published it (design_sources)."""
        what = f'{mechanism}, d = {model.spacing:.4g} m, D = {model.depth:.4g} m'
        graph.log_accepted_design(self, self.design_sources, what, 'plants are scored against '
                                  "it from each row's next planting instant")

    def _on_speed(self, msg, t, now):
        self.samples_taken += 1
        self._last_input = now
        self._publish(self.pipeline.speed(t, msg.twist.linear.x, msg.twist.angular.z), now)

    def _on_joint(self, msg, t, now):
        self.samples_taken += 1
        self._last_input = now
        self._publish(self.pipeline.joints(t, msg.name, msg.position, msg.velocity), now)

    def _on_fix(self, msg, t, now):
        """A GNSS fix: it may place the plants held for it."""
        self.samples_taken += 1
        cov = msg.position_covariance
        self._publish(self.pipeline.fix(GnssFix(t, msg.status.status, msg.latitude,
                                                msg.longitude, cov[0], cov[4],
                                                msg.position_covariance_type)), now)

    def _on_command(self, _msg, _t, _now):
        """Speed commands: recorded; counted, since the lock-step feeder waits on every message
        it feeds."""
        self.samples_taken += 1

    def _on_sections(self, msg, t, _now):
        """The sync node's section states: a row switched off and on again starts a new
        sequence (its next plant has no spacing), like replay reads them from the bag."""
        self.pipeline.sections(t, interfaces.section_states(msg.name, msg.position))

    def _on_diagnostics(self, _msg, _t, _now):
        """/diagnostics: recorded (the run's health in the bag), nothing read from it."""

    def _on_seedlings(self, msg, t, _now):
        """A seedling sensor reading: each planting row's count (by its joint name), for the
        row's next planting instant (prediction.seedlings), as replay reads it."""
        self.samples_taken += 1
        if not self.pipeline.seedlings(t, msg.name, msg.position):
            self.get_logger().warning('a seedling reading without a row name on a machine of '
                                      f'{len(self.pipeline.planting)} rows: skipped', once=True)

    # -- outputs -------------------------------------------------------------------------
    def _publish(self, placed, now):
        """Publish (and record) every batch the pipeline released, with what goes with it."""
        for batch in placed:
            self._publish_plants(batch, now)

    def _send(self, topic, publisher, msg, now):
        """Publish (if the context still runs: the last plants come at shutdown) and record."""
        try:
            publisher.publish(msg)
        except Exception as exc:         # rclpy's own error types once the context is down
            self.get_logger().debug(f'{topic.name} not published: {exc}')
        self._record(topic, None, now, now, message=msg)

    def _publish_plants(self, batch, now):
        plants, placement = batch.plants, batch.placement
        self._send(interfaces.PLANTS, self._pub_plants, plants_message(plants), now)
        self._send(interfaces.UPRIGHTNESS_RATE, self._pub_rate,
                   Float64(data=batch.upright_rate), now)
        self._send(interfaces.SPACING_QUALITY, self._pub_quality,
                   quality_message(batch.quality), now)
        if np.any(np.isfinite(placement.east)):
            self._send(interfaces.PLANT_MARKERS, self._pub_markers,
                       marker_array(plants, placement, self.pipeline.model, self._labels,
                                    self._drawn), now)
        for fix in plant_fixes(plants, placement, self._labels):
            self._send(interfaces.PLANT_FIXES, self._pub_fixes, fix, now)
        for msg in plant_rows(plants, self._labels):
            self._send(interfaces.PLANT_ROWS, self._pub_rows, msg, now)
        self._tables.append(plants.table())

    def spacing_quality(self):
        """[(-1, the machine's indices)], then (row index, indices) of every planting row
        (MonitorPipeline.spacing_quality)."""
        return list(self.pipeline.spacing_quality())

    def published_tables(self):
        """Every plant table published so far (for the sample generator and tests)."""
        return list(self._tables)

    def _publish_diagnostics(self):
        now = self.get_clock().now()
        self._pub_diag.publish(diagnostics.array(
            [(report, HARDWARE_ID) for report in self.reports(now.nanoseconds)],
            self.get_name(), now.to_msg()))

    def reports(self, now_ns):
        """The monitor's diagnostics.Reports: prediction, spacing quality, recording, design."""
        stale = (self._last_input is None or (now_ns - self._last_input) * 1e-9 > STALE_AFTER)
        if not self.has_design:
            level, message = diagnostics.WARN, 'waiting for design'
        elif stale:
            level, message = diagnostics.STALE, 'no measured motion'
        else:
            level, message = diagnostics.OK, 'predicting'
        pipeline = self.pipeline
        rate, last = pipeline.upright_rate, pipeline.last
        values = {'plants': pipeline.plants,
                  'uprightness_rate': '' if rate is None else f'{rate:.4f}',
                  'upright_threshold_rad': f'{self.settings.upright_threshold:.6g}'}
        if len(self.rows) > 1 or self.rows[0].name:
            values.update({f'plants {row.label}': pipeline.row_plants[row.index]
                           for row in pipeline.planting})
        if last is not None:
            values.update({
                'last_spacing_error_m': f'{last.spacing_error[-1]:.6g}',
                'last_hole_width_m': f'{last.hole_width[-1]:.6g}',
                'last_tilt_rad': f'{last.tilt[-1]:.6g}',
                'last_speed_ratio': f'{last.speed_ratio[-1]:.6g}'})
        prediction = diagnostics.Report(diagnostics.PREDICTION, level, message,
                                        tuple(values.items()))
        if self.recorder is not None:
            recording = diagnostics.Report(diagnostics.RECORDING, diagnostics.OK, 'recording', (
                ('bag', self.recorder.path), ('messages', self.recorder.message_count),
                ('files', len(self.recorder.files))))
        elif self.record_error:
            recording = diagnostics.Report(diagnostics.RECORDING, diagnostics.ERROR,
                                           self.record_error)
        else:
            recording = diagnostics.Report(diagnostics.RECORDING, diagnostics.OK,
                                           'recording off')
        return [prediction, self._quality_report(), recording, self.design_sources.report()]

    def _quality_report(self):
        """The spacing-quality indices so far, the machine's and each row's (no judgement: OK
        once there are spacings; the standard sets no limit)."""
        lines = self.spacing_quality()
        machine = lines[0][1]
        message = format_quality(machine) if machine['spacings'] else 'no spacings yet'
        named = len(self.rows) > 1 or bool(self.rows[0].name)
        values = []
        for row, quality in lines:
            if row != MACHINE and not named:
                continue                     # one row without a name: the machine's line
            where = '' if row == MACHINE else f' {self._labels[row]}'
            values += [(f'{field}{where}', _quality_text(quality[field]))
                       for field in QUALITY_FIELDS]
        return diagnostics.Report(diagnostics.SPACING_QUALITY, diagnostics.OK, message,
                                  tuple(values))

    def destroy_node(self):
        """Complete the plants whose arcs were still open, place and publish the plants still
        held for fixes, then finalise the bag (summary, statistics, metadata) before the node
        goes."""
        self._publish(self.pipeline.finish(), self.get_clock().now().nanoseconds)
        if self.recorder is not None:
            try:
                self.recorder.close()
            except OSError as exc:
                self.record_error = f'bag not finalised: {exc}'
                self.get_logger().error(self.record_error)
        return super().destroy_node()


def _quality_text(value):
    if value is None:
        return ''
    return str(value) if isinstance(value, int) else f'{value:.4f}'


def main(args=None):
    # a stop signal finalises the bag (the node's destroy_node)
    return run_node('monitor_node', lambda arguments: MonitorNode(arguments=arguments), args)


__all__ = ['MonitorNode', 'main']
