"""sync_node: ground speed and yaw rate -> each row's phase-locked mechanism speed -> its CiA 402
drive over CAN.

The machine has one planting unit (a scene without `rows`) or several (planter_ros.rows), each
with its own servo drive on the one CAN bus (one canopen Network: drive.drive_set). The law is
the pure `Machine` (control.machine: one PhaseLock per row on the row's own speed v − ω_z·y);
this node only moves data: ground-speed samples and drive feedback in, one velocity RPDO per
row out. The frames are sent inside the ground-speed callback (the latency that matters is
sample -> frame); a control timer sends the master heartbeat (once per bus), keeps commanding
while samples are missing (stale -> ramp to 0 -> halt) and publishes joint_states. The blocking
enable runs once at start-up, never in a callback: every row at once; a row whose drive does not
answer is reported and left out, the others run. A row's fault, EMCY or lost heartbeat commands
0 to that row only and waits for that row's `reset_fault`; `section` switches a row off and on.
A configuration whose CAN bus load exceeds 70 % is refused at start-up.
"""

import logging
import sys
import threading
import time

import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from planter_ros import diagnostics, interfaces, stop_signals
from planter_ros.config import ConfigError
from planter_ros.control import sync_status
from planter_ros.control.loop_timing import PeriodStats, SyncLoopConfig
from planter_ros.control.machine import Machine, TurnConfig
from planter_ros.control.phase_lock import PhaseLockConfig, PlantingAngles
from planter_ros.control.row_loop import RowLoop
from planter_ros.dds_domain import keep_discovery_on_host
from planter_ros.design import from_json
from planter_ros.scene.design_sources import DesignSources
from planter_ros.scene.files import SceneError
from planter_ros.drive.bus_load import bus_load, check_bus_load
from planter_ros.drive.config import DriveConfig
from planter_ros.drive.drive_set import DriveSet
from planter_ros.drive.errors import DriveError
from planter_ros.drive.states import FAULT
from planter_ros.nodes import graph
from planter_ros.nodes.parameters import ParameterGroup, declare_rows, refuse_undeclared
from planter_ros.rows import IMPLICIT
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
from planter_ros.sensing.row_speed import YawRateLimits


class RowUnit:
    """One row as the node runs it: the row, its law, its drive and what it last did."""

    def __init__(self, row, law, drive, hardware_id):
        self.row = row
        self.law = law
        self.drive = drive                  # None: disabled in the scene, never on the bus
        self.hardware_id = hardware_id
        self.running = False                # enabled at start-up and not shut down
        self.left_out = ''                  # why the drive was left out at start-up
        self.status = None
        self.halt = sync_status.NEVER_ENABLED
        self.command = 0.0
        self.send_errors = 0
        self.last_send_error = None         # (monotonic time, message)
        self.joint = None                   # joint name, once the design is known
        self.period = PeriodStats()         # gaps between its command frames
        self.faults = 0                     # drive faults (and lost heartbeats) seen
        self.last_fault = ''

    @property
    def label(self):
        return self.row.label


