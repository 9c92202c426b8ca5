"""`planter design five-bar`: agronomic needs (D, d, k) -> bar lengths: table, JSON or plot.

The options are the scene's values (kinematics.scene_settings): same ranges as a scene file and
the design node's parameters."""

import json
import math

from planter_ros.output_files import require_finite
from planter_ros.cli.options import output_file, spec_option
from planter_ros.kinematics.scene_settings import SceneSettings


def add_arguments(parser):
    parser.add_argument('--depth', type=spec_option(SceneSettings, 'planting_depth', '--depth'),
                        required=True, metavar='M', help='planting depth D (m), e.g. 0.045')
    parser.add_argument('--spacing', type=spec_option(SceneSettings, 'plant_spacing',
                                                      '--spacing'),
                        required=True, metavar='M', help='plant spacing d along the row (m), '
                        'e.g. 0.2')
    parser.add_argument('--hole-ratio', type=spec_option(SceneSettings, 'hole_ratio',
                                                         '--hole-ratio'),
                        default=0.05, metavar='K',
                        help='hole entry-exit distance over depth, k = t/D (default 0.05)')
    parser.add_argument('--method', type=spec_option(SceneSettings, 'design_method', '--method'),
                        default='exact', metavar='exact|paper',
                        help="'exact' solves ψ - sin ψ = πkD/d; 'paper' uses the paper's "
                             'cube-root approximation (default exact)')
    parser.add_argument('--speed', type=spec_option(SceneSettings, 'nominal_ground_speed',
                                                    '--speed'),
                        metavar='M/S', help='ground speed v (m/s): adds the sun-bar speed '
                        'ω1 = 2πv/d')
    parser.add_argument('--tolerance', type=float, metavar='M',
                        help='bar length tolerance (m): hole-width range over built machines '
                             'with l1, l2 anywhere within ±M')
    parser.add_argument('--speed-error', type=float, metavar='F',
                        help='ground-speed error as a fraction of the synchronised speed '
                             '(0.01 = 1 %%): hole-width range with the speed anywhere within ±F')
    parser.add_argument('--json', action='store_true', help='print JSON (SI units) for machines')
    parser.add_argument('--plot', metavar='FILE.png', type=output_file('--plot', ('.png',)),
                        help='draw static and soil-frame trajectories, velocity, acceleration')


# a tolerance is a small part of the bar: beyond a tenth of l1 the "tolerance" is another design
TOLERANCE_OF_L1 = 0.1
# a ground-speed reading off by more than this is a broken sensor, not an error to design for
# (wheel slip reaches 10-15 %, radar about 3 %, GNSS velocity about 1 %)
SPEED_ERROR_MAX = 0.2


def _check_tolerances(args, design):
    from planter_ros.cli.main import BadInput
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
    from planter_ros.kinematics.five_bar import (design_five_bar, hole_sensitivity,
                                                 hole_tolerance, sun_bar_speed)
    from planter_ros.output_files import atomic_output
    from planter_ros.plausibility import check_design_query
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
        from planter_ros.plots.five_bar import plot_design
        with atomic_output(args.plot) as tmp:
            plot_design(design, tmp, ground_speed=args.speed)
        result['plot'] = args.plot
    if args.json:
        print(json.dumps(result, indent=2, allow_nan=False))
    else:
        from planter_ros.design.text import five_bar_table
        print(five_bar_table(result))
    return 0
