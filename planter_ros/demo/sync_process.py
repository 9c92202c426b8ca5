"""The demo's command path in processes of its own: the sync node (a shell), its command
process, and the simulated drives.

The drives' RPDO deadline (0.2 s) is only as safe as the thread that sends the commands. Here
the sync node spins alone in a child process (a single-threaded executor, as `sync_node` runs
on the machine) and, as on the machine, hands the CAN bus to its command process (no DDS, no
rclpy: planter_ros.command), so neither the demo's other work nor a DDS graph event can hold up
a command frame. The simulated drives run in a process of their own too
(simdrive.process, over a CAN socket pair, doc/command.md), so they see on their own clock
every gap a real drive would see (`drive_gaps` in the report). The child talks to the rest of
the demo over DDS in the demo's private domain (ground speed and the design in; joint_states,
speed commands and /diagnostics out) and to the demo itself over a pipe: its start, a status
snapshot four times a second for the progress lines, and at the end a report (sample counts,
faults, watchdog trips, the control loop's period statistics, design changes). With
`command_process=False` the drives and the engine run in the child on a virtual bus instead.

A stop is a stop however it comes. The demo decides when the graph stops (the drives first,
then its own nodes, so the bag holds the ramp to zero): a SIGINT or SIGTERM that reaches the
child (the terminal's Ctrl-C and a service manager reach the whole process group; someone may
stop the child alone), or the command process's own stop (a signal that reached it: it ramps
its rows to zero and disables its drives by itself), is passed on to the demo (`stop_requested`)
and from then on nothing restarts the command process or enables a drive. It stops on the
demo's request or when the pipe breaks (the demo closed it or was forced out): either way its
drives are shut down (0x60FF = 0, disable); a second signal ends it at once (its command
process, orphaned, still ramps down and disables). A demo killed outright (SIGKILL) leaves the
child PARENT_GONE_GRACE s for that, then the kernel ends it (planter_ros.host.processes), stuck or
not; if the child itself is killed, its command process ramps to zero, disables the drives and
exits, and the drives' process ends with its parent.

What the child says is typed (`SyncBuilt`, `SyncReady`, `SyncReport` with the command path's
`command.reports.CommandReport` and the drives' `DrivesReport`): a report without the command
path's figures says why (`command_missing`), never a KeyError at the end of a run."""

from dataclasses import asdict, dataclass, field
import gc
import multiprocessing
import time
from typing import Any

from planter_ros.command.reports import CommandReport, ReportError, Snapshot, from_data
from planter_ros.drive.state_names import (FAULT_REACTION_ACTIVE, OPERATION_ENABLED,
                                           QUICK_STOP_ACTIVE)
from planter_ros.config import ConfigError
from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.drive.errors import DriveError
from planter_ros.errors import PlanterError
from planter_ros.host import stop_signals
from planter_ros.host.dds_domain import PRIVATE_GRAPH_ROS_ARGS
from planter_ros.host.processes import die_with_parent
from planter_ros.simdrive.process import SimProcess, drives_report

__all__ = ['DesignReport', 'DriveEnd', 'DrivesReport', 'STANDSTILL', 'SyncBuilt', 'SyncProcess',
           'SyncProcessError', 'SyncProcessSettings', 'SyncReady', 'SyncReport', 'child_main',
           'final_report', 'snapshot']

STATUS_PERIOD = 0.25       # s between status snapshots sent to the demo
DESIGN_WAIT_PERIOD = 0.02  # s between them until a design is in force
PARENT_GONE_GRACE = 4      # s the child may take to shut its drives down once the demo is gone
STANDSTILL = 1.0           # rad/s of a motor below which it stands still (a coasting remainder)
# the CiA 402 states with the drive function (torque) on
POWERED = (OPERATION_ENABLED, QUICK_STOP_ACTIVE, FAULT_REACTION_ACTIVE)


class SyncProcessError(PlanterError, RuntimeError):
    """The sync process did not start (one line: why)."""


@dataclass(frozen=True)
class SyncBuilt:
    """The sync node is built: the CAN bus load it will make."""

    bus_load: float              # fraction of the bit rate
    bitrate: int                 # bit/s


@dataclass(frozen=True)
class SyncReady:
    """The drives are enabled (or, held, wait for an operator)."""

    running: int                 # rows whose drives run
    mode: str                    # the CiA 402 mode, in words
    command_process: bool        # the drives behind a command process of their own