class SyncNode(Node):
    """Keeps each planting mechanism in step with its row's ground through a CiA 402 drive."""

    def __init__(self, bus=None, arguments=None, **kwargs):
        super().__init__('sync_node', **kwargs)
        self.drive_config = ParameterGroup(self, DriveConfig).value
        self.loop = ParameterGroup(self, SyncLoopConfig).value
        cfg = self.drive_config
        self.rows = declare_rows(self, cfg.drive_node_id)
        self.implicit = len(self.rows) == 1 and self.rows[0].name == IMPLICIT
        law = ParameterGroup(self, (PhaseLockConfig, GroundSpeedLimits, YawRateLimits,
                                    TurnConfig), on_change=self._on_law_parameters)
        refuse_undeclared(self, arguments)       # before the bus: a misnamed parameter stops it
        self.machine = Machine([row.lateral_offset for row in self.rows], *law.value)
        self.row_loop = RowLoop(self.machine, cfg.heartbeat_period, cfg.drive_heartbeat_timeout)
        enabled = [row for row in self.rows if row.enabled]
        self.bus_load = bus_load(len(enabled), cfg.can_bitrate, self.loop.control_period,
                                 self.loop.ground_speed_rate, cfg.feedback_period,
                                 cfg.drive_heartbeat_period, cfg.heartbeat_period)
        check_bus_load(self.bus_load, [row.label for row in enabled], self.loop.control_period,
                       self.loop.ground_speed_rate, cfg.feedback_period,
                       cfg.drive_heartbeat_period, cfg.heartbeat_period)
        self.drives = DriveSet(cfg, {row.name: row.drive_node_id for row in enabled}, bus=bus)
        self.bus_id = f'{cfg.can_interface}:{cfg.can_channel}'
        self.units = [RowUnit(row, self.machine.laws[row.index], self.drives.drives.get(row.name),
                              f'{self.bus_id} node {row.drive_node_id}')
                      for row in self.rows]
        self.hardware_id = self.units[0].hardware_id
        self._lock = threading.Lock()
        self._shut_down = False
        self._design_key = None
        self._mechanism = None
        self.design_sources = DesignSources()
        self._bus_send_errors = 0
        self._last_bus_error = None          # (monotonic time, message)

        group = MutuallyExclusiveCallbackGroup()    # one control thread of execution
        self._joint_pub = interfaces.JOINT_STATES.publisher(self)
        self._cmd_pub = (interfaces.SPEED_COMMAND if self.implicit
                         else interfaces.SPEED_COMMANDS).publisher(self)
        self._diag_pub = interfaces.DIAGNOSTICS.publisher(self)
        self._sections_pub = interfaces.SECTIONS.publisher(self)
        interfaces.GROUND_SPEED.subscribe(self, self._on_ground_speed, callback_group=group)
        interfaces.DESIGN.subscribe(self, self._on_design, callback_group=group)
        for unit in self.units:
            self.create_service(interfaces.RESET_FAULT.srv_class(),
                                interfaces.RESET_FAULT.for_row(unit.row.name),
                                lambda req, res, u=unit: self._on_reset_fault(u, req, res),
                                callback_group=group)
            self.create_service(interfaces.SECTION.srv_class(),
                                interfaces.SECTION.for_row(unit.row.name),
                                lambda req, res, u=unit: self._on_section(u, req, res),
                                callback_group=group)
        self.create_timer(self.loop.control_period, self._on_control, callback_group=group)
        self.create_timer(self.loop.diagnostics_period, self._on_diagnostics,
                          callback_group=group)
        self._publish_sections()            # latched: the monitor and recorders know at once

    # ---------------------------------------------------------------- the first row
    @property
    def law(self):
        """The first row's law (the only one in a scene without rows)."""
        return self.units[0].law

    @property
    def drive(self):
        return self.units[0].drive

    @property
    def command_value(self):
        """The first row's last command (rad/s)."""
        return self.units[0].command

    @property
    def _status(self):
        return self.units[0].status

    @property
    def send_errors(self):
        """CAN send errors so far, every row and the heartbeat."""
        return self._bus_send_errors + sum(unit.send_errors for unit in self.units)

    def unit(self, name):
        """The RowUnit of row `name` ('' for the implicit row)."""
        return next(unit for unit in self.units if unit.row.name == name)

    # ---------------------------------------------------------------- life cycle
    def enable_drive(self):
        """BLOCKING: configure and enable every row's drive at once (start-up only, never from
        a callback). A row whose drive does not answer is reported and left out; raises
        DriveError when no row runs (in a scene without rows: that drive's error)."""
        failures = self.drives.enable(keep_alive=self.loop.control_period)
        with_drive = [unit for unit in self.units if unit.drive is not None]
        if self.implicit and failures:
            raise next(iter(failures.values()))
        if with_drive and all(unit.row.name in failures for unit in with_drive):
            raise DriveError('no row\'s drive answered: '
                             + '; '.join(f'{u.label}: {failures[u.row.name]}'
                                         for u in with_drive))
        # at least one row runs: the start has succeeded, log what it found
        with self._lock:
            for unit in with_drive:
                if unit.row.name in failures:
                    unit.left_out = str(failures[unit.row.name])
                    self.get_logger().error(f'row {unit.label} left out: {unit.left_out}')
                else:
                    unit.running = True
                    unit.halt = None
                    self.row_loop.enabled(unit.row.index)
        running = [unit.label for unit in self.units if unit.running]
        if self.implicit:
            self.get_logger().info(f'drive {self.hardware_id} enabled (profile velocity)')
        else:
            self.get_logger().info(f'drives enabled (profile velocity): rows '
                                   f'{", ".join(running)} on {self.bus_id}')
        self.get_logger().info(
            f'{len(with_drive)} row(s) on {self.bus_id}: CAN bus load '
            f'{100 * self.bus_load.load:.1f} % of {self.drive_config.can_bitrate} bit/s '
            '(worst case)')

    def shutdown_drive(self):
        """BLOCKING, idempotent: every row at once: 0x60FF = 0, disable, NMT pre-operational."""
        with self._lock:
            if self._shut_down:
                return
            self._shut_down = True
            was_running = [unit for unit in self.units if unit.running]
            for unit in self.units:
                unit.running = False
        try:
            self.drives.shutdown()
            if was_running:
                self.get_logger().info('drive shut down (target 0, disabled, pre-operational)'
                                       if self.implicit else
                                       f'drives of rows {", ".join(u.label for u in was_running)}'
                                       ' shut down (target 0, disabled, pre-operational)')
        except DriveError as exc:
            self.get_logger().error(f'drive shutdown: {exc}')

    def destroy_node(self):
        self.shutdown_drive()
        return super().destroy_node()

    # ---------------------------------------------------------------- callbacks
    def _on_ground_speed(self, msg):
        now = time.monotonic()
        with self._lock:
            self.machine.sample(msg.twist.linear.x, msg.twist.angular.z, now)
            self._step(now)

    def _on_control(self):
        now = time.monotonic()
        with self._lock:
            self._step(now)
            feedback = [(unit.joint, unit.status) for unit in self.units
                        if unit.running and unit.joint is not None and unit.status is not None
                        and sync_status.has_feedback(unit.status)]
        if feedback:
            self._joint_pub.publish(self._joint_states(feedback))

    def _joint_states(self, feedback):
        """One JointState for every row with feedback, stamped when the newest feedback was
        measured; the other rows' angles carried to that instant with their measured speed
        (their feedback is at most one feedback period older)."""
        newest = max(status.stamp for _, status in feedback)
        age = min(max(time.monotonic() - newest, 0.0), 1.0)
        msg = JointState(name=[joint for joint, _ in feedback],
                         position=[st.position + st.velocity * (newest - st.stamp)
                                   for _, st in feedback],
                         velocity=[st.velocity for _, st in feedback])
        # stamped when the drive measured it, not when we got round to publishing
        msg.header.stamp = (self.get_clock().now() - Duration(seconds=age)).to_msg()
        return msg

    def _on_design(self, msg):
        if msg.data == (self._design_key or (None, None, None))[2]:
            return                                  # the design in force, delivered again
        try:
            design = from_json(msg.data)
            spacing = design.plant_spacing
            n = design.plants_per_revolution
            mechanism = design.mechanism
            joints = [unit.row.joint(mechanism) for unit in self.units]
            with self._lock:
                key = (spacing, n, msg.data)
                # each running row takes it at its next planting instant (the grid goes on)
                self.machine.set_design(spacing, n, time.monotonic())
                self._design_key = key
                self._mechanism = mechanism
                for unit, joint in zip(self.units, joints):
                    unit.joint = joint
        except (ValueError, KeyError, TypeError, ConfigError) as exc:
            self.get_logger().error(f'design ignored, keeping the last one: {exc}')
            return
        # where the mechanism plants (for section stops) may need scipy and a spline: found in
        # a worker thread, so the control loop never waits on it
        threading.Thread(target=self._find_planting_angles, args=(design, key), daemon=True,
                         name='planting-angles').start()
        self._log_design(design, spacing, n)

    def _log_design(self, design, spacing, n):
        """Log an accepted design with the node that published it (design_sources)."""
        what = f'{design.mechanism}, d = {spacing} m, {n} plant(s) per revolution'
        graph.log_accepted_design(self, self.design_sources, what,
                                  "in force from each row's next planting instant")

    def _find_planting_angles(self, design, key):
        planting = _planting_angles(design)
        with self._lock:
            if key == self._design_key:             # still the active design
                self.machine.set_planting(planting)

    def _on_reset_fault(self, unit, _request, response):
        with self._lock:
            if not unit.running:
                response.success = False
                response.message = f'row {unit.label} does not run ({self._idle_reason(unit)})'
                return response
            status = unit.drive.status()
            if not status.fault and status.state != FAULT:
                response.success = False
                response.message = f'no drive fault to reset (state {status.state})'
                return response
            unit.drive.request_fault_reset()
            response.success = True
            response.message = (f'fault reset requested (error 0x{status.error_code:04X}); the '
                                'drive re-enables if the cause is gone')
        self.get_logger().warning(response.message if self.implicit
                                  else f'row {unit.label}: {response.message}')
        return response

    def _on_section(self, unit, request, response):
        on = bool(request.data)
        with self._lock:
            if unit.drive is None:
                response.success = False
                response.message = f'row {unit.label} is disabled in the scene: it never plants'
                return response
            was = unit.law.section_on
            unit.law.switch(on, time.monotonic())
            response.success = True
            if was == on:
                response.message = f'row {unit.label} is already {"on" if on else "off"}'
            elif on:
                response.message = f'row {unit.label} on: a new grid starts here'
            else:
                stop = unit.law.stop_angle
                response.message = (f'row {unit.label} off: coming to rest'
                                     + (f' at {stop:.3f} rad' if stop is not None else ''))
        self.get_logger().info(response.message)
        if response.success and was != on:
            self._publish_sections()        # the instant of the switch, for the monitor
        return response

    def _publish_sections(self):
        """Every row's section on the latched `sections` topic (rows disabled in the scene
        never plant: not named)."""
        names, positions = interfaces.section_fields(
            {unit.row.name: unit.law.section_on for unit in self.units if unit.drive is not None})
        msg = JointState(name=names, position=positions)
        msg.header.stamp = self.get_clock().now().to_msg()
        self._sections_pub.publish(msg)

    def _on_law_parameters(self, value):
        with self._lock:
            self.machine.configure(*value)

    # ---------------------------------------------------------------- the control step
    def _step(self, now):
        """One command per running row: feedback in, law (or 0 when halted), one RPDO out;
        the master heartbeat once per bus when due. Caller holds the lock."""
        if not any(unit.running for unit in self.units):
            return
        for unit in self.units:
            if unit.running:
                unit.status = unit.drive.status()
        step = self.row_loop.step([unit.status if unit.running else None
                                   for unit in self.units],
                                  [unit.running for unit in self.units], now)
        for unit, row in zip(self.units, step.rows):
            if not row.running:
                continue
            if row.changed:
                self._report_halt(unit, row.halt, unit.status)
            unit.halt = row.halt
            try:
                unit.drive.send_velocity(row.command)
            except DriveError as exc:
                self._send_failed(now, exc, unit)
            unit.period.event(time.monotonic())      # when the frame went, not when asked for
            unit.command = row.command
        if step.heartbeat:          # due: from whichever path runs first, after the commands
            try:                    # (they are what is waited for)
                self.drives.send_heartbeat()
            except DriveError as exc:
                self._send_failed(now, exc, None)
        self._publish_commands()

    def _publish_commands(self):
        if self.implicit:
            self._cmd_pub.publish(Float64(data=self.units[0].command))
            return
        running = [unit for unit in self.units if unit.running and unit.joint is not None]
        if running:
            msg = JointState(name=[unit.joint for unit in running],
                             velocity=[unit.command for unit in running])
            msg.header.stamp = self.get_clock().now().to_msg()
            self._cmd_pub.publish(msg)

    def _report_halt(self, unit, halt, status):
        log = self.get_logger()
        row = '' if self.implicit else f'row {unit.label}: '
        service = interfaces.RESET_FAULT.for_row(unit.row.name)
        if halt is not None and halt.kind != sync_status.NOT_ENABLED:
            unit.faults += 1
            unit.last_fault = halt.text
        if halt is None:
            log.info(f'{row}drive back in operation: resuming')
        elif halt.kind == sync_status.FAULTED:
            log.error(f'{row}{halt.text} (state {status.state}): commanding 0; call the '
                      f'{service} service once the cause is cleared')
        else:
            log.warning(f'{row}{halt.text}: commanding 0')

    def _send_failed(self, now, exc, unit):
        """Count and hold a CAN send error of a row's RPDO (or of the heartbeat: unit None)."""
        last = self._last_bus_error if unit is None else unit.last_send_error
        first = last is None or now - last[0] > sync_status.SEND_ERROR_HOLD
        if unit is None:
            self._bus_send_errors += 1
            self._last_bus_error = (now, str(exc))
        else:
            unit.send_errors += 1
            unit.last_send_error = (now, str(exc))
        if first:
            self.get_logger().error(f'CAN send failed: {exc}')

    # ---------------------------------------------------------------- diagnostics
    def _on_diagnostics(self):
        self._diag_pub.publish(diagnostics.array(self._reports(), self.get_name(),
                                                 self.get_clock().now().to_msg()))

    def _idle_reason(self, unit):
        if unit.drive is None:
            return 'disabled in the scene: never enabled on the bus'
        if unit.left_out:
            return f'left out at start-up: {unit.left_out}'
        return 'shut down' if self._shut_down else 'not enabled yet'

    def _row_values(self, unit, now):
        law = unit.law
        return (('lateral offset', f'{unit.row.lateral_offset:.3f} m'),
                ('drive node id', unit.row.drive_node_id),
                ('row speed', f'{law.ground_speed_value:.4f} m/s'),
                ('row travelled', f'{law.travelled(now):.4f} m'))

    def _drive_report(self, unit, now):
        return sync_status.drive_report(unit.status, unit.running, self._shut_down, unit.halt,
                                        unit.send_errors, unit.last_send_error, unit.command,
                                        now)

    def diagnostics(self):
        """The DiagnosticStatus list the next /diagnostics message carries: a scene without
        rows keeps its three statuses (drive, ground speed, phase lock); with rows, one status
        per row; both add the bus (its load)."""
        return list(diagnostics.array(self._reports(), self.get_name()).status)

    def _reports(self):
        """(diagnostics.Report, hardware id) of every status, in the order published."""
        now = time.monotonic()
        with self._lock:
            states = [unit.law.state(now) for unit in self.units if unit.running]
            ramping = [state for state in states if state.startswith('ramping')]
            ground = sync_status.ground_report(self.machine.reference, now, self.machine,
                                               (ramping or states or [None])[0])
            bus = sync_status.bus_report(self.bus_load, self._last_bus_error, now)
            loop = sync_status.loop_report(
                [('' if self.implicit else unit.label, unit.period) for unit in self.units
                 if unit.drive is not None], self.drive_config.command_timeout)
            shared = [(loop, self.bus_id), (self.design_sources.report(), self.bus_id)]
            if self.implicit:
                unit = self.units[0]
                drive = self._drive_report(unit, now)
                if unit.status is None and unit.left_out:
                    drive = diagnostics.Report(diagnostics.DRIVE, diagnostics.ERROR,
                                               unit.left_out, drive.values)
                reports = [(drive, unit.hardware_id), (ground, unit.hardware_id),
                           (sync_status.phase_report(unit.law, now, unit.command),
                            unit.hardware_id),
                           (bus, self.bus_id)] + shared
            else:
                reports = [(ground, self.bus_id), (bus, self.bus_id)]
                for unit in self.units:
                    values = self._row_values(unit, now)
                    if unit.running or (unit.status is not None and self._shut_down):
                        report = sync_status.row_report(
                            unit.label, self._drive_report(unit, now),
                            sync_status.phase_report(unit.law, now, unit.command), values)
                    else:
                        level = diagnostics.OK if unit.drive is None else (
                            diagnostics.ERROR if unit.left_out else diagnostics.STALE)
                        report = sync_status.idle_row_report(unit.label,
                                                             self._idle_reason(unit), level,
                                                             values)
                    reports.append((report, unit.hardware_id))
                reports += shared
        return reports


