"""`planter demo`: the whole machine in one process tree, on a simulated CAN bus.

design_node + sync_node + monitor_node + a simulated ground-speed sensor and GNSS receiver
(demo.field), and one simulated CiA 402 drive per row (node ids from the scene; one drive for a
scene without rows) on a python-can virtual bus with a channel of its own. Each node gets the
scene's parameters for it (scene.Scene.node_overrides), the demo's own choices on top. At the
end the demo prints per row the plants placed, the spacing error, commanded against measured
speed and in the turns the compensation's effect (demo.report). The monitor records the run
(bags/planter_<date-time> unless a bag is given); the demo ends by replaying that bag offline
and printing the replay summary, then one verdict line: PASS, or FAIL and every reason
(demo.verdict); the exit code is 0 on PASS, 1 on FAIL. A stop is a stop however it comes:
Ctrl-C or SIGTERM to the demo alone or to its whole process group (a terminal, systemd,
`docker stop`), to its sync process or to its command process, at start-up, in the run or while
stopping, stops it cleanly (the rows ramped to zero, the drives disabled, the bus closed, the bag
finalised) with the summaries and the verdict on what ran; a second signal forces the exit.

The graph runs in a DDS domain of its own (planter_ros.host.dds_domain), so no other graph on the
host reaches it, and the sync node with the simulated drives runs in a process of its own
(demo.sync_process), so nothing else the demo does can hold up the drives' commands.
"""

from dataclasses import dataclass
import os
import sys
import time
from typing import Any, TextIO

import rclpy
from rclpy.context import Context
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions

from planter_ros import interfaces
from planter_ros.host import stop_signals
from planter_ros.host.dds_domain import (
    PRIVATE_GRAPH_ROS_ARGS, NoFreeDomainError, claim_private_domain, keep_discovery_on_host)
from planter_ros.command.reports import Snapshot
from planter_ros.design import Design
from planter_ros.geo import AntennaSettings
from planter_ros.nodes.design_node import DesignNode
from planter_ros.nodes.monitor_node import MonitorNode
from planter_ros.nodes.run import graph_executor
from planter_ros.prediction.acceptance import Acceptance
from planter_ros.recording.errors import RecordingError
from planter_ros.recording.replay import ReplayResult, replay
from planter_ros.recording.replay_text import format_summary
from planter_ros.rows import Row
from planter_ros.scene import Scene, SceneError, default_scene_path, open_scene
from planter_ros.scene.machine_file import Machine, deployment_parameters, open_machine
from planter_ros.scene.schedule import spacing_schedule
from planter_ros.sim.closed_loop import MotionSensor
from planter_ros.sim.field import FieldProfile
from planter_ros.sim.gnss import SimulatedGnss
from planter_ros.sim.ros_field import GnssSource, GroundSpeedSource, Observer, SeedlingSensor

from .field import field_profile, glitches
from .commissioned import (
    first_plant_errors, first_plant_lines, first_plant_reasons, machine_rows, simulated_drives)
from .options import DemoOptions, check_bag_path
from .report import command_path_lines, progress_line, row_summary
from .sync_process import SyncProcess, SyncProcessError, SyncProcessSettings
from .verdict import RowResult, RunOutcome, Verdict, judge

__all__ = ['Demo', 'DemoResult', 'prepare']

PROGRESS_PERIOD = 2.0     # s between progress lines


