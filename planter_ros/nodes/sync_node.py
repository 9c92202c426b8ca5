"""sync_node: ground speed and yaw rate -> each row's phase-locked mechanism speed -> its CiA 402
drive over CAN.

The node is a shell: the command path (the CAN bus, the CiA 402 masters, the heartbeats, the
row loop: `planter_ros.command.engine.CommandEngine`) runs in a command process of its own with
no DDS participant and no rclpy (`planter_ros.command`, doc/command.md), so no ROS graph event
(a node joining, a publisher blocking) can stall the frames the drives wait for. The node
translates topics and services into messages to it (ground speed: latest value; designs and
section switches: never lost) and publishes what it returns (joint_states, speed commands,
/diagnostics), and supervises it (a dead command process is reported as ERROR and restarted).
With `command_process: false`, a `virtual` CAN interface (in-process by nature) or a bus object
handed in (tests), the same engine runs in this node's process instead.

The machine has one planting unit (a scene without `rows`) or several (planter_ros.rows), each
with its own servo drive on the one CAN bus. A row's fault, EMCY or lost heartbeat commands 0
to that row only and waits for that row's `reset_fault`; `section` switches a row off and on.
A configuration whose CAN bus load exceeds 70 % is refused at start-up.

With `machine_file` (doc/machine_file.md) the machine file's bus, rows, node ids, lever arms
and drive train are the defaults of those parameters, and each row's drive is checked against
it and set up from it at every start (drive.setup, in the command path's configure step). The
law's run-time limits are refused, with the reason and the limit, when the design in force
could not run within them (planter_ros.plausibility.check_law).
"""

import functools
import logging
import sys
import time

import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from planter_ros import diagnostics, interfaces
from planter_ros.host import stop_signals
from planter_ros.host import realtime
from planter_ros.command.client import CommandClient
from planter_ros.command.engine import CommandEngine
from planter_ros.command.settings import LAW_CLASSES, CommandSettings
from planter_ros.config import ConfigError, from_mapping, spec_of
from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.control.machine_law import TurnConfig
from planter_ros.control.phase_lock import PhaseLockConfig
from planter_ros.host.dds_domain import keep_discovery_on_host
from planter_ros.design import from_json
from planter_ros.scene.design_sources import DesignSources
from planter_ros.scene.files import SceneError
from planter_ros.drive.config import DriveConfig
from planter_ros.drive.errors import DriveError
from planter_ros.nodes import graph
from planter_ros.plausibility import check_law
from planter_ros.nodes.parameters import (ParameterGroup, _plain, declare, declare_rows,
                                          refuse_undeclared)
from planter_ros.scene.machine_file import MachineFileSetting, open_machine
from planter_ros.rows import IMPLICIT
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
from planter_ros.sensing.row_speed import YawRateLimits

# a feedback sample's stamp is carried back from the command process's clock at most this
# far (s): the queue it waits in holds 5 s (command.inbox.FEEDBACK_QUEUE)
STAMP_AGE_MAX = 10.0


def restart_hold_reason(loop):
    """Why this start must wait for an operator ('' = it need not): the service manager's note
    of how the graph's last run ended (`last_stop_file`, written by systemd/planter.service
    after every stop) says it did not end with success, so this start is an automatic restart
    (a boot or an operator's stop and start leaves no note: /run is new, the unit removes its
    runtime directory on a stop). `enable_after_restart` (a fenced machine) never waits."""
    if loop.enable_after_restart or not loop.last_stop_file:
        return ''
    try:
        with open(loop.last_stop_file, encoding='utf-8', errors='replace') as note:
            text = ' '.join(note.read(200).split())
    except OSError:
        return ''
    if not text or text.split()[0] == 'success':
        return ''
    return f'the service restarted after its last run ended: {text}'


