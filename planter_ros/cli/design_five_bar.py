"""`planter design five-bar`: agronomic needs (D, d, k) -> bar lengths: table, JSON or plot.

The options are the scene's values (kinematics.scene_settings): same ranges as a scene file and
the design node's parameters."""

import json
import math

from planter_ros.cli.options import output_file, require_finite, spec_option
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
    parser.add_argument('--json', action='store_true', help='print JSON (SI units) for machines')
    parser.add_argument('--plot', metavar='FILE.png', type=output_file('--plot', ('.png',)),
                        help='draw static and soil-frame trajectories, velocity, acceleration')


def run(args):
    from planter_ros.kinematics.five_bar import design_five_bar, sun_bar_speed
    from planter_ros.output_files import atomic_output

    design = design_five_bar(args.depth, args.spacing, args.hole_ratio, args.method)
    result = design.as_dict()
    result['hole_width_error'] = ((design.hole_width - design.requested_hole)
                                  / design.requested_hole)
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
        print(format_table(result))
    return 0


def format_table(r):
    """Human table: lengths in mm, angles in degrees, units labelled."""
    mm = 1000.0
    rows = [
        ('method', r['method']),
        ('planting depth D', f"{r['depth'] * mm:.2f} mm"),
        ('plant spacing d', f"{r['spacing'] * mm:.2f} mm"),
        ('hole ratio k', f"{r['hole_ratio']:.4g}"),
        ('l1 sun bar AB', f"{r['l1'] * mm:.3f} mm"),
        ('l2 planet bar BC', f"{r['l2'] * mm:.3f} mm"),
        ('l3 CD', f"{r['l3'] * mm:.3f} mm"),
        ('l4 DE', f"{r['l4'] * mm:.3f} mm"),
        ('l5 AE (frame)', f"{r['l5'] * mm:.3f} mm"),
        ('hole asked k·D', f"{r['requested_hole'] * mm:.4f} mm"),
        ('hole achieved', f"{r['hole_width'] * mm:.4f} mm ({r['hole_width_error'] * 100:+.3f} %)"),
        ('dyad assembles', 'yes' if r['assemblable'] else 'NO'),
        ('min transmission angle', f"{math.degrees(r['min_transmission_angle']):.2f} deg"),
    ]
    if 'sun_bar_speed' in r:
        rows.append(('ground speed v', f"{r['ground_speed']:.4g} m/s"))
        rows.append(('sun-bar speed ω1', f"{r['sun_bar_speed']:.4f} rad/s "
                     f"({r['sun_bar_speed'] * 60 / (2 * math.pi):.2f} r/min)"))
    if 'plot' in r:
        rows.append(('plot', r['plot']))
    width = max(len(k) for k, _ in rows)
    return '\n'.join(f'{k:<{width}}  {v}' for k, v in rows)
