"""`planter demo`: the whole machine in one process, on a simulated CAN bus.

design_node + sync_node + monitor_node + a simulated ground-speed sensor, and one simulated
CiA 402 drive per row (node ids from the scene; one drive, node 1, for a scene without rows) on
a python-can virtual bus with a channel of its own.
The sensor follows a field run (start, cruise with noise, a left and a right turn of 10 m
radius, a speed change, a stop, noise on speed and yaw rate, and two glitches the sync node
must reject). At the end it prints per row the plants placed, the spacing error (from the
measured mechanism angle in joint_states against the row's true travelled distance), commanded
against measured speed, and in the turns the compensation's effect. The monitor records the run
(bags/planter_<date-time> unless --bag says otherwise); the demo ends by replaying that bag
offline and printing the replay summary, then one verdict line: PASS, or FAIL and every
reason (cli.demo_verdict); the exit code is 0 on PASS, 1 on FAIL, 2 for bad input before
anything starts. Ctrl-C or SIGTERM stops it cleanly (drives shut down, bus closed, bag
finalised) with the summaries and the verdict on what ran; a second signal forces the exit.

The graph runs in a DDS domain of its own (planter_ros.dds_domain), so no other graph on the
host reaches it, and the sync node with the simulated drives runs in a process of its own
(cli.demo_sync), so nothing else the demo does can hold up the drives' commands.
"""

from dataclasses import dataclass
import math
import os
import sys
import time
from pathlib import Path

from planter_ros.cli.options import spec_option
from planter_ros.config import check, setting, spec_of

PROGRESS_PERIOD = 2.0     # s between progress lines


@dataclass(frozen=True)
class DemoOptions:
    """The demo's own settings (the command-line options)."""

    duration: float = setting(30.0, 'length of the field run', unit='s', range=(8.0, 3600.0))
    seed: int = setting(0, 'sensor noise seed', range=(0, 2 ** 32 - 1))

    def __post_init__(self):
        check(self)


def add_arguments(parser):
    parser.add_argument('--scene', metavar='FILE', default=None,
                        help='scene parameter file (default: config/tomato_five_bar.yaml)')
    parser.add_argument('--duration', type=spec_option(DemoOptions, 'duration', '--duration'),
                        default=30.0, metavar='S',
                        help='length of the field run in seconds, 8..3600 (default 30)')
    parser.add_argument('--bag', metavar='PATH',
                        help='record the run to this bag: a .mcap file or a rosbag2 bag '
                             'directory, in an existing writable directory (default: '
                             'bags/planter_<date-time>; never overwrites)')
    parser.add_argument('--speed-only', action='store_true',
                        help='turn phase lock off (feed-forward speed only), for comparison')
    parser.add_argument('--no-turn-compensation', action='store_true',
                        help="every row on the machine's speed, not its own on the curves, "
                             'for comparison')
    parser.add_argument('--seed', type=spec_option(DemoOptions, 'seed', '--seed'), default=0,
                        help='sensor noise seed, 0..2^32-1 (default 0)')
    from planter_ros.sim.gnss import SimulatedGnss
    for name, word in (('origin_latitude', 'latitude'), ('origin_longitude', 'longitude')):
        spec = spec_of(SimulatedGnss, name)
        parser.add_argument(f'--origin-{word}', metavar='DEG', default=spec.default,
                            type=spec_option(SimulatedGnss, name, f'--origin-{word}'),
                            help=f'{word} (WGS 84) where the field run starts: the simulated '
                                 f'GNSS receiver\'s origin, {spec.allowed()} (default '
                                 f'{spec.default:g})')


def default_scene():
    repo = Path(__file__).resolve().parents[2] / 'config' / 'tomato_five_bar.yaml'
    if repo.is_file():
        return repo
    from ament_index_python.packages import get_package_share_directory
    return Path(get_package_share_directory('planter_ros')) / 'config' / 'tomato_five_bar.yaml'


def check_bag_path(bag):
    """Refuse (OutputError) a --bag the recorder could not create, before anything starts:
    an existing path, an extension other than .mcap (a file) or none (a bag directory), a
    missing or read-only directory; without --bag, the default bags/ directory (or the current
    directory it would be made in) must be writable."""
    from planter_ros.output_files import check_directory, check_new_path
    if bag is not None:
        check_new_path(bag, '--bag', ('.mcap', ''))
        return
    bags = Path('bags')
    default = bags / 'planter_<date-time>'
    check_directory(bags if bags.exists() else Path('.'), '--bag (default)', default)


