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
SPEED_ERROR_MAX = 0.5


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
                       f'0..{SPEED_ERROR_MAX:g} (a fraction of the ground speed)')


def run(args):
    from planter_ros.kinematics.five_bar import (design_five_bar, hole_sensitivity,
                                                 hole_tolerance, sun_bar_speed)
    from planter_ros.output_files import atomic_output

    design = design_five_bar(args.depth, args.spacing, args.hole_ratio, args.method)
    _check_tolerances(args, design)
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
    lines = [f'{k:<{width}}  {v}' for k, v in rows]
    lines += ['', *_sensitivity_table(r)]
    if 'tolerance' in r:
        lines += ['', *_tolerance_table(r['tolerance'])]
    return '\n'.join(lines)


# what a person would change each quantity by to see its effect (bar: 0.1 mm, depth: 1 mm,
# speed ratio: 0.01, i.e. 1 % at the synchronised λ = 1)
_STEPS = (('l1', 'l1', 1e-4, '+0.1 mm'), ('l2', 'l2', 1e-4, '+0.1 mm'),
          ('depth', 'depth D', 1e-3, '+1 mm'), ('speed_ratio', 'speed ratio λ', 0.01, '+0.01'))


def _sensitivity_table(r):
    s, hole = r['sensitivity'], r['hole_width']
    rows = [('hole width sensitivity', 'dW/dx', 'change', 'hole moves')]
    for key, label, step, shown in _STEPS:
        unit = 'mm/mm' if key != 'speed_ratio' else 'mm per unit λ'
        scale = 1.0 if key != 'speed_ratio' else 1000.0
        moved = s[key] * step
        rows.append((label, f'{s[key] * scale:+.4g} {unit}', shown,
                     f'{moved * 1000:+.4f} mm ({moved / hole * 100:+.1f} %)'))
    return _aligned(rows) + ['(λ = (l2 − l1)·2π/d: a ground 1 % faster than the sun bar lowers '
                             'λ by about 0.01)']


def _tolerance_table(t):
    mm, nominal = 1000.0, t['nominal']
    p = t['percentiles']

    def pct(v):
        return f'{v * mm:.4f} mm ({(v - nominal) / nominal * 100:+.1f} %)'
    rows = [(f"built machines ({t['samples']:,} samples)",
             f"bars ±{t['bar_tolerance'] * mm:g} mm, speed ±{t['speed_error'] * 100:g} %"),
            ('hole width nominal', f'{nominal * mm:.4f} mm'),
            ('min … max', f"{t['min'] * mm:.4f} … {t['max'] * mm:.4f} mm"),
            ('1 % … 99 %', f"{pct(p['1'])} … {pct(p['99'])}"),
            ('5 % … 95 %', f"{pct(p['5'])} … {pct(p['95'])}"),
            ('median', pct(p['50'])),
            ('mean ± std', f"{t['mean'] * mm:.4f} ± {t['std'] * mm:.4f} mm")]
    return _aligned(rows)


def _aligned(rows):
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return ['  '.join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows]
