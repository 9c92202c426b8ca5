"""`planter replay BAG [--json] [--plot FILE.png]`: re-run the monitor's model on a recording.

BAG is a .mcap file or a rosbag2 bag directory (split files `<name>_<n>.mcap`). The monitor's
settings recorded in the bag are used unless given here. A bag that is not MCAP or lacks the
needed topics is bad input (exit 2); a truncated bag is read up to its last intact chunk with a
warning on stderr.
"""

import json
import sys


def add_arguments(parser):
    parser.add_argument('bag', help='a .mcap file or a rosbag2 bag directory')
    parser.add_argument('--json', action='store_true', help='machine-readable output (SI units)')
    parser.add_argument('--plot', metavar='FILE.png',
                        help='plot spacing error and hole width along the row, tilt histogram')
    parser.add_argument('--upright-threshold', type=float, metavar='RAD',
                        help='minimum stem angle to the ground for "upright" (rad; default: '
                             'the recorded setting, else 30 deg)')
    parser.add_argument('--nozzle-width', type=float, metavar='M',
                        help='nozzle width added to the hole (m; default: recorded, else 0)')
    parser.add_argument('--window', type=int, metavar='N',
                        help='plants in the rolling uprightness rate (default: recorded, else 20)')


def run(args):
    from planter_ros.cli.main import BadInput
    from planter_ros.recording.replay import ReplayError, format_table, replay
    try:
        result = replay(args.bag, {'upright_threshold': args.upright_threshold,
                                   'nozzle_width': args.nozzle_width, 'window': args.window})
    except ReplayError as exc:
        raise BadInput(str(exc)) from None
    for warning in result.warnings:
        print(f'planter: warning: {warning}', file=sys.stderr)
    if args.json:
        print(json.dumps(result.as_json(), indent=1, allow_nan=False))
    else:
        print(format_table(result))
    if args.plot:
        from planter_ros.plots.replay import plot_replay
        plot_replay(result, args.plot)
        if not args.json:
            print(f'plot written to {args.plot}')
    return 0