def run(args):
    return prepare(args).run()


def prepare(args, **kwargs):
    """The Demo `args` ask for, every input and output checked (BadInput, ConfigError,
    OutputError: exit 2 before anything starts); kwargs go to Demo."""
    from planter_ros.cli.main import BadInput
    from planter_ros.config import ConfigError, from_mapping
    from planter_ros.dds_domain import keep_discovery_on_host
    from planter_ros.geo import AntennaSettings
    from planter_ros.kinematics.scene_design import design_for_scene
    from planter_ros.rows import rows_from_scene
    from planter_ros.scene import SceneError, load_scene

    try:
        scene = load_scene(args.scene or default_scene(), 'design_node')
    except SceneError as exc:
        raise BadInput(str(exc)) from None
    check_bag_path(args.bag)
    design = design_for_scene(scene)          # a bad scene fails here, before anything starts
    try:
        rows = rows_from_scene(scene, default_node_id=1)
        antenna = from_mapping(AntennaSettings, scene)
    except ConfigError as exc:
        raise BadInput(f'scene {args.scene or default_scene()}: {exc}') from None
    if not any(row.enabled for row in rows):
        raise BadInput(f'scene {args.scene or default_scene()}: rows = every row has enabled '
                       'false: allowed at least one enabled row')
    keep_discovery_on_host()
    return Demo(scene, design, rows, args, antenna=antenna, **kwargs)


