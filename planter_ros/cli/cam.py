"""`planter cam five-bar`: one mechanism, several spacings and ground speeds, constant sun-bar
speed beside the electronic cam (planter_ros.cam): sweep, hole, tilt and the drive's loads
against its limits; a table, JSON or a plot.

Depth, spacings, speeds, hole ratio and nozzle width take the scene's ranges; the drive options
are the fields of `cam.DriveLimits` with their own ranges."""

import json
import math

from planter_ros.cli.options import output_file, require_finite, shown, spec_option
from planter_ros.kinematics.scene_settings import SceneSettings

MAX_SPACINGS = 20
MAX_SPEEDS = 10
RULE_WORDS = {'design-speed': 'design_speed', 'zero-slip': 'zero_slip'}


def list_option(cls, name, option, most):
    """argparse `type=` for a comma-separated list of `option` values, each checked like
    spec_option; at most `most` values, no repeats (kept in the order given)."""
    one = spec_option(cls, name, option)

    def parse(text):
        from planter_ros.cli.main import BadInput
        parts = text.split(',')
        if not 1 <= len(parts) <= most:
            raise BadInput(f'{option} = {shown(text)} has {len(parts)} values: allowed 1..{most} '
                           'comma-separated values')
        values = [one(p.strip()) for p in parts]
        return list(dict.fromkeys(values))
    parse.__name__ = name
    return parse


def _rule(text):
    from planter_ros.cli.main import BadInput
    if text not in RULE_WORDS:
        raise BadInput(f'--rule = {shown(text)} is not a rule: allowed '
                       f'{" or ".join(RULE_WORDS)}')
    return RULE_WORDS[text]


def add_arguments(parser):
    from planter_ros.cam.drive import DriveLimits
    from planter_ros.config import specs

    parser.add_argument('--depth', type=spec_option(SceneSettings, 'planting_depth', '--depth'),
                        required=True, metavar='M', help='planting depth D (m), e.g. 0.045')
    parser.add_argument('--design-spacing', required=True, metavar='M',
                        type=spec_option(SceneSettings, 'plant_spacing', '--design-spacing'),
                        help='the spacing the mechanism is designed for (m): its bars come from '
                             'the five-bar reverse design at D, this spacing and the hole ratio')
    parser.add_argument('--spacing', required=True, metavar='M[,M…]',
                        type=list_option(SceneSettings, 'plant_spacing', '--spacing',
                                         MAX_SPACINGS),
                        help=f'the spacings to plant (m), up to {MAX_SPACINGS}, e.g. 0.15,0.3,0.5')
    parser.add_argument('--speed', required=True, metavar='M/S[,…]',
                        type=list_option(SceneSettings, 'nominal_ground_speed', '--speed',
                                         MAX_SPEEDS),
                        help=f'top ground speeds (m/s), up to {MAX_SPEEDS}: the cam is planned '
                             'for each as the top speed')
    parser.add_argument('--hole-ratio', type=spec_option(SceneSettings, 'hole_ratio',
                                                         '--hole-ratio'),
                        default=0.05, metavar='K',
                        help='the design hole over depth, k = t/D (default 0.05)')
    parser.add_argument('--nozzle-width', type=spec_option(SceneSettings, 'nozzle_width',
                                                           '--nozzle-width'),
                        default=0.0, metavar='M',
                        help="the nozzle's width along the row (m), added to the tip's sweep "
                             'for the hole (default 0: the hole is the sweep)')
    parser.add_argument('--rule', type=_rule, default='design-speed',
                        metavar='design-speed|zero-slip',
                        help='the cam in the soil: design-speed (the mechanism\'s own '
                             'zero-speed ratio: the design hole, no tilt) or zero-slip (a '
                             'point hole, far larger loads); default design-speed')
    limits = parser.add_argument_group('drive and limits (default: a 750 W servo, 20:1 '
                                       'planetary gearbox; doc/cam.md)')
    for spec in specs(DriveLimits):
        option = '--' + spec.name.replace('_', '-')
        limits.add_argument(option, dest=f'drive_{spec.name}',
                            metavar=spec.unit.upper().replace(' ', '·') or 'X',
                            type=spec_option(DriveLimits, spec.name, option),
                            help=f'{spec.describe()} (default {spec.default:.6g})'
                            .replace('%', '%%'))
    parser.add_argument('--json', action='store_true', help='print JSON (SI units) for machines')
    parser.add_argument('--plot', metavar='FILE.png', type=output_file('--plot', ('.png',)),
                        help='draw θ(s) and the tip in the soil for both profiles, sweep and '
                             'tilt against spacing, the feasibility map and the loads')


