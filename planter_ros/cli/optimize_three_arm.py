"""`planter optimize three-arm`: search a three-arm design meeting all eight goals."""

import math
import os
import sys

DEFAULT_WORKERS = 2
MAX_WORKERS = 64


def add_arguments(parser):
    parser.add_argument('--seed', type=int, default=1, help='random seed (same seed, same '
                        'result; default 1)')
    parser.add_argument('--max-time', type=float, default=60.0, metavar='S',
                        help='stop after S seconds (default 60)')
    parser.add_argument('--workers', type=int, default=DEFAULT_WORKERS, metavar='N',
                        help='processes scoring each generation (same result for any N; '
                             f'default {DEFAULT_WORKERS})')
    parser.add_argument('--base', metavar='FILE', default=None,
                        help='scene whose crop values and control angles are kept (default '
                             'config/rice_three_arm.yaml)')
    parser.add_argument('--out', metavar='FILE', default='three_arm_optimized.yaml',
                        help='parameter file to write (default three_arm_optimized.yaml)')


def _progress(elapsed, generation, best, passing, max_time):
    width = 30
    done = min(1.0, elapsed / max_time) if max_time > 0 else 1.0
    bar = '#' * int(done * width) + '-' * (width - int(done * width))
    sys.stderr.write(f'\r[{bar}] {elapsed:5.1f}s gen {generation:4d}  best so far: score '
                     f'{best:9.4f}, goals passing {passing}/8')
    sys.stderr.flush()


def run(args):
    from pathlib import Path

    from planter_ros.cli.design_three_arm import format_table, load_params
    from planter_ros.cli.main import BadInput
    from planter_ros.kinematics.three_arm import ThreeArmMechanism, design_summary
    from planter_ros.optimize.three_arm import optimize
    from planter_ros.scene_writer import write_scene

    if not (math.isfinite(args.max_time) and args.max_time > 0):
        raise BadInput(f'--max-time = {args.max_time} is out of range: allowed finite and > 0 s')
    if not 1 <= args.workers <= MAX_WORKERS:
        raise BadInput(f'--workers = {args.workers} is out of range: allowed 1..{MAX_WORKERS} '
                       f'(this machine has {os.cpu_count()} cores)')
    base_path = args.base or Path(__file__).resolve().parents[2] / 'config' / \
        'rice_three_arm.yaml'
    base = load_params(base_path)
    params, goals, info = optimize(base, seed=args.seed, max_time=args.max_time,
                                   progress=_progress, workers=args.workers)
    sys.stderr.write('\n')
    header = (f"written by `planter optimize three-arm --seed {args.seed}`: "
              f"{sum(g.passed for g in goals) if goals else 0}/8 goals, "
              f"{info['generations']} generations, {info['evaluations']} designs, "
              f"{info['seconds']:.1f} s ({info['stopped']})")
    write_scene(args.out, params, header)
    summary = design_summary(params, ThreeArmMechanism.from_parameters(params))
    summary['params'] = args.out
    print(format_table(summary))
    print(f"search: {info['seconds']:.1f} s, {info['generations']} generations, "
          f"{info['evaluations']} designs ({info['designs_per_second']:.0f}/s on "
          f"{info['workers']} process{'es' if info['workers'] > 1 else ''}), "
          f"stopped: {info['stopped']}")
    return 0
