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
offline and printing the replay summary. Ctrl-C stops it cleanly (drives shut down, bus closed,
bag finalised) with a summary.
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
    from planter_ros.cli.main import BadInput
    from planter_ros.config import ConfigError, from_mapping
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
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return Demo(scene, design, rows, args, antenna).run()


class Demo:
    def __init__(self, scene, design, rows, args, antenna=None):
        from planter_ros.geo import AntennaSettings
        self.scene, self.design, self.rows, self.args = scene, design, rows, args
        self.antenna = antenna or AntennaSettings()
        self.planting = [row for row in rows if row.enabled]

    def run(self):
        import threading

        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from planter_ros import interfaces
        from planter_ros.drive.simulated_drive import SimulatedBus
        from planter_ros.nodes.design_node import DesignNode
        from planter_ros.nodes.sync_node import SyncNode
        from planter_ros.rows import scene_row_parameters
        from planter_ros.sim.field import FieldProfile, demo_curves
        from planter_ros.sim.gnss import SimulatedGnss
        from planter_ros.sim.ros_field import GnssSource, GroundSpeedSource, Observer

        args, design = self.args, self.design
        from planter_ros.nodes.monitor_node import MonitorNode
        channel = f'planter_demo_{os.getpid()}_{time.monotonic_ns() % 1_000_000}'
        profile = FieldProfile(args.duration, design['nominal_ground_speed'],
                               curves=demo_curves(args.duration))
        glitches = [(0.3 * args.duration, 25.0), (0.6 * args.duration, math.nan)]
        ros_scene = _scene_parameters(self.scene)
        row_params = [_param(k, v) for k, v in scene_row_parameters(self.scene).items()]

        sims = SimulatedBus(channel, [row.drive_node_id for row in self.planting])
        sims.start()
        context = Context()
        rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
        executor = SingleThreadedExecutor(context=context)
        nodes = []
        sync = spinner = monitor = None
        interrupted = False
        try:
            ns = interfaces.NAMESPACE
            nodes.append(DesignNode(context=context, namespace=ns,
                                    parameter_overrides=ros_scene))
            sync = SyncNode(context=context, namespace=ns, parameter_overrides=[
                _param('can_interface', 'virtual'), _param('can_channel', channel),
                _param('phase_lock', not args.speed_only),
                _param('turn_compensation', not args.no_turn_compensation)] + row_params)
            nodes.append(sync)
            observer = Observer(context=context, namespace=ns)
            nodes.append(observer)
            monitor = MonitorNode(context=context, namespace=ns, parameter_overrides=(
                [_param('bag_path', args.bag)] if args.bag else []) + row_params + [
                _param('antenna_position', list(self.antenna.antenna_position))])
            nodes.append(monitor)                # per-plant predictions and the bag
            turns = ', '.join(f'{"left" if c.radius > 0 else "right"} turn R = '
                              f'{abs(c.radius):g} m at {c.start:.1f}-{c.end:.1f} s'
                              for c in profile.curves)
            print(f"planter demo: {design['crop']} {design['mechanism']}, d = "
                  f"{design['plant_spacing']:.3f} m, cruise {profile.cruise:.2f} -> "
                  f"{profile.cruise * profile.change:.2f} m/s, {turns}, {args.duration:g} s, "
                  f"{'speed-only' if args.speed_only else 'phase-locked'}, turn compensation "
                  f"{'off' if args.no_turn_compensation else 'on'}, CAN virtual:{channel}")
            if self.rows[0].name:
                print('rows: ' + ', '.join(
                    f'{row.name} (y = {row.lateral_offset:+.2f} m, node {row.drive_node_id}'
                    f'{"" if row.enabled else ", disabled"})' for row in self.rows)
                      + f'; CAN bus load {100 * sync.bus_load.load:.1f} % of '
                      f'{sync.bus_load.bitrate} bit/s')
            sync.enable_drive()                  # blocking, before anything spins
            print(('drive enabled' if len(self.planting) == 1 else
                   f'{sum(u.running for u in sync.units)} drives enabled')
                  + ' (CiA 402 profile velocity); field run starts')
            source = GroundSpeedSource(profile, glitches=glitches, seed=args.seed,
                                       context=context, namespace=ns)
            nodes.append(source)
            # the machine's GNSS receiver, on the same path and clock
            gnss = SimulatedGnss(origin_latitude=args.origin_latitude,
                                 origin_longitude=args.origin_longitude)
            nodes.append(GnssSource(profile, gnss, source.start,
                                    antenna=self.antenna.antenna_position, seed=args.seed,
                                    context=context, namespace=ns))
            print(f'GNSS: simulated receiver at {gnss.rate:g} Hz from {gnss.origin_latitude:.7f}, '
                  f'{gnss.origin_longitude:.7f} (WGS 84), noise {gnss.noise * 1e3:.0f} mm per '
                  f'axis; antenna x = {self.antenna.antenna_position[0]:+.2f} m, y = '
                  f'{self.antenna.antenna_position[1]:+.2f} m on the machine')
            observer.start = source.start
            for node in nodes:
                executor.add_node(node)
            spinner = threading.Thread(target=executor.spin, daemon=True)
            spinner.start()
            next_print = PROGRESS_PERIOD
            while True:
                t = source.elapsed()
                if t >= args.duration:
                    break
                if t >= next_print:
                    print(self._progress(t, profile, sync, observer), flush=True)
                    next_print += PROGRESS_PERIOD
                time.sleep(0.05)
        except KeyboardInterrupt:
            interrupted = True
            print('\ninterrupted: stopping', flush=True)
        finally:
            executor.shutdown(timeout_sec=2.0)
            if spinner is not None:
                spinner.join(timeout=2.0)
            for node in reversed(nodes):
                node.destroy_node()          # the sync node shuts the drive down first
            context.try_shutdown()
            sims.stop()
        if sync is not None and 'observer' in locals() and observer.start is not None:
            print(self.summary(profile, sync, observer, sims))
        if monitor is not None and monitor.recorder is not None:
            print(self.replay_summary(monitor.recorder.path))
        return 130 if interrupted else 0

    @staticmethod
    def replay_summary(bag):
        """Re-read the finished bag offline, as `planter replay` would, and summarise it."""
        from planter_ros.cli.replay import format_summary
        from planter_ros.recording.replay import ReplayError, replay
        try:
            result = replay(bag)
        except ReplayError as exc:
            return f'\nreplay of {bag} failed: {exc}'
        lines = [f'\nrecorded {bag}; replay (`planter replay {bag}`):']
        lines += [f'  {line}' for line in format_summary(result).splitlines()]
        lines += [f'  warning: {w}' for w in result.warnings]
        return '\n'.join(lines)

    def _joint(self, row):
        return row.joint(self.design['mechanism'])

    def _progress(self, t, profile, sync, observer):
        plants = sum(len(observer.plant_positions(profile, self.design, self._joint(row),
                                                  row.lateral_offset))
                     for row in self.planting)
        if len(self.planting) == 1:
            status = sync._status
            return (f't = {t:5.1f} s  v = {profile(t):.3f} m/s  command = '
                    f'{sync.command_value:6.3f} rad/s  measured = '
                    f'{status.velocity if status else 0.0:6.3f} rad/s  plants = {plants:3d}  '
                    f'drive: {status.state if status else "-"}')
        commands = ' '.join(f'{u.command:5.2f}' for u in sync.units if u.drive is not None)
        return (f't = {t:5.1f} s  v = {profile(t):.3f} m/s  yaw rate = '
                f'{profile.yaw_rate(t):+.3f} rad/s  commands = {commands} rad/s  '
                f'plants = {plants:3d}')

    def summary(self, profile, sync, observer, sims):
        import numpy as np

        from planter_ros.sim.spacing import spacing_stats
        d = self.design['plant_spacing']
        n = self.design['plants_per_revolution']
        named = bool(self.rows[0].name)
        lines = ['', 'summary']
        for row in self.planting:
            joint = self._joint(row)
            times, positions = observer.plants(profile, self.design, joint, row.lateral_offset)
            stats = spacing_stats(positions, d)
            gaps = np.diff(positions) - d
            rms = float(np.sqrt(np.mean(gaps ** 2))) if gaps.size else 0.0
            head = f'  row {row.label} (y = {row.lateral_offset:+.2f} m)' if named else ''
            if head:
                lines.append(head)
            pad = '    ' if named else '  '
            lines += [f"{pad}plants placed            {stats.plants}",
                      f"{pad}spacing error |gap - d|  mean "
                      f"{stats.mean_abs_spacing_error * 1e3:.2f} mm, RMS {rms * 1e3:.2f} mm, "
                      f"max {stats.max_abs_spacing_error * 1e3:.2f} mm  (d = {d * 1e3:.0f} mm)",
                      f"{pad}drift from the grid      max {stats.max_abs_drift * 1e3:.2f} mm, "
                      f"last plant {stats.final_drift * 1e3:+.2f} mm"]
            for label, (a, b) in (('cruise 1', (profile.start + 0.5, profile.t_change)),
                                  ('cruise 2', (profile.t_change + 1.5, profile.t_stop))):
                expected = 2 * math.pi * profile(0.5 * (a + b)) / (n * d)
                cmd = observer.window('command', a, b, joint)
                meas = observer.window('velocity', a, b, joint)
                if cmd.size and meas.size and not named:
                    rms = np.sqrt(np.mean((meas - expected) ** 2))
                    lines.append(f"{pad}{label + ' speed':<24} expected {expected:.3f} rad/s, "
                                 f'commanded {np.mean(cmd):.3f}, measured {np.mean(meas):.3f} '
                                 f'(rms measured - expected {rms:.3f})')
            lines += self._curve_lines(profile, observer, row, times, positions, pad)
        law = sync.law
        lines.append(f"  ground-speed samples     {law.accepted} accepted, rejected "
                     + ', '.join(f'{k} {v}' for k, v in law.rejected.items()))
        yaw = sync.machine.filter.yaw
        lines.append(f"  yaw-rate samples         {yaw.accepted} accepted, rejected "
                     + ', '.join(f'{k} {v}' for k, v in yaw.rejected.items()))
        slips = sum(unit.law.phase_slips for unit in sync.units)
        lines.append(f'  phase slips              {slips}; CAN send errors '
                     f'{sync.send_errors}; mode '
                     f"{'phase-locked' if law.config.phase_lock else 'speed-only'}, turn "
                     f"compensation {'on' if sync.machine.turn.turn_compensation else 'off'}")
        trips = ', '.join(f'node {node}: {why} (0x{code:04X})'
                          for node, why, code in sims.watchdog_trips)
        lines.append(f"  drive watchdog trips     {trips or 'none'}")
        return '\n'.join(lines)

    def _curve_lines(self, profile, observer, row, times, positions, pad):
        """Per turn: the row's mean spacing error and speed against 2πv_i/(n·d), next to the
        bias a machine without turn compensation shows there (−y·d/R)."""
        import numpy as np
        d = self.design['plant_spacing']
        n = self.design['plants_per_revolution']
        lines = []
        gaps = np.diff(positions) - d
        for curve in profile.curves:
            a, b = curve.start + curve.ease, curve.end - curve.ease
            mine = gaps[(times[:-1] >= a) & (times[1:] <= b)]
            meas = observer.window('velocity', a, b, self._joint(row))
            grid = np.linspace(a, b, 50)
            expected = np.mean([2 * math.pi * profile(t) * (1 - row.lateral_offset
                                                            / curve.radius) / (n * d)
                                for t in grid])
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
