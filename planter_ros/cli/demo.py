"""`planter demo`: the whole machine in one process, on a simulated CAN bus.

design_node + sync_node + monitor_node + a simulated ground-speed sensor, and the simulated
CiA 402 drive on a python-can virtual bus with a channel of its own.
The sensor follows a field run (start, cruise with noise, a speed change, a stop, and two
glitches the sync node must reject). At the end it prints plants placed, spacing error (from the
measured mechanism angle in joint_states against the true travelled distance), and commanded
against measured speed. The monitor records the run (bags/planter_<date-time> unless --bag says
otherwise); the demo ends by replaying that bag offline and printing the replay summary.
Ctrl-C stops it cleanly (drive shut down, bus closed, bag finalised) with a summary.
"""

from dataclasses import dataclass
import math
import os
import sys
import time
from pathlib import Path

from planter_ros.cli.options import spec_option
from planter_ros.config import check, setting

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
    parser.add_argument('--seed', type=spec_option(DemoOptions, 'seed', '--seed'), default=0,
                        help='sensor noise seed, 0..2^32-1 (default 0)')


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
    from planter_ros.kinematics.scene_design import design_for_scene
    from planter_ros.scene import SceneError, load_scene

    try:
        scene = load_scene(args.scene or default_scene(), 'design_node')
    except SceneError as exc:
        raise BadInput(str(exc)) from None
    check_bag_path(args.bag)
    design = design_for_scene(scene)          # a bad scene fails here, before anything starts
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return Demo(scene, design, args).run()


class Demo:
    def __init__(self, scene, design, args):
        self.scene, self.design, self.args = scene, design, args

    def run(self):
        import threading

        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from planter_ros import interfaces
        from planter_ros.drive.simulated_drive import SimulatedDrive
        from planter_ros.nodes.design_node import DesignNode
        from planter_ros.nodes.sync_node import SyncNode
        from planter_ros.sim.field import FieldProfile
        from planter_ros.sim.ros_field import GroundSpeedSource, Observer

        args, design = self.args, self.design
        from planter_ros.nodes.monitor_node import MonitorNode
        channel = f'planter_demo_{os.getpid()}_{time.monotonic_ns() % 1_000_000}'
        profile = FieldProfile(args.duration, design['nominal_ground_speed'])
        glitches = [(0.3 * args.duration, 25.0), (0.6 * args.duration, math.nan)]
        ros_scene = _scene_parameters(self.scene)

        sim = SimulatedDrive(channel, node_id=1)
        sim.start()
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
                _param('phase_lock', not args.speed_only)])
            nodes.append(sync)
            observer = Observer(context=context, namespace=ns)
            nodes.append(observer)
            monitor = MonitorNode(context=context, namespace=ns, parameter_overrides=(
                [_param('bag_path', args.bag)] if args.bag else []))
            nodes.append(monitor)                # per-plant predictions and the bag
            print(f"planter demo: {design['crop']} {design['mechanism']}, d = "
                  f"{design['plant_spacing']:.3f} m, cruise {profile.cruise:.2f} -> "
                  f"{profile.cruise * profile.change:.2f} m/s, {args.duration:g} s, "
                  f"{'speed-only' if args.speed_only else 'phase-locked'}, CAN virtual:{channel}")
            sync.enable_drive()                  # blocking, before anything spins
            print('drive enabled (CiA 402 profile velocity); field run starts')
            source = GroundSpeedSource(profile, glitches=glitches, seed=args.seed,
                                       context=context, namespace=ns)
            nodes.append(source)
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
            sim.stop()
        if sync is not None and 'observer' in locals() and observer.start is not None:
            print(self.summary(profile, sync, observer, sim))
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

    def _progress(self, t, profile, sync, observer):
        status = sync._status
        n = len(observer.plant_positions(profile, self.design))
        return (f't = {t:5.1f} s  v = {profile(t):.3f} m/s  command = {sync.command_value:6.3f} '
                f'rad/s  measured = {status.velocity if status else 0.0:6.3f} rad/s  '
                f'plants = {n:3d}  drive: {status.state if status else "-"}')

    def summary(self, profile, sync, observer, sim):
        import numpy as np

        from planter_ros.sim.spacing import spacing_stats
        d = self.design['plant_spacing']
        positions = observer.plant_positions(profile, self.design)
        stats = spacing_stats(positions, d)
        lines = ['', 'summary',
                 f"  plants placed            {stats.plants}",
                 f"  spacing error |gap - d|  mean {stats.mean_abs_spacing_error * 1e3:.2f} mm, "
                 f"max {stats.max_abs_spacing_error * 1e3:.2f} mm  (d = {d * 1e3:.0f} mm)",
                 f"  drift from the grid      max {stats.max_abs_drift * 1e3:.2f} mm, last plant "
                 f"{stats.final_drift * 1e3:+.2f} mm"]
        n = self.design['plants_per_revolution']
        for label, (a, b) in (('cruise 1', (profile.start + 0.5, profile.t_change)),
                              ('cruise 2', (profile.t_change + 1.5, profile.t_stop))):
            expected = 2 * math.pi * profile(0.5 * (a + b)) / (n * d)
            cmd = observer.window('command', a, b)
            meas = observer.window('velocity', a, b)
            if cmd.size and meas.size:
                rms = np.sqrt(np.mean((meas - expected) ** 2))
                lines.append(f"  {label + ' speed':<24} expected {expected:.3f} rad/s, "
                             f'commanded {np.mean(cmd):.3f}, measured {np.mean(meas):.3f} '
                             f'(rms measured - expected {rms:.3f})')
        law = sync.law
        lines.append(f"  ground-speed samples     {law.accepted} accepted, rejected "
                     + ', '.join(f'{k} {v}' for k, v in law.rejected.items()))
        lines.append(f'  phase slips              {law.phase_slips}; CAN send errors '
                     f'{sync.send_errors}; mode '
                     f"{'phase-locked' if law.config.phase_lock else 'speed-only'}")
        trips = ', '.join(f'{why} (0x{code:04X})' for why, code in sim.watchdog_trips)
        lines.append(f"  drive watchdog trips     {trips or 'none'}")
        return '\n'.join(lines)


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
