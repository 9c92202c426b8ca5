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
did, whether or not the sync node compensated the turn). The model is
`planter_ros.prediction`; this node only turns messages into calls of it.
Inputs stamped 0 are timed by their receive time. Samples before the first design are recorded
but not predicted (replay does the same). A changed design is logged with the node that
published it (scene.design_sources), counted in /diagnostics, and scores plants from each
row's next planting instant on (the plant set next is still the old design's, as in the sync
law); a design of another mechanism starts a new sequence.
"""

from collections import deque
import math

import numpy as np

from rclpy.node import Node
from rclpy.serialization import deserialize_message

from std_msgs.msg import Float64, Float64MultiArray, MultiArrayDimension

from planter_ros import diagnostics, interfaces
from planter_ros.config import ConfigError, as_dict
from planter_ros.design import from_json
from planter_ros.scene.design_sources import DesignSources
from planter_ros.geo import AntennaSettings
from planter_ros.prediction import (
    PLANT_FIELDS, AcceptanceLimits, PlantPredictor, PredictionSettings, SectionBreaks,
    Plants, SeedlingAccount, design_spacing_of, planting_model_from_design, seedling_spacings)
from planter_ros.prediction import (
    QUALITY_FIELDS, SpacingQuality, format_quality)
from planter_ros.nodes import graph
from planter_ros.nodes.markers import marker_array, plant_fixes, plant_rows
from planter_ros.nodes.parameters import ParameterGroup, declare_rows, refuse_undeclared
from planter_ros.nodes.run import run_node
from planter_ros.recording.errors import BagWriteError
from planter_ros.recording.recorder import Recorder, RecorderConfig
from planter_ros.recording.replay import map_record
from planter_ros.rows import rows_record
from planter_ros.sensing.plant_map import MapSettings, PlantPlacer
from planter_ros.sensing.row_speed import RowSpeedStream

STALE_AFTER = 2.0          # s without input samples before the status says STALE
PLANTS_LABEL = ','.join(PLANT_FIELDS)
QUALITY_LABEL = ','.join(('row',) + QUALITY_FIELDS)
MACHINE = -1               # the `row` of the whole machine's line in spacing_quality
HARDWARE_ID = 'planter'    # the hardware_id of the monitor's statuses


def plants_message(plants):
    """Float64MultiArray of a Plants batch: dim[0] 'plant' × dim[1] = the field names."""
    table = plants.table()
    n, f = table.shape
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label='plant', size=n, stride=n * f),
                      MultiArrayDimension(label=PLANTS_LABEL, size=f, stride=f)]
    msg.data = table.ravel().tolist()
    return msg


def quality_message(qualities):
    """Float64MultiArray of [(row index, SpacingQuality.result())]: dim[0] 'row' x dim[1] the
    labels of QUALITY_LABEL; an undefined index is NaN."""
    table = [[float(row)] + [math.nan if q[f] is None else float(q[f]) for f in QUALITY_FIELDS]
             for row, q in qualities]
    msg = Float64MultiArray()
    n, f = len(table), len(QUALITY_FIELDS) + 1
    msg.layout.dim = [MultiArrayDimension(label='row', size=n, stride=n * f),
                      MultiArrayDimension(label=QUALITY_LABEL, size=f, stride=f)]
    msg.data = [v for line in table for v in line]
    return msg


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
        self._planting = [row for row in self.rows if row.enabled]
        self._labels = {row.index: row.label for row in self.rows}
        self._placer = self._new_placer(self._map_settings.value)
        self._quality = {row.index: SpacingQuality() for row in self._planting}
        self._machine_quality = SpacingQuality()
        self._drawn = {}                    # row index -> plants drawn (marker ids)
        self._sections = SectionBreaks()    # the rows' section states -> breaks
        # the rows' seedling sensors (as the scene declares them) -> each instant's
        self._seedlings = SeedlingAccount({row.index: row.seedling_sensor for row in self.rows})

        self.recorder = None
        self.record_error = ''
        self.has_design = False
        self.samples_taken = 0
        self._design_text = None
        self._model = None
        self._mechanism = None
        self.design_sources = DesignSources()
        self._predictors = None             # one PlantPredictor per planting row
        self._speeds = None                 # the rows' speeds (sensing.row_speed)
        self._joint_names = []
        self._recent = deque()              # upright flags of the machine's last plants
        self._tables = []
        self._plants = 0
        self._row_plants = {row.index: 0 for row in self._planting}
        self._last = None
        self._last_input = None
        self._rate = None

        self._pub_plants = interfaces.PLANTS.publisher(self)
        self._pub_rate = interfaces.UPRIGHTNESS_RATE.publisher(self)
        self._pub_quality = interfaces.SPACING_QUALITY.publisher(self)
        self._pub_markers = interfaces.PLANT_MARKERS.publisher(self)
        self._pub_fixes = interfaces.PLANT_FIXES.publisher(self)
        self._pub_rows = interfaces.PLANT_ROWS.publisher(self)
        self._pub_diag = interfaces.DIAGNOSTICS.publisher(self)
        if recording.record:
            self._start_recorder(recording)
        handlers = {interfaces.DESIGN: self._on_design,
                    interfaces.GROUND_SPEED: self._on_speed,
                    interfaces.JOINT_STATES: self._on_joint,
                    interfaces.SPEED_COMMAND: self._on_command,
                    interfaces.SPEED_COMMANDS: self._on_command,
                    interfaces.GNSS_FIX: self._on_fix,
                    interfaces.SECTIONS: self._on_sections,
                    interfaces.DIAGNOSTICS: self._on_diagnostics,
                    interfaces.SEEDLINGS: self._on_seedlings}
        self._subs = [topic.subscribe(self, self._raw_callback(topic, handlers[topic]),
                                      qos=topic.recording_qos(), raw=True)
                      for topic in interfaces.MONITOR_INPUTS]
        self.create_timer(0.25 * recording.flush_period, self._on_flush_timer)
        self.create_timer(1.0, self._publish_diagnostics)

    @property
    def settings(self):
        return self._settings.value

    def _on_settings(self, settings):
        if self._model is not None:
            self._start_predictors(settings)
            self.get_logger().info('prediction settings changed: a new sequence starts')

    def _new_placer(self, settings):
        return PlantPlacer(settings, self.antenna.antenna_position,
                           {row.index: row.lateral_offset for row in self.rows},
                           {row.index: row.longitudinal_offset for row in self.rows})

    def _on_map_settings(self, settings):
        """A new map from here on: the plants held so far are placed with the old one."""
        self._publish_placed(self._placer.flush(), self.get_clock().now().nanoseconds)
        self._placer = self._new_placer(settings)
        self.get_logger().info('map settings changed: a new map starts')

    def _start_predictors(self, settings):
        """Fresh predictors (and row speeds) for every planting row, as replay starts them at
        each design."""
        self._predictors = [PlantPredictor(self._model, settings, row=row.index,
                                           speed_filter=False) for row in self._planting]
        # the yaw rate always: the as-planted map dead-reckons the machine's heading
        self._speeds = RowSpeedStream([row.lateral_offset for row in self._planting],
                                      settings.speed_limits, yaw=True)
        self._recent = deque(maxlen=settings.window)

    # -- recording -----------------------------------------------------------------------
    def _start_recorder(self, recording):
        try:
            self.recorder = Recorder(recording.bag_path or None,
                                     split_size=recording.split_size,
                                     split_duration=recording.split_duration,
                                     flush_period=recording.flush_period)
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
            name = self.resolve_topic_name(topic.name)
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
            now = self.get_clock().now().nanoseconds
            msg = deserialize_message(raw, msg_type)
            stamp = _stamp_ns(msg.header.stamp) if hasattr(msg, 'header') else 0
            self._record(topic, raw, now, stamp or now)
            handler(msg, (stamp or now) * 1e-9, now)
        return callback

    def _on_design(self, msg, t, _now):
        if msg.data == self._design_text:
            return
        try:
            design = from_json(msg.data)
            model = planting_model_from_design(design)
        except (ValueError, ConfigError) as exc:
            self.get_logger().error(f'design ignored: {str(exc).splitlines()[0]}')
            return
        self._design_text = msg.data
        self._model = model
        mechanism = design.mechanism
        if self._predictors is None or mechanism != self._mechanism:
            # the first design, or another machine: a new sequence
            self._mechanism = mechanism
            self._joint_names = [row.joint(mechanism) for row in self._planting]
            self._start_predictors(self.settings)
        else:
            # in force from each row's next planting instant, as in the sync law
            for predictor in self._predictors:
                predictor.change_model(model, t)
        self.has_design = True
        self._log_design(mechanism, model)

    def _log_design(self, mechanism, model):
        """Log an accepted design with the node that published it (design_sources)."""
        what = f'{mechanism}, d = {model.spacing:.4g} m, D = {model.depth:.4g} m'
        graph.log_accepted_design(self, self.design_sources, what, 'plants are scored against '
                                  "it from each row's next planting instant")

    def _on_speed(self, msg, t, now):
        self.samples_taken += 1
        self._last_input = now
        if self._predictors is None:
            return
        motion = self._speeds.motion(t, msg.twist.linear.x, msg.twist.angular.z)
        if motion is None:
            return
        t, v, yaw_rate = motion
        self._publish_placed(self._placer.add_motion(t, v, yaw_rate), now)
        for predictor, speed in zip(self._predictors,
                                    self._speeds.speeds(v, yaw_rate).tolist()):
            self._predicted(predictor.add_speed(t, speed), now)

    def _on_joint(self, msg, t, now):
        self.samples_taken += 1
        self._last_input = now
        if self._predictors is None:
            return
        for predictor, name in zip(self._predictors, self._joint_names):
            i = joint_index(msg, name)
            if i is None:
                continue
            velocity = msg.velocity[i] if len(msg.velocity) > i else math.nan
            self._predicted(predictor.add_joint(t, msg.position[i], velocity), now)

    def _on_fix(self, msg, t, now):
        """A GNSS fix: it may place the plants held for it."""
        self.samples_taken += 1
        cov = msg.position_covariance
        self._publish_placed(self._placer.add_fix(
            t, msg.status.status, msg.latitude, msg.longitude, cov[0], cov[4],
            msg.position_covariance_type), now)

    def _on_command(self, _msg, _t, _now):
        """Speed commands: recorded; counted, since the lock-step feeder waits on every message
        it feeds."""
        self.samples_taken += 1

    def _on_sections(self, msg, t, _now):
        """The sync node's section states: a row switched off and on again starts a new
        sequence (its next plant has no spacing), like replay reads them from the bag."""
        self._section_states(t, interfaces.section_states(msg.name, msg.position))

    def _on_diagnostics(self, _msg, _t, _now):
        """/diagnostics: recorded (the run's health in the bag), nothing read from it."""

    def _on_seedlings(self, msg, t, _now):
        """A seedling sensor reading: each planting row's count (by its joint name), for the
        row's next planting instant (prediction.seedlings), as replay reads it."""
        self.samples_taken += 1
        if self._mechanism is None:
            return
        if not msg.name and len(self._planting) > 1:
            # a reading without a row's name on a machine of several rows belongs to none of
            # them for sure: not credited to every row (replay skips it the same way)
            self.get_logger().warning('a seedling reading without a row name on a machine of '
                                      f'{len(self._planting)} rows: skipped', once=True)
            return
        for row in self._planting:
            i = joint_index(msg, row.joint(self._mechanism))
            if i is not None and len(msg.position) > i:
                self._seedlings.add_reading(row.index, t, msg.position[i])

    def _section_states(self, t, states):
        """Rows' section states {row name: on} at `t` (s): each break they end goes to its
        row's predictor."""
        ended = {row: (start, end) for row, start, end in self._sections.update(t, states)}
        if not ended or self._predictors is None:
            return
        for predictor, row in zip(self._predictors, self._planting):
            if row.name in ended:
                predictor.add_break(*ended[row.name])

    # -- outputs -------------------------------------------------------------------------
    def _predicted(self, plants, now):
        """Plants just predicted: their seedlings and status, to the map, published once
        placed."""
        if len(plants):
            plants = self._seedlings.apply(plants, design_spacing_of(plants,
                                                                     self._model.spacing))
            self._publish_placed(self._placer.add_plants(plants), now)

    def _publish_placed(self, placed, now):
        for plants, placement in placed:
            self._publish_plants(plants, placement, now)

    def _publish(self, topic, publisher, msg, now):
        """Publish (if the context still runs: the last plants come at shutdown) and record."""
        try:
            publisher.publish(msg)
        except Exception as exc:         # rclpy's own error types once the context is down
            self.get_logger().debug(f'{topic.name} not published: {exc}')
        self._record(topic, None, now, now, message=msg)

    def _publish_plants(self, plants, placement, now):
        if not len(plants):
            return
        self._publish(interfaces.PLANTS, self._pub_plants, plants_message(plants), now)
        self._recent.extend(u for u in plants.upright.tolist() if math.isfinite(u))
        rate = Float64(data=float(sum(self._recent) / len(self._recent)) if self._recent
                       else math.nan)
        self._publish(interfaces.UPRIGHTNESS_RATE, self._pub_rate, rate, now)
        design_spacing = design_spacing_of(plants, self._model.spacing)
        for row in set(plants.row.astype(int).tolist()):
            mine = plants.row == row
            x, x_d = seedling_spacings(Plants.from_table(plants.table()[mine]),
                                       design_spacing[mine])
            self._quality.setdefault(row, SpacingQuality()).add(x, x_d)
        self._machine_quality.add(*seedling_spacings(plants, design_spacing))
        self._publish(interfaces.SPACING_QUALITY, self._pub_quality,
                      quality_message(self.spacing_quality()), now)
        if self._model is not None and np.any(np.isfinite(placement.east)):
            self._publish(interfaces.PLANT_MARKERS, self._pub_markers,
                          marker_array(plants, placement, self._model, self._labels,
                                       self._drawn), now)
        for fix in plant_fixes(plants, placement, self._labels):
            self._publish(interfaces.PLANT_FIXES, self._pub_fixes, fix, now)
        for msg in plant_rows(plants, self._labels):
            self._publish(interfaces.PLANT_ROWS, self._pub_rows, msg, now)
        self._tables.append(plants.table())
        self._plants += len(plants)
        for row in plants.row.astype(int).tolist():
            self._row_plants[row] = self._row_plants.get(row, 0) + 1
        self._last = plants
        self._rate = rate.data

    def spacing_quality(self):
        """[(-1, the machine's indices)], then (row index, indices) of every planting row: the
        machine first, so a viewer finds it at the same place whatever the rows."""
        return [(MACHINE, self._machine_quality.result())] + \
            [(row.index, self._quality[row.index].result()) for row in self._planting]

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
        values = {'plants': self._plants,
                  'uprightness_rate': '' if self._rate is None else f'{self._rate:.4f}',
                  'upright_threshold_rad': f'{self.settings.upright_threshold:.6g}'}
        if len(self.rows) > 1 or self.rows[0].name:
            values.update({f'plants {row.label}': self._row_plants[row.index]
                           for row in self._planting})
        if self._last is not None:
            values.update({
                'last_spacing_error_m': f'{self._last.spacing_error[-1]:.6g}',
                'last_hole_width_m': f'{self._last.hole_width[-1]:.6g}',
                'last_tilt_rad': f'{self._last.tilt[-1]:.6g}',
                'last_speed_ratio': f'{self._last.speed_ratio[-1]:.6g}'})
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
        now = self.get_clock().now().nanoseconds
        for predictor in self._predictors or ():
            self._predicted(predictor.finish(), now)
        self._publish_placed(self._placer.flush(), now)
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
    # a stop signal finalises the bag (the node's destroy_node)
    return run_node('monitor_node', lambda arguments: MonitorNode(arguments=arguments), args)


__all__ = ['MonitorNode', 'joint_index', 'main', 'plants_message']