def prepare(options: DemoOptions, **kwargs: Any) -> 'Demo':
    """The Demo `options` ask for, every input and output checked before anything starts
    (SceneError, ConfigError, OutputError: the command line's exit 2); kwargs go to Demo."""

    scene = open_scene(options.scene or default_scene_path())
    check_bag_path(options.bag)
    design = scene.design()               # a bad scene fails here, before anything starts
    spacing_schedule(scene.parameters('design_node'), scene.path)
    node_id = scene.parameters('sync_node').get('drive_node_id', 1)
    rows = scene.rows(default_node_id=node_id)
    antenna = scene.antenna()
    machine = None
    if options.machine:                   # its rows and drives over the scene (demo.commissioned)

        machine = open_machine(options.machine)
        deployment_parameters(options.machine, scene.path)
        rows, antenna = machine_rows(scene, machine), AntennaSettings()
    if not any(row.enabled for row in rows):
        raise SceneError(f'scene {scene.path}: rows = every row has enabled false: allowed at '
                         'least one enabled row')
    for warning in scene.warnings:        # unusual but possible values (planter_ros.plausibility)
        print(f'planter: warning: {warning}', file=sys.stderr)
    keep_discovery_on_host()
    return Demo(DemoInputs(scene, design, tuple(rows), antenna, machine), options, **kwargs)


@dataclass(frozen=True)
class DemoInputs:
    """What one demo runs, read and checked by `prepare`: the scene, its design, every row
    of the machine (the scene's, or --machine's), the GNSS antenna on the machine and the
    --machine file (None without one)."""

    scene: Scene
    design: Design
    rows: tuple[Row, ...]
    antenna: AntennaSettings
    machine: Machine | None = None