class Demo:
    """One demo run. `out`: where the report goes (stdout); `install_signals`: take over
    SIGINT/SIGTERM (the command line; a caller that runs demos itself, the bench, keeps its
    own); `log_level`: the nodes' ROS log level; `antenna`: the GNSS antenna on the machine
    (geo.AntennaSettings, the scene's)."""

    def __init__(self, scene, design, rows, args, out=None, install_signals=True,
                 log_level='info', antenna=None):
        from planter_ros.geo import AntennaSettings
        self.scene, self.design, self.rows, self.args = scene, design, rows, args
        self.antenna = antenna or AntennaSettings()
        self.planting = [row for row in rows if row.enabled]
        self.out = out or sys.stdout
        self.install_signals = install_signals
        self.log_level = log_level
        self.result = None            # DemoResult once run

    def _print(self, text=''):
        print(text, file=self.out, flush=True)

    # ---------------------------------------------------------------- the run
    def run(self):
        """The whole run; returns the exit code (0 PASS, 1 FAIL)."""
        from planter_ros import stop_signals
        from planter_ros.dds_domain import NoFreeDomainError, claim_private_domain

        stop = (stop_signals.install('planter demo') if self.install_signals
                else stop_signals.StopSignals('planter demo'))
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

    def finish(self, run):
        """Summaries, the replay of the bag, the verdict line; the exit code."""
        from planter_ros.cli.demo_verdict import judge
        report = run.sync.report if run.sync is not None else None
        rows = []
        if run.observer is not None and run.observer.start is not None and report is not None:
            summary, rows = self.summary(run.profile, run.observer, report)
            self._print(summary)
        bag_error = run.bag_error()
        if not bag_error:
            replayed, bag_error = self.replay_summary(run.monitor.recorder.path)
            self._print(replayed)
        monitor_changes = ''
        if run.monitor is not None and run.monitor.design_sources.changes:
            sources = run.monitor.design_sources
            monitor_changes = (f'{sources.changes}x, the latest from '
                               f'{sources.last_change.text}')
        verdict = judge(rows, report, run.start_error, bag_error, monitor_changes)
        verdict.stopped_by, verdict.elapsed = run.stopped_by, run.elapsed
        self.result = DemoResult(verdict, report, rows, run.domain)
        self._print('')
        self._print(verdict.line())
        return verdict.exit_code

    @staticmethod
    def replay_summary(bag):
        """Re-read the finished bag offline, as `planter replay` would, and summarise it:
        (text, why it failed or '')."""
        from planter_ros.cli.replay import format_summary
        from planter_ros.recording.replay import ReplayError, replay
        try:
            result = replay(bag)
        except ReplayError as exc:
            return f'\nreplay of {bag} failed: {exc}', f'replay of {bag} failed: {exc}'
        lines = [f'\nrecorded {bag}; replay (`planter replay {bag}`):']
        lines += [f'  {line}' for line in format_summary(result).splitlines()]
        lines += [f'  warning: {w}' for w in result.warnings]
        return '\n'.join(lines), ''

    def _joint(self, row):
        return row.joint(self.design['mechanism'])

    def _progress(self, t, profile, status, observer):
        plants = sum(len(observer.plant_positions(profile, self.design, self._joint(row),
                                                  row.lateral_offset))
                     for row in self.planting)
        rows = status.get('rows', [])
        if len(self.planting) == 1:
            row = rows[0] if rows else {}
            return (f't = {t:5.1f} s  v = {profile(t):.3f} m/s  command = '
                    f'{row.get("command", 0.0):6.3f} rad/s  measured = '
                    f'{row.get("velocity", 0.0):6.3f} rad/s  plants = {plants:3d}  '
                    f'drive: {row.get("state", "-")}')
        commands = ' '.join(f'{row["command"]:5.2f}' for row in rows)
        return (f't = {t:5.1f} s  v = {profile(t):.3f} m/s  yaw rate = '
                f'{profile.yaw_rate(t):+.3f} rad/s  commands = {commands} rad/s  '
                f'plants = {plants:3d}')

    def _spacing_changes(self, observer):
        """(t since start, d) of each design change the observer saw."""
        return [(t, float(design['plant_spacing'])) for t, design in observer.design_changes()]

    def summary(self, profile, observer, report):
        """The demo's own figures per row (from the measured angle against the true distance)
        and the command path's report: (text, [RowResult] for the verdict)."""
        import numpy as np

        from planter_ros.cli.demo_verdict import RowResult
        from planter_ros.sim.spacing import spacing_in_force, spacing_stats
        d = self.design['plant_spacing']
        n = self.design['plants_per_revolution']
        named = bool(self.rows[0].name)
        changes = self._spacing_changes(observer)
        lines = ['', 'summary']
        results = []
        for row in self.planting:
            joint = self._joint(row)
            times, positions = observer.plants(profile, self.design, joint, row.lateral_offset)
            in_force = spacing_in_force(times, d, changes)      # each gap against its design
            stats = spacing_stats(positions, in_force)
            gaps = np.diff(positions) - in_force
            rms = float(np.sqrt(np.mean(gaps ** 2))) if gaps.size else 0.0
            relative = float(np.sqrt(np.mean((gaps / in_force) ** 2))) if gaps.size else 0.0
            results.append(RowResult(row.label if named else '', stats.plants, relative))
            head = f'  row {row.label} (y = {row.lateral_offset:+.2f} m)' if named else ''
            if head:
                lines.append(head)
            pad = '    ' if named else '  '
            against = (f'd = {d * 1e3:.0f} mm' if not changes else
                       'd in force: ' + ' -> '.join(f'{x * 1e3:.0f}' for x in
                                                    [d] + [c[1] for c in changes]) + ' mm')
            lines += [f"{pad}plants placed            {stats.plants}",
                      f"{pad}spacing error |gap - d|  mean "
                      f"{stats.mean_abs_spacing_error * 1e3:.2f} mm, RMS {rms * 1e3:.2f} mm, "
                      f"max {stats.max_abs_spacing_error * 1e3:.2f} mm  ({against})",
                      f"{pad}drift from the grid      max {stats.max_abs_drift * 1e3:.2f} mm, "
                      f"last plant {stats.final_drift * 1e3:+.2f} mm"]
            for label, (a, b) in (('cruise 1', (profile.start + 0.5, profile.t_change)),
                                  ('cruise 2', (profile.t_change + 1.5, profile.t_stop))):
                expected = 2 * math.pi * profile(0.5 * (a + b)) / (
                    n * _in_force_at(0.5 * (a + b), d, changes))
                cmd = observer.window('command', a, b, joint)
                meas = observer.window('velocity', a, b, joint)
                if cmd.size and meas.size and not named:
                    rms_speed = np.sqrt(np.mean((meas - expected) ** 2))
                    lines.append(f"{pad}{label + ' speed':<24} expected {expected:.3f} rad/s, "
                                 f'commanded {np.mean(cmd):.3f}, measured {np.mean(meas):.3f} '
                                 f'(rms measured - expected {rms_speed:.3f})')
            lines += self._curve_lines(profile, observer, row, times, positions, pad, in_force)
        lines += self._command_path_lines(report)
        return '\n'.join(lines), results

    @staticmethod
    def _command_path_lines(report):
        """Sample counts, slips, send errors, watchdog trips and the control loop's period
        statistics, from the sync process's report."""
        lines = [f"  ground-speed samples     {report['accepted']} accepted, rejected "
                 + ', '.join(f'{k} {v}' for k, v in report['rejected'].items()),
                 f"  yaw-rate samples         {report['yaw_accepted']} accepted, rejected "
                 + ', '.join(f'{k} {v}' for k, v in report['yaw_rejected'].items()),
                 f"  phase slips              {report['phase_slips']}; CAN send errors "
                 f"{report['send_errors']}; mode "
                 f"{'phase-locked' if report['phase_lock'] else 'speed-only'}, turn "
                 f"compensation {'on' if report['turn_compensation'] else 'off'}"]
        trips = ', '.join(f'node {node}: {why} (0x{code:04X})'
                          for node, why, code in report['watchdog_trips'])
        lines.append(f"  drive watchdog trips     {trips or 'none'}")
        deadline = report['command_timeout']
        for row in report['rows']:
            loop = row['loop']
            name = f' {row["label"]}' if len(report['rows']) > 1 else ''
            if not loop['gaps']:
                lines.append(f'  control loop{name:<12} no command frames')
                continue
            lines.append(f"  control loop{name:<12} command gap mean {loop['mean'] * 1e3:.1f} "
                         f"ms, p99.9 {loop['p999'] * 1e3:.1f} ms, max {loop['max'] * 1e3:.1f} "
                         f"ms over {loop['gaps'] + 1} frames (drive deadline "
                         f'{deadline * 1e3:.0f} ms)')
        design = report['design']
        lines.append(f"  design                   from {design['first'] or 'nobody'}"
                     + (f"; {design['changes']} change(s) during the run, the latest from "
                        f"{design['last_change']}" if design['changes'] else
                        '; unchanged during the run'))
        return lines

    def _curve_lines(self, profile, observer, row, times, positions, pad, in_force):
        """Per turn: the row's mean spacing error and speed against 2πv_i/(n·d), next to the
        bias a machine without turn compensation shows there (−y·d/R)."""
        import numpy as np
        d = self.design['plant_spacing']
        n = self.design['plants_per_revolution']
        changes = self._spacing_changes(observer)
        lines = []
        gaps = np.diff(positions) - in_force
        for curve in profile.curves:
            a, b = curve.start + curve.ease, curve.end - curve.ease
            mine = gaps[(times[:-1] >= a) & (times[1:] <= b)]
            meas = observer.window('velocity', a, b, self._joint(row))
            grid = np.linspace(a, b, 50)
            expected = np.mean([2 * math.pi * profile(t) * (1 - row.lateral_offset
                                                            / curve.radius)
                                / (n * _in_force_at(t, d, changes)) for t in grid])
            side = 'left' if curve.radius > 0 else 'right'
            err = (f'mean {np.mean(mine) * 1e3:+.2f} mm, RMS '
                   f'{np.sqrt(np.mean(mine ** 2)) * 1e3:.2f} mm over {mine.size} gaps'
                   if mine.size else 'n/a')
            ratio = (f'; speed {np.median(meas) / expected:.3f} x 2πv_i/(n·d)'
                     if meas.size and expected > 0 else '')
            bias = (f'; without compensation expect '
                    f'{-row.lateral_offset * d / curve.radius * 1e3:+.2f} mm (-y·d/R)'
                    if row.lateral_offset else '')     # a row at y = 0 sees no difference
            lines.append(f'{pad}{side + " turn R = " + format(abs(curve.radius), "g") + " m":<24}'
                         f' spacing error {err}{ratio}{bias}')
        return lines


