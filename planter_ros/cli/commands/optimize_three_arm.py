"""`planter optimize three-arm`: run (the options: cli/optimize_three_arm.py)."""

import sys
import tempfile

from planter_ros.cli.commands.design_three_arm import load_params
from planter_ros.cli.main import BadInput
from planter_ros.design.text import three_arm_table
from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.three_arm import ThreeArmMechanism, design_summary
from planter_ros.optimize.three_arm import (
    INSTALL_BOUNDS, RADIUS_BOUNDS, SearchOptions, optimize, parameters_from_vector)
from planter_ros.output_files import atomic_output, require_finite
from planter_ros.scene import default_scene_path, write_scene


def run(args):

    base_path = args.base or default_scene_path('rice_three_arm.yaml')
    base = load_params(base_path, '--base')
    _check_control_angles(base, base_path)
    params, goals, info = optimize(
        base, SearchOptions(seed=args.seed, max_time=args.max_time, workers=args.workers),
        progress=lambda status: print('\r' + status.line(), end='', file=sys.stderr,
                                      flush=True))
    sys.stderr.write('\n')
    try:           # the result must be a design before it may replace anything
        summary = design_summary(params, ThreeArmMechanism.from_parameters(params))
    except DesignError as exc:
        raise BadInput(f'no valid design found in {info["seconds"]:.1f} s ({exc}); '
                       'nothing written') from None
    require_finite(summary, 'optimised design')
    header = (f"written by `planter optimize three-arm --seed {args.seed}`: "
              f"{sum(g.passed for g in goals) if goals else 0}/8 goals, "
              f"{info['generations']} generations, {info['evaluations']} designs, "
              f"{info['seconds']:.1f} s ({info['stopped']})")
    with tempfile.TemporaryDirectory(prefix='planter-optimize-') as scratch:
        out = args.out or f'{scratch}/scene.yaml'       # no --out: the scene goes to stdout
        with atomic_output(out) as tmp:
            write_scene(tmp, params, header)
            load_params(tmp, '--out')        # what is written reads back as a valid scene
        scene = None if args.out else open(out).read()
    summary['params'] = args.out or '(on stdout)'
    report = sys.stdout if args.out else sys.stderr      # stdout: the scene file alone
    print(three_arm_table(summary), file=report)
    print(f"search: {info['seconds']:.1f} s, {info['generations']} generations, "
          f"{info['evaluations']} designs ({info['designs_per_second']:.0f}/s on "
          f"{info['workers']} process{'es' if info['workers'] > 1 else ''}), "
          f"stopped: {info['stopped']}", file=report)
    if scene is not None:
        sys.stdout.write(scene)
    return 0


def _check_control_angles(base, path):
    """The search keeps the base's control angles: refuse them now if no design can use them
    (tried with radii and installation values at the middle of the search domain)."""
    middle = [0.5 * sum(RADIUS_BOUNDS)] * len(base['control_angles']) + \
        [0.5 * (lo + hi) for lo, hi in INSTALL_BOUNDS.values()]
    try:
        ThreeArmMechanism.from_parameters(parameters_from_vector(middle, base))
    except DesignError as exc:
        raise BadInput(f'--base {path}: {exc}') from None