def run(args):
    from planter_ros.cam import CamMechanism, DRIVE_SOURCE, DriveLimits
    from planter_ros.cam.plan import rule_top_speeds
    from planter_ros.cam.study import compare
    from planter_ros.kinematics.five_bar import design_five_bar
    from planter_ros.output_files import atomic_output

    design = design_five_bar(args.depth, args.design_spacing, args.hole_ratio)
    mech = CamMechanism.from_design(design, args.nozzle_width)
    drive = DriveLimits(**{k[len('drive_'):]: v for k, v in vars(args).items()
                           if k.startswith('drive_') and v is not None})
    top = max(args.speed)
    import scipy.interpolate  # noqa: F401  (loaded before the plans are timed)
    import scipy.optimize  # noqa: F401
    cases = [compare(mech, d, v, drive, args.rule) for d in args.spacing for v in args.speed]
    tops = []
    for d in args.spacing:
        found = rule_top_speeds(mech, d, drive, top)
        tops.append({'spacing': d, **{k: {'ground_speed': v, 'limit': why}
                                      for k, (v, why) in found.items()}})
    result = {
        'mechanism': {'l1': mech.l1, 'l2': mech.l2, 'depth': mech.depth,
                      'design_spacing': args.design_spacing, 'hole_ratio': args.hole_ratio,
                      'nozzle_width': mech.nozzle_width, 'design_hole': mech.design_hole,
                      'design_hole_width': mech.design_hole + mech.nozzle_width},
        'rule': args.rule,
        'drive': {spec: getattr(drive, spec) for spec in drive.__dataclass_fields__},
        'limits': drive.effective(mech).as_dict(),
        'drive_source': DRIVE_SOURCE,
        'cases': cases,
        'top_speeds': tops,
    }
    require_finite(result, 'cam')
    if args.plot:
        from planter_ros.plots.cam import plot_cam
        with atomic_output(args.plot) as tmp:
            plot_cam(mech, drive, args.rule, args.spacing, args.speed, cases, tops, tmp)
        result['plot'] = args.plot
    if args.json:
        print(json.dumps(result, indent=2, allow_nan=False))
    else:
        print(format_table(result))
    return 0


def _pct(u):
    return f'{u * 100:.0f} %'


def format_table(r):
    """Human table: mm, degrees, the loads' units labelled."""
    mm, m = 1000.0, r['mechanism']
    lim = r['limits']
    lines = [f"five-bar for D = {m['depth'] * mm:.1f} mm, d = {m['design_spacing'] * mm:.1f} mm, "
             f"k = {m['hole_ratio']:.4g}: l1 = {m['l1'] * mm:.3f} mm, l2 = {m['l2'] * mm:.3f} "
             f"mm; design hole {m['design_hole'] * mm:.4f} mm + nozzle "
             f"{m['nozzle_width'] * mm:.1f} mm",
             f"limits: sun bar ≤ {lim['sun_bar_speed']:.4g} rad/s, "
             + (f"≤ {lim['sun_bar_acceleration']:.4g} rad/s², "
                if lim['sun_bar_acceleration'] else '')
             + f"≤ {lim['sun_bar_jerk']:.4g} rad/s³; motor ≤ {lim['motor_peak_torque']:.4g} N·m "
             f"peak, ≤ {lim['motor_rms_torque']:.4g} N·m RMS",
             f"drive: {r['drive_source']}",
             f"cam rule: {r['rule'].replace('_', '-')}; each cam planned for its speed as the "
             'top speed', '']
    head = ('spacing', 'speed', 'profile', 'sweep', 'hole', 'tilt', 'ω peak', 'α peak',
            'jerk peak', 'T peak', 'T rms', 'within', 'binds', 'plan', 'sweep check')
    units = ('mm', 'm/s', '', 'mm', 'mm', 'deg', 'rad/s', 'rad/s²', 'rad/s³', 'N·m', 'N·m',
             'limits', '', 'time', 'error (m)')
    rows = [head, units]
    for case in r['cases']:
        for key in ('constant', 'cam'):
            p = case[key]
            loads = p['loads']
            if key == 'constant':
                name = 'constant speed'
            elif p['blended_with']:
                name = f"cam: β {p['blend']:.3f} of {p['blend_of']}, rest {p['blended_with']}"
            else:
                name = f"cam: {p['blend_of']}"
            util = loads['utilisation']
            binds = p.get('binding', loads['binding'])
            check = p.get('sweep_check')
            rows.append((f"{case['spacing'] * mm:.0f}" if key == 'constant' else '',
                         f"{case['ground_speed']:.3g}" if key == 'constant' else '', name,
                         f"{p['tip_sweep'] * mm:.4f}", f"{p['hole_width'] * mm:.4f}",
                         f"{round(math.degrees(p['tilt']), 2) + 0.0:+.2f}",
                         f"{loads['peak_sun_bar_speed']:.3g}",
                         f"{loads['peak_sun_bar_acceleration']:.4g}",
                         f"{loads['peak_sun_bar_jerk']:.4g}",
                         f"{loads['peak_motor_torque']:.3g}", f"{loads['rms_motor_torque']:.3g}",
                         'yes' if p['feasible'] else 'NO',
                         f"{binds} {_pct(util[binds])}" if binds in util else binds,
                         f"{p['plan_time'] * 1000:.0f} ms" if 'plan_time' in p else '',
                         f"{check['error']:.1e}" if check else ''))
    widths = [max(len(row[i]) for row in rows) for i in range(len(head))]
    lines += ['  '.join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows]
    lines += ['', 'sweep check: |closed-form sweep − brute force|, the tip path sampled at '
              f"{r['cases'][0]['cam']['sweep_check']['samples_per_revolution']:,} points per "
              'revolution; plan: time to plan the cam (the fallback search included)', '',
              'up to what ground speed each holds (planned for that speed), and what stops it:']
    for t in r['top_speeds']:
        parts = [f"{label} {t[key]['ground_speed']:.3g} m/s ({t[key]['limit']})"
                 for key, label in (('zero_slip', 'exact zero slip'),
                                    ('design_speed', 'design-speed rule'),
                                    ('constant', 'constant speed'))]
        lines.append(f"  d = {t['spacing'] * mm:.0f} mm: " + '; '.join(parts))
    if 'plot' in r:
        lines += ['', f"plot: {r['plot']}"]
    return '\n'.join(lines)