def _planting_angles(design):
    """Where the design's mechanism plants on its shaft (for section stops), or None."""
    from planter_ros.prediction import planting_model_from_design
    try:
        model = planting_model_from_design(design)
    except (ValueError, TypeError, KeyError, ConfigError):
        return None
    return PlantingAngles(float(model.planting_phase), float(model.entry_angle),
                          float(model.exit_angle))


class LibraryLog(logging.Handler):
    """python-can and canopen (and our drive master) log through `logging`; with no handler
    Python prints their warnings raw on stderr, e.g. canopen's SDO abort just before our own
    error. Until the drive is enabled their records are held (a failed start is said in our
    one line, which names the cause); from then on they go to the node's ROS log."""

    LOGGERS = ('can', 'canopen', 'planter_ros.drive')

    def __init__(self):
        super().__init__(logging.WARNING)
        self.held = []
        self.node = None
        self._saved = []
        for name in self.LOGGERS:
            logger = logging.getLogger(name)
            self._saved.append((logger, logger.propagate))
            logger.addHandler(self)
            logger.propagate = False

    def emit(self, record):
        text = f'{record.name}: {record.getMessage()}'
        if self.node is None:
            self.held.append(text)
        else:
            self.node.get_logger().warning(text)

    def close(self):
        for logger, propagate in self._saved:
            logger.removeHandler(self)
            logger.propagate = propagate
        super().close()


