"""`planter cam`'s study as data and as a table for people: one mechanism at several spacings
and top ground speeds, constant sun-bar speed beside the cam, and up to what ground speed each
in-soil rule holds. Pure: no ROS, no matplotlib."""

from collections.abc import Mapping
from dataclasses import dataclass
import math
from typing import Any

# loaded here, before the plans are timed (the arc planner imports them when first used)
import scipy.interpolate  # noqa: F401
import scipy.optimize  # noqa: F401

from .drive import DRIVE_SOURCE, DriveLimits
from .mechanism import CamMechanism
from .plan import CamSpec, rule_top_speeds
from .study import compare

__all__ = ['CamStudy', 'format_table', 'study']


@dataclass(frozen=True)
class CamStudy:
    """What `planter cam` studies: a mechanism (a five-bar designed for `design_spacing`, m,
    with hole ratio `hole_ratio`), its drive, the rule, and the plant spacings (m) and top
    ground speeds (m/s) to compare at."""

    mech: CamMechanism
    drive: DriveLimits
    rule: str
    spacings: tuple[float, ...]
    speeds: tuple[float, ...]
    design_spacing: float
    hole_ratio: float


def study(asked: CamStudy) -> dict[str, Any]:
    """The study (SI units): the mechanism, the limits, per spacing and speed the constant-speed
    and cam figures, and per spacing the top ground speed of each rule with its binding limit."""
    mech, drive, rule, spacings = asked.mech, asked.drive, asked.rule, asked.spacings
    top = max(asked.speeds)
    cases = [compare(CamSpec(mech, d, v, drive, rule)) for d in spacings for v in asked.speeds]
    tops = []
    for d in spacings:
        found = rule_top_speeds(mech, d, drive, top)
        tops.append({'spacing': d, **{k: {'ground_speed': v, 'limit': why}
                                      for k, (v, why) in found.items()}})
    result = {
        'mechanism': {'l1': mech.l1, 'l2': mech.l2, 'depth': mech.depth,
                      'design_spacing': asked.design_spacing,
                      'hole_ratio': asked.hole_ratio,
                      'nozzle_width': mech.nozzle_width, 'design_hole': mech.design_hole,
                      'design_hole_width': mech.design_hole + mech.nozzle_width},
        'rule': rule,
        'drive': {spec: getattr(drive, spec) for spec in drive.__dataclass_fields__},
        'limits': drive.effective(mech).as_dict(),
        'drive_source': DRIVE_SOURCE,
        'cases': cases,
        'top_speeds': tops,
    }
    return result


def _pct(u: float) -> str:
    return f'{u * 100:.0f} %'


def format_table(r: Mapping[str, Any]) -> str:
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