class _Run:
    """The graph of one demo run and its life cycle: the sync process (the command path and
    the simulated drives) and, in this process, the design node, the monitor, the demo's
    observer and the field sensors, all in the demo's private DDS domain."""

    START_TIMEOUT = 120.0     # s for the sync process to import, build and enable (loaded host)
    MATCH_TIMEOUT = 20.0      # s for the graph to discover itself before the field run

    def __init__(self, demo, domain, stop):
        self.demo, self.domain, self.stop_signal = demo, domain, stop
        self.sync = self.context = self.executor = self.spinner = None
        self.monitor = self.observer = self.source = None
        self.nodes = []
        self.profile = None
        self.start_error = ''
        self.elapsed = 0.0

    @property
    def stopped_by(self):
        return self.stop_signal.name_received

    def _stopped(self):
        return self.stop_signal.received is not None

    def start_and_drive(self):
        import threading

        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from planter_ros import interfaces
        from planter_ros.cli.demo_sync import (SyncProcess, SyncProcessError,
                                               SyncProcessSettings)
        from planter_ros.nodes.design_node import DesignNode
        from planter_ros.nodes.monitor_node import MonitorNode
        from planter_ros.rows import scene_row_parameters
        from planter_ros.sim.field import FieldProfile, demo_curves
        from planter_ros.sim.ros_field import Observer

        demo, args, design = self.demo, self.demo.args, self.demo.design
        channel = f'planter_demo_{os.getpid()}_{time.monotonic_ns() % 1_000_000}'
        self.profile = profile = FieldProfile(args.duration, design['nominal_ground_speed'],
                                              curves=demo_curves(args.duration))
        row_params = list(scene_row_parameters(demo.scene).items())
        ns = interfaces.NAMESPACE
        # the command path first: it takes longest to start (its own interpreter)
        self.sync = SyncProcess(SyncProcessSettings(
            self.domain, channel, tuple(row.drive_node_id for row in demo.planting), ns,
            (('can_interface', 'virtual'), ('can_channel', channel),
             ('phase_lock', not args.speed_only),
             ('turn_compensation', not args.no_turn_compensation)) + tuple(row_params),
            demo.log_level))
        self.context = Context()
        rclpy.init(args=['--ros-args', '--log-level', demo.log_level], context=self.context,
                   domain_id=self.domain, signal_handler_options=SignalHandlerOptions.NO)
        self.executor = SingleThreadedExecutor(context=self.context)
        context = self.context
        self.nodes.append(DesignNode(context=context, namespace=ns,
                                     parameter_overrides=_scene_parameters(demo.scene)))
        self.observer = Observer(context=context, namespace=ns)
        self.nodes.append(self.observer)
        params = [_param(k, v) for k, v in row_params]
        self.monitor = MonitorNode(context=context, namespace=ns, parameter_overrides=(
            [_param('bag_path', args.bag)] if args.bag else []) + params + [
            _param('antenna_position', list(demo.antenna.antenna_position))])
        self.nodes.append(self.monitor)          # per-plant predictions and the bag
        for node in self.nodes:
            self.executor.add_node(node)
        self.spinner = threading.Thread(target=self.executor.spin, daemon=True)
        self.spinner.start()
        turns = ', '.join(f'{"left" if c.radius > 0 else "right"} turn R = '
                          f'{abs(c.radius):g} m at {c.start:.1f}-{c.end:.1f} s'
                          for c in profile.curves)
        demo._print(f"planter demo: {design['crop']} {design['mechanism']}, d = "
                    f"{design['plant_spacing']:.3f} m, cruise {profile.cruise:.2f} -> "
                    f"{profile.cruise * profile.change:.2f} m/s, {turns}, {args.duration:g} s, "
                    f"{'speed-only' if args.speed_only else 'phase-locked'}, turn compensation "
                    f"{'off' if args.no_turn_compensation else 'on'}, CAN virtual:{channel}, "
                    f'DDS domain {self.domain} (private)')
        try:
            built = self.sync.wait_for('built', self.START_TIMEOUT, self._stopped)
            if built is None:
                return self._interrupted()
            if demo.rows[0].name:
                demo._print('rows: ' + ', '.join(
                    f'{row.name} (y = {row.lateral_offset:+.2f} m, node {row.drive_node_id}'
                    f'{"" if row.enabled else ", disabled"})' for row in demo.rows)
                    + f"; CAN bus load {100 * built['bus_load']:.1f} % of "
                    f"{built['bitrate']} bit/s")
            ready = self.sync.wait_for('ready', self.START_TIMEOUT, self._stopped)
            if ready is None:
                return self._interrupted()
        except SyncProcessError as exc:
            self.start_error = str(exc)
            demo._print(f'drives not started: {exc}')
            return None
        demo._print(('drive enabled' if len(demo.planting) == 1 else
                     f"{ready['running']} drives enabled")
                    + ' (CiA 402 profile velocity, sync node in a process of its own); field '
                    'run starts')
        self._start_field(profile)
        return self._drive(profile)

    def _start_field(self, profile):
        """The simulated sensors, once the graph has found itself (the sync node and the
        monitor subscribe the ground speed, the sync node has the design): t = 0 then."""
        from planter_ros import interfaces
        from planter_ros.sim.gnss import SimulatedGnss
        from planter_ros.sim.ros_field import GnssSource, GroundSpeedSource
        args, ns = self.demo.args, interfaces.NAMESPACE
        glitches = [(0.3 * args.duration, 25.0), (0.6 * args.duration, math.nan)]
        self.source = GroundSpeedSource(profile, glitches=glitches, seed=args.seed,
                                        context=self.context, namespace=ns)
        deadline = time.monotonic() + self.MATCH_TIMEOUT
        while time.monotonic() < deadline and not self._stopped():
            self.sync.poll(0.05)
            if (self.source._pub.get_subscription_count() >= 2
                    and self.sync.status.get('spacing') is not None):
                break
        self.source.restart()
        # the machine's GNSS receiver, on the same path and clock
        receiver = SimulatedGnss(origin_latitude=args.origin_latitude,
                                 origin_longitude=args.origin_longitude)
        antenna = self.demo.antenna.antenna_position
        gnss = GnssSource(profile, receiver, self.source.start, antenna=antenna,
                          seed=args.seed, context=self.context, namespace=ns)
        self.demo._print(
            f'GNSS: simulated receiver at {receiver.rate:g} Hz from '
            f'{receiver.origin_latitude:.7f}, {receiver.origin_longitude:.7f} (WGS 84), noise '
            f'{receiver.noise * 1e3:.0f} mm per axis; antenna x = {antenna[0]:+.2f} m, '
            f'y = {antenna[1]:+.2f} m on the machine')
        self.observer.start = self.source.start
        for node in (self.source, gnss):
            self.nodes.append(node)
            self.executor.add_node(node)

    def _drive(self, profile):
        demo, args = self.demo, self.demo.args
        next_print = PROGRESS_PERIOD
        while True:
            self.sync.poll()
            t = self.source.elapsed()
            self.elapsed = min(t, args.duration)
            if self._stopped():
                return self._interrupted()
            if t >= args.duration:
                return None
            if t >= next_print:
                demo._print(demo._progress(t, profile, self.sync.status, self.observer))
                next_print += PROGRESS_PERIOD
            time.sleep(0.05)

    def _interrupted(self):
        self.demo._print(f'\ninterrupted by {self.stopped_by}: stopping')
        return None

    def stop(self):
        """Drives shut down first (the sync process), then this process's nodes: the monitor
        finalises the bag."""
        if self.sync is not None:
            self.sync.stop()
        if self.executor is not None:
            self.executor.shutdown(timeout_sec=2.0)
        if self.spinner is not None:
            self.spinner.join(timeout=2.0)
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

    verdict: object               # demo_verdict.Verdict
    report: dict                  # the sync process's final report (None if none came)
    rows: list                    # demo_verdict.RowResult per planting row
    domain: int                   # the private DDS domain it ran in


def _in_force_at(t, spacing, changes):
    """d (m) in force at t s (by the changes' message times: for speeds, not plants)."""
    for when, new in changes:
        if t >= when:
            spacing = new
    return spacing


def _param(name, value):
    from rclpy.parameter import Parameter
    return Parameter(name, value=value)


def _scene_parameters(scene):
    """The scene as ROS parameters, each value of its declared type (YAML writes 1 for 1.0)."""
    from planter_ros.config import coerce, specs
    from planter_ros.kinematics.scene_settings import scene_classes
    known = {spec.name: spec for cls in scene_classes(scene.get('mechanism'))
             for spec in specs(cls)}
    return [_param(k, coerce(known[k], v) if k in known else v) for k, v in scene.items()]


if __name__ == '__main__':
    from planter_ros.cli.main import main
    sys.exit(main(['demo'] + sys.argv[1:]))