class Demo:
    """One demo run of `inputs` (DemoInputs). `out`: where the report goes (stdout);
    `install_signals`: take over SIGINT/SIGTERM (the command line; a caller that runs demos
    itself, the bench, keeps its own); `log_level`: the nodes' ROS log level; `stop`: a
    stop_signals handler the caller installed."""

    def __init__(self, inputs: DemoInputs, options: DemoOptions, out: TextIO | None = None,
                 install_signals: bool = True, log_level: str = 'info',
                 stop: stop_signals.StopSignals | None = None) -> None:
        self.scene, self.design, self.options = inputs.scene, inputs.design, options
        self.rows = list(inputs.rows)
        self.machine = inputs.machine     # scene.machine_file.Machine of --machine, or None
        self._replayed: ReplayResult | None = None     # the replay of the bag, once done
        self.antenna = inputs.antenna
        self.planting = [row for row in self.rows if row.enabled]
        self.out = out or sys.stdout
        self.install_signals = install_signals
        self.stop = stop                  # a stop_signals handler installed by the caller
        self.log_level = log_level
        self.result: DemoResult | None = None
        self.schedule = spacing_schedule(self.scene.parameters('design_node'), self.scene.path)

    def _print(self, text: str = '') -> None:
        print(text, file=self.out, flush=True)

    # ---------------------------------------------------------------- the run
    def run(self) -> int:
        """The whole run; returns the exit code (0 PASS, 1 FAIL)."""

        # the command line installs its handler first thing (a stop while the demo reads its
        # inputs is a stop too)
        stop = self.stop or ((stop_signals.installed() or stop_signals.install('planter demo'))
                             if self.install_signals else stop_signals.StopSignals('planter demo'))
        try:
            return self._run(stop)
        finally:
            if self.install_signals:
                # the verdict is out: a stop signal while the interpreter winds down (its
                # threads, DDS) changes nothing, not even the exit code
                stop_signals.ignore()

    def _run(self, stop) -> int:
        if stop.received is not None:     # stopped while it was reading its inputs
            return self.stopped_before_start(stop)
        try:
            # a domain of its own: no other graph on the host (another demo, a stray node in
            # the default domain 0) can reach this one, nor this one them
            domain = claim_private_domain()
        except NoFreeDomainError as exc:
            print(f'planter demo: error: {exc}', file=sys.stderr)
            return 1
        run = _Run(self, domain, stop)
        try:
            run.start_and_drive()
        finally:
            run.stop()
        return self.finish(run)

    def stopped_before_start(self, stop) -> int:
        """A stop that came before the graph started: nothing ran, nothing to shut down."""
        self._print(f'interrupted by {stop.description} before the graph started: nothing ran')
        self._print('\nsummary\n  no field run, no drive enabled, no bag')
        verdict = Verdict(['stopped before the graph started: no bag'], stop.description)
        self.result = DemoResult(verdict, None, [], -1)
        self._print('')
        self._print(verdict.line())
        return verdict.exit_code

    def finish(self, run: '_Run') -> int:
        """Summaries, the replay of the bag, the verdict line; the exit code."""
        report = run.sync.report if run.sync is not None else None
        rows: list[RowResult] = []
        if run.observer is not None and run.observer.start is not None and report is not None:
            summary, rows = row_summary(self.design, self.rows, run.profile, run.observer,
                                        report)
            self._print(summary)
        else:                             # stopped (or failed) before the field run
            self._print('\n'.join(['', 'summary', '  no field run (stopped or failed before '
                                    'it started): no plant placed']
                                   + (command_path_lines(report) if report is not None else
                                      ['  the sync process gave no report'])))
        bag_error = run.bag_error()
        acceptance = None
        recorder = run.monitor.recorder if run.monitor is not None else None
        if not bag_error and recorder is not None:      # bag_error() says why there is none
            replayed, bag_error, acceptance = self.replay_summary(recorder.path)
            self._print(replayed)
        monitor_changes = ''
        sources = run.monitor.design_sources if run.monitor is not None else None
        if (sources is not None and sources.last_change is not None
                and sources.changes > run.scheduled_changes):
            monitor_changes = (f'{sources.changes}x, the latest from '
                               f'{sources.last_change.text}')
        first_plants = {}
        if self.machine is not None and self._replayed is not None and report is not None:
            first_plants = first_plant_errors(self.rows, self._replayed,
                                              report.drives.bottom_times, run.profile,
                                              *run.field_start)
            self._print('\n'.join(first_plant_lines(first_plants)))
        field_run = run.observer is not None and run.observer.start is not None
        outcome = RunOutcome(run.start_error, bag_error, monitor_changes, run.scheduled_changes,
                             field_run)
        verdict = judge(rows, report, outcome, acceptance if field_run else None)
        if first_plants:
            verdict.reasons += first_plant_reasons(first_plants)
        verdict.stopped_by, verdict.elapsed = run.stopped_by, run.elapsed
        self.result = DemoResult(verdict, report, rows, run.domain, first_plants)
        self._print('')
        self._print(verdict.line())
        return verdict.exit_code

    def replay_summary(self, bag) -> tuple[str, str, Acceptance | None]:
        """Re-read the finished bag offline, as `planter replay` would, and summarise it:
        (text, why it failed or '', the run judged by the crop's acceptance limits the bag
        recorded: replay's `acceptance`, None when the replay failed)."""
        try:
            result = replay(bag)
        except RecordingError as exc:
            return (f'\nreplay of {bag} failed: {exc}', f'replay of {bag} failed: {exc}',
                    None)
        self._replayed = result
        lines = [f'\nrecorded {bag}; replay (`planter replay {bag}`), plants placed as the '
                 "machine's monitor places them, at the distance integrated from the recorded "
                 'ground speed (its noise included):']
        lines += [f'  {line}' for line in format_summary(result).splitlines()]
        lines += [f'  warning: {w}' for w in result.warnings]
        return '\n'.join(lines), '', result.acceptance

    def progress(self, t: float, profile, status: Snapshot, observer) -> str:
        """The progress line at `t` s of the field run."""
        plants = sum(len(observer.plant_positions(profile, self.design,
                                                  row.joint(self.design.mechanism),
                                                  row.lateral_offset))
                     for row in self.planting)
        return progress_line(t, profile, status, plants, self.planting)