class SyncNode(Node):
    """Keeps each planting mechanism in step with its row's ground through a CiA 402 drive.
    `stop`: the process's stop_signals handler (a stop asked for: nothing restarts the command
    process or enables a drive; the command process stopped by a signal of its own stops this
    node too)."""

    def __init__(self, bus=None, arguments=None, stop=None, **kwargs):
        super().__init__('sync_node', **kwargs)
        self._stop = stop
        self.machine = self._machine_file()
        self.drive_config = ParameterGroup(self, DriveConfig).value
        self.loop = ParameterGroup(self, SyncLoopConfig).value
        cfg = self.drive_config
        self.rows = declare_rows(self, cfg.drive_node_id)
        self.implicit = len(self.rows) == 1 and self.rows[0].name == IMPLICIT
        setups = self._drive_setups()
        self._design = None                      # the design in force (law plausibility)
        law = ParameterGroup(self, (PhaseLockConfig, GroundSpeedLimits, YawRateLimits,
                                    TurnConfig), build=self._checked_law,
                             on_change=self._on_law_parameters)
        refuse_undeclared(self, arguments)       # before the bus: a misnamed parameter stops it
        self.in_process = (bus is not None or not self.loop.command_process
                           or cfg.can_interface == 'virtual')
        self._held_logs = []                     # the command process's, until it is ready
        self._ready = False
        self.hold_reason = restart_hold_reason(self.loop)   # the rows wait for an operator
        self._in_process_held = False
        settings = CommandSettings(cfg, self.loop, self.rows, law.value, setups=setups)
        # in process: the engine itself; else the client of the command process that runs it
        self.engine: CommandEngine | CommandClient
        if self.in_process:
            self.engine = CommandEngine(settings, bus=bus, log=self._log)
        else:
            self.engine = CommandClient(
                settings,
                log=self._log, stop_asked=self._stop_asked, on_exit=self._command_stopped,
                enable_service=self.resolve_service_name(interfaces.ENABLE_ROWS.name))
        self.bus_load = self.engine.bus_load
        self.bus_id = f'{cfg.can_interface}:{cfg.can_channel}'
        self.hardware_id = f'{self.bus_id} node {self.rows[0].drive_node_id}'
        self.design_sources = DesignSources()
        self._design_text = None

        group = MutuallyExclusiveCallbackGroup()    # one control thread of execution
        self._joint_pub = interfaces.JOINT_STATES.publisher(self)
        self._cmd_pub = (interfaces.SPEED_COMMAND if self.implicit
                         else interfaces.SPEED_COMMANDS).publisher(self)
        self._diag_pub = interfaces.DIAGNOSTICS.publisher(self)
        self._sections_pub = interfaces.SECTIONS.publisher(self)
        interfaces.GROUND_SPEED.subscribe(self, self._on_ground_speed, callback_group=group)
        interfaces.DESIGN.subscribe(self, self._on_design, callback_group=group)
        for row in self.rows:
            self.create_service(interfaces.RESET_FAULT.srv_class(),
                                interfaces.RESET_FAULT.for_row(row.name),
                                functools.partial(self._on_reset_fault, row),
                                callback_group=group)
            self.create_service(interfaces.SECTION.srv_class(),
                                interfaces.SECTION.for_row(row.name),
                                functools.partial(self._on_section, row),
                                callback_group=group)
        self.create_service(interfaces.ENABLE_ROWS.srv_class(), interfaces.ENABLE_ROWS.name,
                            self._on_enable_rows, callback_group=group)
        self._group = group
        self._control_timer = self.create_timer(self.loop.control_period, self._on_control,
                                                callback_group=group)
        self.create_timer(self.loop.diagnostics_period, self._on_diagnostics,
                          callback_group=group)
        self._last_fb = -1
        self._publish_sections(self._initial_sections())   # latched: known at once

    def _machine_file(self):
        """The `machine_file` parameter's Machine (None without one): its bus, rows, node ids,
        lever arms and drive train become the defaults of those parameters (an explicit value
        wins; a different one is warned about). SceneError (one line) for a bad file."""
        path = declare(self, spec_of(MachineFileSetting, 'machine_file'))
        if not path:
            return None
        machine = open_machine(path)
        given = self._parameter_overrides          # rclpy's: what the node was given
        for name, value in machine.node_parameters()['sync_node'].items():
            if name == 'machine_file':
                continue
            if name not in given:
                given[name] = Parameter(name, value=value)
            elif _plain(given[name].value) != value:
                self.get_logger().warning(
                    f'{name} = {_plain(given[name].value)!r} given; the machine file {path} '
                    f'says {value!r}: using {_plain(given[name].value)!r}')
        return machine

    def _drive_setups(self):
        """{row: DriveSetup} of the machine file, checked, applied at every enable; SceneError
        for a row the machine file does not have."""
        if self.machine is None:
            return {}
        setups = self.machine.drive_setups()
        for row in self.rows:
            if row.name not in setups:
                raise SceneError(f'row {row.label} is not a row of the machine file '
                                 f'{self.machine.path}: allowed {", ".join(setups)}')
        return {row.name: setups[row.name] for row in self.rows}

    def _checked_law(self, values):
        """The law's configuration from `values`; a limit the design in force would exceed at
        its ground speed or a tractor's acceleration is refused with the reason and the limit
        (planter_ros.plausibility, the scene loader's checks), unusual values warned about."""
        built = tuple(from_mapping(cls, values) for cls in LAW_CLASSES)
        if self._design is not None:
            limits = self.machine.row_limits() if self.machine is not None else ()
            for warning in check_law(self._design, built[0], built[1], limits):
                self.get_logger().warning(warning)
        return built

    def _log(self, level, text):
        """A line of the engine (here or in the command process): held until the drives are
        enabled (a failed start is said in one line, naming the cause), then the ROS log."""
        if not self._ready and level < logging.ERROR:
            self._held_logs.append((level, text))
            return
        logger = self.get_logger()       # (rclpy: one severity per call site)
        if level >= logging.ERROR:
            logger.error(text)
        elif level >= logging.WARNING:
            logger.warning(text)
        elif level >= logging.INFO:
            logger.info(text)
        else:
            logger.debug(text)

    def _initial_sections(self):
        return {row.name: True for row in self.rows if row.enabled}

    # ---------------------------------------------------------------- what it commands
    @property
    def command_value(self):
        """The first row's last command (rad/s)."""
        commands = self.engine.commands()
        return commands[0][1] if commands else 0.0

    @property
    def send_errors(self):
        """CAN send errors so far (with a command process: as its final report says, 0
        before it)."""
        if isinstance(self.engine, CommandEngine):
            return self.engine.send_errors
        report = self.engine.final_report()
        return report.send_errors if report is not None else 0

    # ---------------------------------------------------------------- life cycle
    def raise_shell_priority(self):
        """A process of its own (main, the demo's sync process) with a command process: every
        thread of it at `shell_nice`, so CPU-bound neighbours do not hold a ground-speed sample
        between its receipt and the channel (refused: said in the log once the drives run)."""
        if not self.in_process:
            refused = realtime.request_nice(self.loop.shell_nice)
            if refused:
                self._log(logging.WARNING, f'sync node shell runs at normal priority: {refused}')

    def _stop_asked(self):
        return self._stop is not None and self._stop.received is not None

    def _command_stopped(self, reason):
        """The command process ended on purpose (a stop signal reached it alone): a stop is a
        stop, this node stops too."""
        if self._stop is not None:
            self._stop.ask(stop_signals.signal_number(reason), 'the command process')

    @property
    def held(self):
        """The rows wait at zero for an operator's enable_rows."""
        if isinstance(self.engine, CommandEngine):      # in process
            return self._in_process_held
        return self.engine.held

    def enable_drive(self):
        """BLOCKING: start the command path and enable every row's drive at once (start-up
        only). A row whose drive does not answer is reported and left out; raises DriveError
        when no row runs (in a scene without rows: that drive's error). After an automatic
        restart (`hold_reason`) nothing is enabled: the rows wait at zero for an operator's
        enable_rows; so does a stop asked for meanwhile."""
        if self.hold_reason:
            self.get_logger().warning(f'{self.hold_reason}: the rows stay at zero until an '
                                      'operator enables them (service '
                                      f'{self.resolve_service_name(interfaces.ENABLE_ROWS.name)})')
        if not isinstance(self.engine, CommandEngine):  # the command process
            self.engine.enable(hold_reason=self.hold_reason)
        elif self.hold_reason:
            self._in_process_held = True
        elif not self._stop_asked():
            self._enable_in_process()
        self._ready = True
        held, self._held_logs = self._held_logs, []
        for level, text in held:
            self._log(level, text)

    def _enable_in_process(self):
        engine = self.engine
        if not isinstance(engine, CommandEngine):
            raise TypeError('_enable_in_process: the command path runs in a command process')
        engine.enable()
        if engine.period != self.loop.control_period:
            # CSP in this process: one step (SYNC + targets) per SYNC period
            self.destroy_timer(self._control_timer)
            self._control_timer = self.create_timer(engine.period, self._on_control,
                                                    callback_group=self._group)

    def _on_enable_rows(self, _request, response):
        """An operator enables the rows held after an automatic restart."""
        if self._stop_asked():
            response.success, response.message = False, 'stopping: nothing is enabled any more'
        elif not isinstance(self.engine, CommandEngine):    # the command process
            reply = self.engine.operator_enable()
            response.success, response.message = reply.ok, reply.message
        elif not self._in_process_held:
            response.success, response.message = False, 'the rows are enabled already'
        else:
            try:
                self._enable_in_process()
            except DriveError as exc:
                response.success, response.message = False, f'not enabled: {exc}'
                return response
            self._in_process_held = False
            response.success = True
            response.message = f'enabled ({self.engine.mode_text()}): the rows follow the ' \
                               'ground speed'
            self.get_logger().warning(f'rows enabled by an operator: {response.message}')
        return response

    def shutdown_drive(self):
        """BLOCKING, idempotent: every row at once: 0x60FF = 0, disable, NMT pre-operational."""
        self._ready = True
        self.engine.shutdown()

    def destroy_node(self):
        self.shutdown_drive()
        return super().destroy_node()

    # ---------------------------------------------------------------- callbacks
    def _on_ground_speed(self, msg):
        if self._in_process_held:      # held: the rows start from where they are, once enabled
            return
        self.engine.sample(msg.twist.linear.x, msg.twist.angular.z, time.monotonic())
        if self.in_process:
            self._publish_commands()

    def _on_control(self):
        self.engine.step(time.monotonic())
        if not isinstance(self.engine, CommandEngine):      # the command process
            if self.engine.fb_count == self._last_fb:
                return                      # nothing new from the command process
            self._last_fb = self.engine.fb_count
            self._publish_commands()
        # one joint_states per feedback sample, each with its own stamp: after a stall of
        # this shell (its DDS, its GIL) the samples queued meanwhile go out in order
        for feedback in self.engine.take_feedback():
            self._joint_pub.publish(self._joint_states(feedback))

    def _joint_states(self, feedback):
        """One JointState for every row with feedback, stamped when the newest feedback was
        measured; the other rows' angles carried to that instant with their measured speed
        (their feedback is at most one feedback period older)."""
        newest = max(f.stamp for f in feedback)
        age = min(max(time.monotonic() - newest, 0.0), STAMP_AGE_MAX)
        msg = JointState(name=[f.joint for f in feedback],
                         position=[f.position + f.velocity * (newest - f.stamp)
                                   for f in feedback],
                         velocity=[f.velocity for f in feedback])
        # stamped when the drive measured it, not when we got round to publishing
        msg.header.stamp = (self.get_clock().now() - Duration(seconds=age)).to_msg()
        return msg

    def _on_design(self, msg):
        if msg.data == self._design_text:
            return                                  # the design in force, delivered again
        try:
            design = from_json(msg.data)
            changed = self.engine.set_design(design, msg.data, time.monotonic())
        except (ValueError, KeyError, TypeError) as exc:     # ValueError: ConfigError too
            self.get_logger().error(f'design ignored, keeping the last one: {exc}')
            return
        self._design_text = msg.data
        self._design = design
        if changed:
            what = (f'{design.mechanism}, d = {design.plant_spacing} m, '
                    f'{design.plants_per_revolution} plant(s) per revolution')
            graph.log_accepted_design(self, self.design_sources, what,
                                      "in force from each row's next planting instant")

    def _on_reset_fault(self, row, _request, response):
        reply = self.engine.reset_fault(row.name)
        response.success, response.message = reply.ok, reply.message
        return response

    def _on_section(self, row, request, response):
        reply = self.engine.section(row.name, bool(request.data), time.monotonic())
        response.success, response.message = reply.ok, reply.message
        if reply.ok and reply.changed:
            sections = self._initial_sections()
            sections.update(self.engine.sections())
            sections[row.name] = bool(request.data)
            self._publish_sections(sections)     # the instant of the switch, for the monitor
        return response

    def _publish_sections(self, sections):
        """Every row's section on the latched `sections` topic (rows disabled in the scene
        never plant: not named)."""
        names, positions = interfaces.section_fields(sections)
        msg = JointState(name=names, position=positions)
        msg.header.stamp = self.get_clock().now().to_msg()
        self._sections_pub.publish(msg)

    def _on_law_parameters(self, value):
        self.engine.configure(value)

    def _publish_commands(self):
        commands = self.engine.commands()
        if self.implicit:
            if commands:
                self._cmd_pub.publish(Float64(data=float(commands[0][1])))
            return
        if commands:
            msg = JointState(name=[joint for joint, _ in commands],
                             velocity=[float(command) for _, command in commands])
            msg.header.stamp = self.get_clock().now().to_msg()
            self._cmd_pub.publish(msg)

    # ---------------------------------------------------------------- diagnostics
    def _on_diagnostics(self):
        self._diag_pub.publish(diagnostics.array(self._reports(), self.get_name(),
                                                 self.get_clock().now().to_msg()))

    def diagnostics(self):
        """The DiagnosticStatus list the next /diagnostics message carries: a scene without
        rows keeps its three statuses (drive, ground speed, phase lock); with rows, one status
        per row; both add the bus (its load), the control loop, the design's source and (with
        a command process) the command process."""
        return list(diagnostics.array(self._reports(), self.get_name()).status)

    def _reports(self):
        shared = [self.design_sources.report()]
        if self.in_process and self._in_process_held:
            shared.append(diagnostics.Report(
                'enable', diagnostics.WARN, f'rows held at zero ({self.hold_reason}): an '
                'operator enables them (service '
                f'{self.resolve_service_name(interfaces.ENABLE_ROWS.name)})'))
        return self.engine.reports(time.monotonic(), shared)


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
                        arguments=sys.argv if args is None else args, stop=stop)
        node.raise_shell_priority()
        node.enable_drive()
        library_log.node = node
        if stop.received is None:            # not stopped while the drives were enabled
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            stop_signals.spin(executor, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except SceneError as exc:                # a parameter file it refuses: bad input
        error, code = f'sync_node: error: {str(exc).splitlines()[0]}', 2
    except (DriveError, ConfigError, ParameterException) as exc:
        if stop.received is None:        # (a start cut short by a stop is no error)
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
