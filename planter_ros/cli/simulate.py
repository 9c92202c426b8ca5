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
    parser.add_argument('--rows', metavar='R', default=4,
                        type=spec_option(SeasonOptions, 'rows', '--rows'),
                        help='planting rows of the machine, 1..16 (default 4; 1 = a machine '
                             'without rows)')
    parser.add_argument('--seed', metavar='K', default=0,
                        type=spec_option(SeasonOptions, 'seed', '--seed'),
                        help='seed of the season, 0..2^32-1 (default 0): the same seed gives '
                             'the same bags')
    add_engine_arguments(parser)
    parser.add_argument('--json', action='store_true',
                        help='print every bag written and what happens in it as JSON (SI)')


def check_path(path, names):
    """Refuse (OutputError) a PATH the bags cannot be written to: not a directory, not
    writable, a parent missing, or one of the bags already there (never overwritten)."""
    from pathlib import Path

    from planter_ros.output_files import OutputError, check_directory
    path = Path(path)
    if path.exists() or path.is_symlink():
        if not path.is_dir():
            raise OutputError(f'PATH = {path} exists and is not a directory: allowed a '
                              'directory for the bags')
        check_directory(path, 'PATH')
        taken = [name for name in names if (path / name).exists()]
        if taken:
            raise OutputError(f'PATH = {path} already holds {taken[0]}'
                              f'{f" and {len(taken) - 1} more" if len(taken) > 1 else ""}: '
                              'allowed another PATH or --seed (a recording is never '
                              'overwritten)')
    else:
        check_directory(path.parent if str(path.parent) else Path('.'), 'PATH', path)
    return path


def run(args):
    import time

    from planter_ros.analysis.engine import EngineError, check_workers, cluster, completed
    from planter_ros.analysis.progress import Progress
    from planter_ros.analysis.task import model_version, warm_up
    from planter_ros.cli.main import BadInput
    from planter_ros.sim.season import bag_name, simulate_bag

    names = [bag_name(args.seed, k) for k in range(args.bags)]
    path = check_path(args.path, names)
    version = model_version()
    where = args.scheduler or 'the local cluster'
    written, errors = [], []
    try:
        with cluster(args.workers, args.scheduler) as client:
            workers = check_workers(client, warm_up, version, where)
            path.mkdir(exist_ok=True)
            progress = Progress(args.bags, what='bags', label='planter simulate')
            started = time.monotonic()
            try:
                arguments = [(str(path.resolve() / name), args.seed, k, args.duration,
                              args.rows) for k, name in enumerate(names)]
                for i, result, error in completed(client, simulate_bag, arguments):
                    if error is None:
                        written.append(result)
                    else:
                        errors.append((names[i], error))
                    progress.update(len(written) + len(errors),
                                    sum(r['duration'] for r in written), len(errors))
            finally:
                progress.close()
            seconds = time.monotonic() - started
    except EngineError as exc:
        raise BadInput(str(exc)) from None
    written.sort(key=lambda r: r['run'])
    run_seconds = sum(r['duration'] for r in written)
    size = sum((path / bag_name(args.seed, r['run'])).stat().st_size for r in written)
    report = {'path': str(path), 'bags': len(written), 'failed': len(errors),
              'seed': args.seed, 'duration': args.duration, 'rows': args.rows,
              'workers': workers, 'seconds': seconds, 'bag_seconds': run_seconds,
              'times_real_time': run_seconds / seconds if seconds > 0 else None,
              'bytes': size, 'messages': sum(r['messages'] for r in written),
              'plants': sum(r['plants'] for r in written)}
    if args.json:
        print(json.dumps({**report, 'runs': written}, indent=1, allow_nan=False))
    else:
        print(f'{len(written)} bags written to {path} ({args.rows} rows, {args.duration:g} s '
              f'each, seed {args.seed}): {report["messages"]} messages, {report["plants"]} '
              f'plants, {size / 1e6:.1f} MB')
        print(f'{seconds:.1f} s on {workers} worker(s): {report["times_real_time"]:.0f}× real '
              'time')
    for name, error in errors:
        print(f'planter: error: {name} not written: {type(error).__name__}: {error}',
              file=sys.stderr)
    return 1 if errors else 0