class _Run:
    """The graph of one demo run and its life cycle: the sync process (the command path and
    the simulated drives) and, in this process, the design node, the monitor, the demo's
    observer and the field sensors, all in the demo's private DDS domain."""

    START_TIMEOUT = 120.0     # s for the sync process to import, build and enable (loaded host)
    MATCH_TIMEOUT = 20.0      # s for the graph to discover itself before the field run

    def __init__(self, demo: Demo, domain: int, stop: stop_signals.StopSignals) -> None:
        self.demo, self.domain, self.stop_signal = demo, domain, stop
        # made by start_and_drive, in this order (None: not made: stopped or failed before)
        self.sync: SyncProcess | None = None
        self.context: Context | None = None
        self.spinner: stop_signals.SpinThread | None = None     # the executor, spun
        self.design_node: DesignNode | None = None
        self.observer: Observer | None = None
        self.monitor: MonitorNode | None = None
        self.source: GroundSpeedSource | None = None      # made by _start_field
        self.nodes: list[Node] = []
        self.profile: FieldProfile | None = None
        self.start_error = ''
        self.elapsed = 0.0
        self._next_switch = 0           # the spacing schedule's next switch
        self.field_start = (0.0, 0.0)   # (ROS time s, monotonic s) of the field run's t = 0
        self.scheduled_changes = 0      # design changes the schedule made (not foreign)
        self.completed = False          # the field run ran its full length

    @property
    def stopped_by(self):
        """What stopped the run early: a signal to the demo (its process group), or one that
        reached its sync process or command process ('' = none, also for a signal that came
        after the field run had run its full length)."""
        if self.completed:
            return ''
        return self.stop_signal.description or (self.sync.stop_requested
                                                if self.sync is not None else '')

    def _stopped(self):
        return (self.stop_signal.received is not None
                or (self.sync is not None and bool(self.sync.poll_stop())))

    def start_and_drive(self):
        demo, options, design = self.demo, self.demo.options, self.demo.design
        channel = f'planter_demo_{os.getpid()}_{time.monotonic_ns() % 1_000_000}'
        self.profile = profile = field_profile(options.duration, design.nominal_ground_speed,
                                               design.top_ground_speed)
        ns = interfaces.NAMESPACE
        # the command path first: it takes longest to start (its own interpreter)
        machine: tuple[tuple[str, str], ...] = ()
        if demo.machine is not None:
            machine = (('machine_file', str(demo.machine.path)),)
        self.sync = sync = SyncProcess(SyncProcessSettings(
            self.domain, channel, tuple(row.drive_node_id for row in demo.planting), ns,
            tuple(demo.scene.node_overrides('sync_node')) + machine + (
                ('can_interface', 'virtual'), ('can_channel', channel),
                ('phase_lock', options.phase_lock),
                ('turn_compensation', options.turn_compensation)),
            demo.log_level, simulated_drives(demo.machine, options.seed) if machine else {}))
        self.context = context = Context()
        rclpy.init(args=['--ros-args', '--log-level', demo.log_level, *PRIVATE_GRAPH_ROS_ARGS],
                   context=context, domain_id=self.domain,
                   signal_handler_options=SignalHandlerOptions.NO)
        executor = graph_executor(context)
        self.spinner = stop_signals.SpinThread(executor, 'demo-executor')
        self.design_node = design_node = DesignNode(
            context=context, namespace=ns, parameter_overrides=[
                _param(k, v) for k, v in demo.scene.node_overrides('design_node')])
        self.nodes.append(design_node)
        self.observer = observer = Observer(context=context, namespace=ns)
        self.nodes.append(observer)
        monitor = dict(demo.scene.node_overrides('monitor_node'))
        if demo.machine is not None:
            monitor.update(demo.machine.node_parameters()['monitor_node'])
        if options.bag:
            monitor['bag_path'] = options.bag
        self.monitor = recording = MonitorNode(context=context, namespace=ns, parameter_overrides=[
            _param(k, v) for k, v in monitor.items()])
        self.nodes.append(self.monitor)          # per-plant predictions and the bag
        for node in self.nodes:
            executor.add_node(node)
        self.spinner.start()
        turns = ', '.join(f'{"left" if c.radius > 0 else "right"} turn R = '
                          f'{abs(c.radius):g} m at {c.start:.1f}-{c.end:.1f} s'
                          for c in profile.curves)
        demo._print(f'planter demo: {design.crop} {design.mechanism}, d = '
                    f'{design.plant_spacing:.3f} m, cruise {profile.cruise:.2f} -> '
                    f'{profile.cruise * profile.change:.2f} m/s, {turns}, '
                    f'{options.duration:g} s, '
                    f"{'phase-locked' if options.phase_lock else 'speed-only'}, turn "
                    f"compensation {'on' if options.turn_compensation else 'off'}, "
                    f'DDS domain {self.domain} (private), bag '
                    f"{getattr(recording.recorder, 'path', None) or 'none (not recording)'}")
        try:
            built = sync.wait_for('built', self.START_TIMEOUT, self._stopped)
            if built is None:
                return self._interrupted()
            if demo.rows[0].name:
                demo._print('rows: ' + ', '.join(
                    f'{row.name} (y = {row.lateral_offset:+.2f} m, node {row.drive_node_id}'
                    f'{"" if row.enabled else ", disabled"})' for row in demo.rows)
                    + f"; CAN bus load {100 * built.bus_load:.1f} % of "
                    f"{built.bitrate} bit/s")
            ready = sync.wait_for('ready', self.START_TIMEOUT, self._stopped)
            if ready is None:
                return self._interrupted()
        except SyncProcessError as exc:
            self.start_error = str(exc)
            demo._print(f'drives not started: {exc}')
            return None
        demo._print(('drive enabled' if len(demo.planting) == 1 else
                     f"{ready.running} drives enabled")
                    + f" (CiA 402 {ready.mode or 'mode unknown'}; "
                    + ('CAN bus and drives in a command process without DDS, the simulated '
                       "drives in a process of their own" if ready.command_process else
                       f'CAN virtual:{channel}, drives in the sync process')
                    + '); field run starts')
        self.source = source = self._start_field(profile, sync, observer, context, executor)
        return self._drive(profile, sync, source, observer, design_node)

    def _start_field(self, profile: FieldProfile, sync: SyncProcess, observer: Observer,
                     context: Context, executor: Executor) -> GroundSpeedSource:
        """The simulated sensors, once the graph has found itself (the sync node and the
        monitor subscribe the ground speed, the sync node has the design): t = 0 then."""

        options, ns = self.demo.options, interfaces.NAMESPACE
        source = GroundSpeedSource(profile, MotionSensor(seed=options.seed),
                                   glitches=glitches(options.duration),
                                   context=context, namespace=ns)
        deadline = time.monotonic() + self.MATCH_TIMEOUT
        while time.monotonic() < deadline and not self._stopped():
            sync.poll(0.05)
            if (source._pub.get_subscription_count() >= 2
                    and sync.status.spacing is not None):
                break
        source.restart()
        self.field_start = (source.start.nanoseconds * 1e-9, time.monotonic())
        # the machine's GNSS receiver, on the same path and clock
        origin = {name: value for name, value in (
            ('origin_latitude', options.origin_latitude),
            ('origin_longitude', options.origin_longitude)) if value is not None}
        receiver = SimulatedGnss(**origin)
        antenna = self.demo.antenna.antenna_position
        gnss = GnssSource(profile, receiver, source.start, antenna=antenna,
                          seed=options.seed, context=context, namespace=ns)
        self.demo._print(
            f'GNSS: simulated receiver at {receiver.rate:g} Hz from '
            f'{receiver.origin_latitude:.7f}, {receiver.origin_longitude:.7f} (WGS 84), noise '
            f'{receiver.noise * 1e3:.0f} mm per axis; antenna x = {antenna[0]:+.2f} m, '
            f'y = {antenna[1]:+.2f} m on the machine')
        sensed = [row for row in self.demo.planting if row.seedling_sensor]
        nodes: list[Node] = [source, gnss]
        if sensed:
            nodes.append(SeedlingSensor(self.demo.design, sensed, options.empty_rate,
                                        options.double_rate, seed=options.seed,
                                        context=context, namespace=ns))
        self.demo._print(
            f'seedling sensor: a cup sensor on {len(sensed)} of {len(self.demo.planting)} '
            f'row(s) on a simulated tray, '
            f'{options.empty_rate:.0%} empty cells, {options.double_rate:.0%} doubles (topic '
            'seedlings)' if sensed else 'seedling sensor: none (the scene declares no row '
            'with one): every planting instant unknown')
        observer.start = source.start
        for node in nodes:
            self.nodes.append(node)
            executor.add_node(node)
        return source

    def _drive(self, profile: FieldProfile, sync: SyncProcess, source: GroundSpeedSource,
               observer: Observer, design_node: DesignNode) -> None:
        demo, duration = self.demo, self.demo.options.duration
        next_print = PROGRESS_PERIOD
        while True:
            sync.poll()
            t = source.elapsed()
            self.elapsed = min(t, duration)
            if self._stopped():
                return self._interrupted()
            if t >= duration:
                self.completed = True
                return None
            self._switch_spacing(t, design_node)
            if t >= next_print:
                demo._print(demo.progress(t, profile, sync.status, observer))
                next_print += PROGRESS_PERIOD
            time.sleep(0.05)

    def _switch_spacing(self, t: float, design_node: DesignNode) -> None:
        """The scene's spacing schedule: at each switch's time, the design node's
        plant_spacing is set (it publishes the new design)."""
        schedule = self.demo.schedule
        while self._next_switch < len(schedule) and t >= schedule[self._next_switch][0]:
            at, spacing = schedule[self._next_switch]
            self._next_switch += 1
            if spacing == design_node.design.plant_spacing:
                continue
            result = design_node.set_parameters([_param('plant_spacing', spacing)])[0]
            if result.successful:
                self.scheduled_changes += 1
                self.demo._print(f'{t:6.1f} s  spacing schedule: plant_spacing -> '
                                 f'{spacing:.3f} m (from the next plant)')
            else:
                self.demo._print(f'{t:6.1f} s  spacing schedule: {spacing} m refused: '
                                 f'{result.reason}')

    def _interrupted(self):
        self.demo._print(f'\ninterrupted by {self.stopped_by}: stopping')
        return None

    def stop(self):
        """Drives shut down first (the sync process), then this process's nodes: the monitor
        finalises the bag."""
        if self.sync is not None:
            self.sync.stop()
        if self.spinner is not None:
            self.spinner.stop()             # spinning ended, then the executor shut down
        for node in reversed(self.nodes):
            node.destroy_node()
        if self.context is not None:
            self.context.try_shutdown()

    def bag_error(self):
        """Why the run has no usable bag ('' when it has one)."""
        if self.monitor is None:
            return 'the monitor did not start'
        if self.monitor.recorder is None:
            return self.monitor.record_error or 'the monitor did not record'
        if not self.monitor.recorder.closed or self.monitor.record_error:
            return self.monitor.record_error or f'{self.monitor.recorder.path} not finalised'
        return ''


@dataclass
class DemoResult:
    """What a run found, for callers that run demos themselves (the bench)."""

    verdict: Any                  # verdict.Verdict
    sync: Any                     # sync_process.SyncReport (None if none came)
    rows: list                    # verdict.RowResult per planting row
    domain: int                   # the private DDS domain it ran in (-1: none)
    first_plants: dict | None = None    # --machine: demo.commissioned.first_plant_errors

    @property
    def report(self) -> dict | None:
        """The sync process's final report as one plain mapping (SyncReport.flat)."""
        return self.sync.flat() if self.sync is not None else None


def _param(name: str, value: Any):
    return Parameter(name, value=value)