@dataclass(frozen=True)
class DriveEnd:
    """A simulated drive as the run left it."""

    state: str                   # CiA 402 state name
    motor_velocity: float        # rad/s
    nmt: str                     # NMT state

    @property
    def disabled(self) -> bool:
        """The drive function is off (no torque): not enabled, not stopping under power."""
        return self.state not in POWERED

    @property
    def at_standstill(self) -> bool:
        return abs(self.motor_velocity) < STANDSTILL

    def text(self) -> str:
        speed = f'{self.motor_velocity:.3f}'.replace('-0.000', '0.000')
        return f'{self.state.lower()} at {speed} rad/s (motor), NMT {self.nmt.lower()}'


@dataclass
class DrivesReport:
    """What the simulated drives counted, on their own clock (simdrive.process's report)."""

    watchdog_trips: list = field(default_factory=list)     # [node id, reason, EMCY code]
    bottom_times: dict = field(default_factory=dict)       # node id -> [monotonic s]
    rpdo_gaps: dict | None = None     # node id -> gaps between command frames (own process)
    sync: dict = field(default_factory=dict)
    heartbeat_gaps: dict = field(default_factory=dict)
    end: dict[str, DriveEnd] = field(default_factory=dict)  # node id -> as the run left it

    @classmethod
    def from_data(cls, data: dict) -> 'DrivesReport':
        report = from_data(cls, data)
        report.end = {node: from_data(DriveEnd, end) for node, end in report.end.items()}
        return report


@dataclass(frozen=True)
class DesignReport:
    """Who set the design the sync node ran (scene.design_sources)."""

    first: str = ''
    changes: int = 0
    foreign_changes: int = 0
    last_change: str = ''


@dataclass
class SyncReport:
    """The sync process's final report: the command path's figures (None when they never came:
    `command_missing` says why), the drives', who set the design, and how the command process
    ended (`command_exit`: its reason for a deliberate exit, '' otherwise)."""

    command: CommandReport | None
    drives: DrivesReport
    design: DesignReport
    command_missing: str = ''
    command_exit: str = ''

    def flat(self) -> dict[str, Any]:
        """The report as one plain mapping (the command path's figures, the drives' under
        drive_* keys), for tools that keep it as JSON (the bench)."""
        out = asdict(self.command) if self.command is not None else {}
        out['watchdog_trips'] = self.drives.watchdog_trips
        out['bottom_times'] = self.drives.bottom_times
        if self.drives.rpdo_gaps is not None:
            out['drive_gaps'] = self.drives.rpdo_gaps
            out['drive_sync'] = self.drives.sync
            out['drive_heartbeat_gaps'] = self.drives.heartbeat_gaps
        out['design'] = asdict(self.design)
        return out


@dataclass(frozen=True)
class SyncProcessSettings:
    domain: int                      # the demo's private DDS domain
    channel: str                     # python-can virtual channel of the drives' bus
    node_ids: tuple                  # the simulated drives' CANopen node ids
    namespace: str
    parameters: tuple = ()           # (name, value) sync node parameter overrides
    log_level: str = 'info'
    drive_kwargs: dict = field(default_factory=dict)
    # True: the drives in a process of their own and the sync node's command process between
    # them and the node (as on the machine); False: drives and engine in this child (virtual bus)
    command_process: bool = True


class SyncProcess:
    """The parent's handle of the child process (start, status, stop)."""

    def __init__(self, settings):
        context = multiprocessing.get_context('spawn')   # no fork of a process running DDS
        self._conn, child = context.Pipe()
        self.process = context.Process(target=child_main, args=(child, settings),
                                       name='planter-demo-sync')
        stop_signals.start_held(self.process)    # its own handler first, then a stop signal
        child.close()
        self.info = {}               # what the child said at start: SyncBuilt, SyncReady
        self.status = Snapshot()     # the latest snapshot
        self.report: SyncReport | None = None      # the final report
        self.error = None
        self.stop_requested = ''     # a stop that reached the child or its command process
        self._closed = False         # the child's end of the pipe is closed (it ended)

    def _handle(self, kind, payload):
        if kind == 'status':
            self.status = payload
        elif kind == 'final':
            self.report = payload
        elif kind == 'error':
            self.error = payload
        elif kind == 'stop_requested':
            self.stop_requested = self.stop_requested or payload
        else:
            self.info[kind] = payload

    def poll_stop(self):
        """A stop that reached the child or its command process ('' = none), after taking
        what the child has sent."""
        self.poll(0.0)
        return self.stop_requested

    def poll(self, timeout=0.0):
        """Take every message the child has sent (waiting up to `timeout` for the first)."""
        try:
            while self._conn.poll(timeout):
                self._handle(*self._conn.recv())
                timeout = 0.0
        except (EOFError, OSError):
            self._closed = True

    def _gone(self):
        """Nothing more can come from the child: `poll` has read up to its closed end, or it
        has ended with nothing left unread. (A closed pipe polls as readable for ever, so
        `_conn.poll()` alone keeps saying "more to read": a stop spun until its timeout.)"""
        return self._closed or (not self.process.is_alive() and not self._conn.poll())

    def wait_for(self, kind, timeout, stopped=lambda: False):
        """Wait until the child has said `kind` ('built', 'ready'); raises SyncProcessError
        with the child's own line if it failed. Returns its payload, or None when `stopped()`
        turned true first."""
        deadline = time.monotonic() + timeout
        while kind not in self.info:
            if self.error is not None:
                raise SyncProcessError(self.error)
            if stopped():
                return None
            if self._gone():
                raise SyncProcessError(f'the sync process ended (exit code '
                                       f'{self.process.exitcode}) before it was {kind}')
            if time.monotonic() > deadline:
                raise SyncProcessError(f'the sync process was not {kind} within {timeout:g} s')
            self.poll(0.05)
        return self.info[kind]

    def stop(self, timeout=30.0) -> SyncReport | None:
        """Ask the child to shut its drives down and report; returns the report (None if it
        never came)."""
        try:
            self._conn.send('stop')
        except (BrokenPipeError, OSError):
            pass
        deadline = time.monotonic() + timeout
        while self.report is None and time.monotonic() < deadline:
            if self._gone():
                break
            self.poll(0.1)
        self.process.join(max(0.0, deadline - time.monotonic()))
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self._conn.close()
        return self.report


