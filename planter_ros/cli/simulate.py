"""`planter simulate PATH --bags N`: a season of realistic bags to analyse, fast, without DDS.

Each run is drawn from the seed and its number (varied speeds, stops, sensor glitches, a stall
now and then, a curve, GNSS), simulated in closed loop (the sync law against the drive model)
and written as PATH/run_<seed>_<n>.mcap in the exact layout the monitor records, its plants
from the monitor's model (planter_ros.sim.season). The runs are simulated in parallel on the
same Dask engine as `planter analyze` (a local cluster, or --scheduler).
"""

import json
import sys

from planter_ros.cli.options import add_engine_arguments, spec_option
from planter_ros.sim.season import SeasonOptions


def add_arguments(parser):
    parser.add_argument('path', metavar='PATH',
                        help='directory for the bags (made if missing; its parent must exist)')
    parser.add_argument('--bags', metavar='N', required=True,
                        type=spec_option(SeasonOptions, 'bags', '--bags'),
                        help='runs to simulate, 1..100000')
    parser.add_argument('--duration', metavar='S', default=60.0,
                        type=spec_option(SeasonOptions, 'duration', '--duration'),
                        help='length of each run in seconds, 10..3600 (default 60)')
    parser.add_argument('--rows', metavar='R', default=None,
                        type=spec_option(SeasonOptions, 'rows', '--rows'),
                        help='planting rows of the machine, 1..16 (default 4; 1 = a machine '
                             'without rows); not with --scene')
    parser.add_argument('--scene', metavar='FILE',
                        help="simulate the scene's machine: its design (five-bar or three-arm), "
                             'rows, monitor settings, acceptance limits and antenna, cruising '
                             'around its nominal ground speed (default: a tomato five-bar)')
    parser.add_argument('--seed', metavar='K', default=0,
                        type=spec_option(SeasonOptions, 'seed', '--seed'),
                        help='seed of the season, 0..2^32-1 (default 0): the same seed gives '
                             'the same bags')
    add_engine_arguments(parser)
    parser.add_argument('--json', action='store_true',
                        help='print every bag written and what happens in it as JSON (SI)')


def run(args):
    from planter_ros.analysis.simulate import check_path, simulate_season
    from planter_ros.sim.season import bag_name

    from planter_ros.analysis.engine import EngineError
    from planter_ros.cli.main import BadInput
    scene, rows = None, 4 if args.rows is None else args.rows
    if args.scene:
        if args.rows is not None:
            raise BadInput(f'--rows = {args.rows} with --scene: allowed one of them (the '
                           "scene's rows are its machine's)")
        from pathlib import Path

        from planter_ros.sim.season import scene_machine
        rows = len(scene_machine(args.scene).rows)        # a bad scene: one line, exit 2
        scene = str(Path(args.scene).resolve())
    names = [bag_name(args.seed, k) for k in range(args.bags)]
    path = check_path(args.path, names)
    try:
        report, written, errors = simulate_season(path, names, args.seed, args.duration,
                                                  rows, args.workers, args.scheduler, scene)
    except EngineError as exc:
        raise BadInput(str(exc)) from None
    if args.json:
        print(json.dumps({**report, 'runs': written}, indent=1, allow_nan=False))
    else:
        print(f'{len(written)} bags written to {path} ({rows} rows, {args.duration:g} s '
              f'each, seed {args.seed}): {report["messages"]} messages, {report["plants"]} '
              f'plants, {report["bytes"] / 1e6:.1f} MB')
        print(f'{report["seconds"]:.1f} s on {report["workers"]} worker(s): '
              f'{report["times_real_time"]:.0f}× real time')
    for name, error in errors:
        print(f'planter: error: {name} not written: {type(error).__name__}: {error}',
              file=sys.stderr)
    return 1 if errors else 0
