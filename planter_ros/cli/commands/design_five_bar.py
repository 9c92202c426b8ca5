"""`planter design five-bar`: run (the options: cli/design_five_bar.py)."""

import json
import math

from planter_ros.cli.main import BadInput
from planter_ros.design.text import five_bar_table
from planter_ros.kinematics.five_bar import (design_five_bar, hole_sensitivity, hole_tolerance,
                                             sun_bar_speed)
from planter_ros.output_files import atomic_output, require_finite
from planter_ros.plausibility import check_design_query

# a tolerance is a small part of the bar: beyond a tenth of l1 the "tolerance" is another design
TOLERANCE_OF_L1 = 0.1
# a ground-speed reading off by more than this is a broken sensor, not an error to design for
# (wheel slip reaches 10-15 %, radar about 3 %, GNSS velocity about 1 %)
SPEED_ERROR_MAX = 0.2


def _check_tolerances(args, design):
    limit = TOLERANCE_OF_L1 * design.l1
    if args.tolerance is not None and not (math.isfinite(args.tolerance)
                                           and 0.0 <= args.tolerance <= limit):
        raise BadInput(f'--tolerance = {args.tolerance} is out of range: allowed 0..{limit:.6g} '
                       f'm (a tenth of l1 = {design.l1:.6g} m)')
    if args.speed_error is not None and not (math.isfinite(args.speed_error)
                                             and 0.0 <= args.speed_error <= SPEED_ERROR_MAX):
        raise BadInput(f'--speed-error = {args.speed_error} is out of range: allowed '
                       f'0..{SPEED_ERROR_MAX:g} (a fraction of the ground speed; wheel slip '
                       'reaches 0.15)')


def run(args):
    design = design_five_bar(args.depth, args.spacing, args.hole_ratio, args.method)
    _check_tolerances(args, design)
    check_design_query('planter', args.depth, args.spacing, args.hole_ratio, args.speed)
    result = design.as_dict()
    result['hole_width_error'] = ((design.hole_width - design.requested_hole)
                                  / design.requested_hole)
    result['sensitivity'] = hole_sensitivity(design.l1, design.l2, design.depth,
                                             design.advance).as_dict()
    if args.tolerance is not None or args.speed_error is not None:
        result['tolerance'] = hole_tolerance(design, args.tolerance or 0.0,
                                             args.speed_error or 0.0)
    if args.speed is not None:
        result['ground_speed'] = args.speed
        result['sun_bar_speed'] = sun_bar_speed(args.speed, args.spacing)
    require_finite(result, 'five-bar design')
    if args.plot:
        # lazy: the plot's module only with --plot: a five-bar design loads no matplotlib
        # (an extra: dependencies; test_skip_what_a_scene_does_not_need)
        from planter_ros.plots.five_bar import plot_design
        with atomic_output(args.plot) as tmp:
            plot_design(design, tmp, ground_speed=args.speed)
        result['plot'] = args.plot
    if args.json:
        print(json.dumps(result, indent=2, allow_nan=False))
    else:
        print(five_bar_table(result))
    return 0