def child_main(conn, settings):
    """The child process: the sync node on the simulated bus until asked to stop."""
    # a demo killed outright (SIGKILL): the broken pipe below is the clean way out (drives shut
    # down), but it is only read between status snapshots; the kernel's signal ends this
    # process PARENT_GONE_GRACE s after the demo however stuck it is
    parent = multiprocessing.parent_process()
    if parent is None or parent.pid is None:
        raise RuntimeError('child_main is the sync process a SyncProcess starts: no parent')
    die_with_parent(parent.pid, grace=PARENT_GONE_GRACE)
    # a stop signal here (or one its command process received) is passed on to the demo
    stop = stop_signals.install('planter demo: sync process')
    # lazy: this spawned child imports rclpy, the sync node and python-can (0.4-0.6 s) only
    # once die_with_parent and its stop handler are in place: until then a stop signal is held
    # for it (stop_signals.held_for_child) and a demo killed meanwhile would not take it down
    import rclpy  # lazy: (above)
    from rclpy.context import Context  # lazy: (above)
    from rclpy.exceptions import ParameterException  # lazy: (above)
    from rclpy.parameter import Parameter  # lazy: (above)
    from rclpy.signals import SignalHandlerOptions  # lazy: (above)

    from planter_ros.simdrive.bus import SimulatedBus  # lazy: python-can (above)
    from planter_ros.drive.socket_bus import INTERFACE, socket_pair  # lazy: python-can (above)
    from planter_ros.nodes.run import graph_executor  # lazy: (above)
    from planter_ros.nodes.sync_node import LibraryLog, SyncNode, start_error  # lazy: (above)

    def send(*message):
        try:
            conn.send(message)
            return True
        except (BrokenPipeError, OSError):
            return False

    parameters = list(settings.parameters)
    sims: SimProcess | SimulatedBus
    if settings.command_process:
        # drives | CAN socket pair | command process | channel | this shell (the sync node)
        ours, theirs = socket_pair()
        # drives that offer CSP (and profile velocity): the command process runs them in CSP
        # unless the scene says operation_mode: velocity
        kwargs = {'supported_modes': [3, 8], **settings.drive_kwargs}
        # the drives stand for hardware: just below the command process's real-time priority
        priority = dict(parameters).get('realtime_priority', SyncLoopConfig().realtime_priority)
        with stop_signals.held_for_child():      # the drives ignore stop signals
            sims = SimProcess(ours.fileno(), list(settings.node_ids),
                              priority=max(int(priority) - 1, 0), **kwargs)
        ours.close()
        parameters = [(k, v) for k, v in parameters if k not in ('can_interface', 'can_channel')]
        parameters += [('can_interface', INTERFACE), ('can_channel', str(theirs.fileno()))]
    else:
        sims = SimulatedBus(settings.channel, list(settings.node_ids), **settings.drive_kwargs)
        sims.start()
    context = Context()
    rclpy.init(args=['--ros-args', '--log-level', settings.log_level, *PRIVATE_GRAPH_ROS_ARGS],
               context=context, domain_id=settings.domain,
               signal_handler_options=SignalHandlerOptions.NO)
    executor = graph_executor(context)
    spinner = stop_signals.SpinThread(executor, 'sync-executor')
    library_log = LibraryLog()
    sync = None
    passed_on = False

    def pass_on_stop():
        nonlocal passed_on
        if stop.received is not None and not passed_on:
            passed_on = send('stop_requested', stop.description if stop.source else
                             f'{stop.name_received} to the sync process')

    try:
        sync = SyncNode(context=context, namespace=settings.namespace, parameter_overrides=[
            Parameter(name, value=value) for name, value in parameters], stop=stop)
        send('built', SyncBuilt(sync.bus_load.load, sync.bus_load.bitrate))
        sync.raise_shell_priority()
        if stop.received is None:
            sync.enable_drive()                    # blocking; the loop spins right after it
        # what start-up built (canopen's object dictionaries, rclpy, numpy, scipy) lives as
        # long as the process: out of the collector's reach, a full collection scans only
        # what the run allocates (the start-up objects alone take ~45 ms to scan, unloaded)
        gc.freeze()
        executor.add_node(sync)
        spinner.start()
        library_log.node = sync
        if stop.received is None:
            send('ready', SyncReady(sync.engine.running, sync.engine.mode_text(),
                                    settings.command_process))
        while True:
            pass_on_stop()
            status = snapshot(sync)
            if not send('status', status):
                break
            # the demo starts its field run once the design is in force: until then, often
            wait = STATUS_PERIOD if status.spacing is not None else DESIGN_WAIT_PERIOD
            if conn.poll(wait) and conn.recv() == 'stop':
                break
    except (EOFError, OSError):
        pass                                       # the demo is gone: stop the drives
    except (DriveError, ConfigError, ParameterException) as exc:
        if stop.received is None:
            send('error', start_error(exc, sync.drive_config if sync is not None else None))
        else:                                      # the start was cut short by the stop
            pass_on_stop()
            _wait_for_stop(conn)
    finally:
        spinner.stop()                             # spinning ended, then the executor shut down
        if sync is not None:
            sync.destroy_node()                    # every row: 0x60FF = 0, disable
        context.try_shutdown()
        if isinstance(sims, SimProcess):      # settings.command_process
            drive_report = sims.stop()
        else:                       # the drives in this process, measured the same way
            sims.stop()
            drive_report = drives_report(sims)
        library_log.close()
    # the drives' own account of how they ended, also when the start was cut short (by a stop
    # or a start error) before the sync node stood: without it a stop at start-up left the
    # demo nothing to show that every drive ended disabled
    send('final', final_report(sync, drive_report) if sync is not None else
         start_cut_report(drive_report))
    conn.close()