def start_error(exc, config):
    """Our one line for a failed start: the cause, the bus and drive it was tried on, and the
    parameters that choose them."""
    text = f'sync_node: error: {str(exc).splitlines()[0]}'
    if config is None or not isinstance(exc, DriveError):
        return text
    return (f'{text} [tried can_interface={config.can_interface}, can_channel='
            f'{config.can_channel}, drive_node_id={config.drive_node_id}; choose them with '
            '--ros-args -p can_interface:=<socketcan|virtual|...> -p can_channel:=<can0|...> '
            '-p drive_node_id:=<1..127>]')


def main(args=None):
    keep_discovery_on_host()
    stop = stop_signals.install('sync_node')   # SIGTERM stops like Ctrl-C: drives shut down
    rclpy.init(args=args)
    library_log = LibraryLog()
    node = None
    error, code = None, 1
    try:
        node = SyncNode(namespace=interfaces.NAMESPACE,
                        arguments=sys.argv if args is None else args)
        node.enable_drive()
        library_log.node = node
        if stop.received is None:            # not stopped while the drives were enabled
            rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except SceneError as exc:                # a parameter file it refuses: bad input
        error, code = f'sync_node: error: {str(exc).splitlines()[0]}', 2
    except (DriveError, ConfigError, ParameterException) as exc:
        error = start_error(exc, node.drive_config if node is not None else None)
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        library_log.close()
    if error is not None:            # last, after the shutdown: nothing follows our line
        print(error, file=sys.stderr)
        return code
    return 0


if __name__ == '__main__':
    sys.exit(main())
