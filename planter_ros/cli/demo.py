"""`planter demo`: the whole machine on a simulated CAN bus (planter_ros.demo); this module only
parses the options. Bad input (a scene, an option, the bag path) is exit 2 before anything
starts; the verdict line gives 0 (PASS) or 1 (FAIL)."""

import sys

from planter_ros.cli.main import main
from planter_ros.cli.options import spec_option
from planter_ros.config import spec_of
from planter_ros.demo.options import DemoOptions
from planter_ros.sim.gnss import SimulatedGnss
from planter_ros.sim.tray import add_tray_arguments


def add_arguments(parser):
    parser.add_argument('--scene', metavar='FILE', default=None,
                        help='scene parameter file (default: config/tomato_five_bar.yaml)')
    parser.add_argument('--duration', type=spec_option(DemoOptions, 'duration', '--duration'),
                        default=30.0, metavar='S',
                        help='length of the field run in seconds, 8..3600 (default 30)')
    parser.add_argument('--bag', metavar='PATH', help='record the run to this bag: a .mcap '
                        'file or a rosbag2 bag directory, in an existing writable directory '
                        '(default: bags/planter_<date-time>; never overwrites)')
    parser.add_argument('--speed-only', action='store_true',
                        help='turn phase lock off (feed-forward speed only), for comparison')
    parser.add_argument('--no-turn-compensation', action='store_true', help="every row on "
                        "the machine's speed, not its own on the curves, for comparison")
    parser.add_argument('--seed', type=spec_option(DemoOptions, 'seed', '--seed'), default=0,
                        help='noise, tray and (--machine) wiring seed, 0..2^32-1 (default 0)')
    add_tray_arguments(parser, DemoOptions, (0.0, 0.0), spec_option)
    parser.add_argument('--machine', metavar='FILE', help='a commissioned machine file (its '
                        'rows, drives checked, homed, phased; the first plant measured)')
    for name, word in (('origin_latitude', 'latitude'), ('origin_longitude', 'longitude')):
        spec = spec_of(SimulatedGnss, name)
        parser.add_argument(f'--origin-{word}', metavar='DEG', default=spec.default,
                            type=spec_option(SimulatedGnss, name, f'--origin-{word}'),
                            help=f'{word} (WGS 84) where the field run starts: the simulated '
                                 f'GNSS receiver\'s origin, {spec.allowed()} (default '
                                 f'{spec.default:g})')


def options(args):
    """The DemoOptions the parsed arguments ask for."""
    return DemoOptions(scene=args.scene, duration=args.duration, bag=args.bag, seed=args.seed,
                       phase_lock=not args.speed_only, empty_rate=args.empty_rate,
                       turn_compensation=not args.no_turn_compensation,
                       double_rate=args.double_rate, origin_latitude=args.origin_latitude,
                       origin_longitude=args.origin_longitude, machine=args.machine)


if __name__ == '__main__':
    sys.exit(main(['demo'] + sys.argv[1:]))