def _wait_for_stop(conn, timeout=30.0):
    """Until the demo says stop (or is gone): it decides when the graph stops."""
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            if conn.poll(STATUS_PERIOD) and conn.recv() == 'stop':
                return
    except (EOFError, OSError):
        return


def snapshot(sync) -> Snapshot:
    """What the progress lines show: each running row's command, measured speed and state."""
    return sync.engine.snapshot()


def start_cut_report(drives: dict) -> SyncReport:
    """The report of a sync process whose start was cut short before its sync node stood: no
    command path, only what the simulated drives counted."""
    drives_report, unreadable = _drives_report(drives)
    missing = 'the start was cut short before the sync node stood'
    return SyncReport(None, drives_report, DesignReport(),
                      f'{missing}; {unreadable}' if unreadable else missing)


def _drives_report(drives: dict) -> tuple[DrivesReport, str]:
    """What the simulated drives counted, read from their data, and '' (or why it could not
    be read: an empty report then)."""
    try:
        return DrivesReport.from_data(drives or {}), ''
    except ReportError as exc:
        return DrivesReport(), f'the drives\' report: {exc}'


def final_report(sync, drives: dict) -> SyncReport:
    """The run's figures from the command path; `drives`: what the simulated drives counted
    (watchdog trips, their state at the end; in a process of their own also the gaps between
    command frames on their own clock)."""
    command = sync.engine.final_report()
    missing = ''
    unreadable = getattr(sync.engine, 'final_error', '')
    if unreadable:
        missing = f'the command path\'s report is unreadable: {unreadable}'
    elif command is None:
        exit_ = getattr(sync.engine, 'exit', None)
        missing = ('the command process sent no report (it never enabled a drive)'
                   if exit_ is not None and not exit_.enabled else
                   'the command process sent no report')
    drives_report, unreadable_drives = _drives_report(drives)
    missing = missing or unreadable_drives
    sources = sync.design_sources
    design = DesignReport(sources.first.text if sources.first else '', sources.changes,
                          sources.foreign_changes,
                          sources.last_change.text if sources.last_change else '')
    exit_ = getattr(sync.engine, 'exit', None)
    return SyncReport(command, drives_report, design, missing,
                      exit_.reason if exit_ is not None else '')
