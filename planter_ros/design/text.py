"""Designs as text for people (lengths in mm, angles in degrees, labelled): the tables
`planter design five-bar`, `planter design three-arm` and `planter optimize three-arm` print
from their JSON-ready results (the keys their --json output has)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:                 # text only: the models are not imported to print a table
    from planter_ros.kinematics.five_bar import HoleTolerance
    from planter_ros.kinematics.three_arm.paper import PaperComparison

__all__ = ['five_bar_table', 'three_arm_table']


def five_bar_table(r: dict[str, Any]) -> str:
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


def _sensitivity_table(r: Mapping[str, Any]) -> list[str]:
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


def _tolerance_table(t: HoleTolerance) -> list[str]:
    mm, nominal = 1000.0, t['nominal']
    p = t['percentiles']

    def pct(v: float) -> str:
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


def _aligned(rows: Sequence[Sequence[str]]) -> list[str]:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return ['  '.join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows]


def _show(value: float | None, unit: str) -> str:
    if value is None:
        return '—'
    if unit == 'rad':
        return f'{math.degrees(value):.2f} deg'
    return f'{value * 1000:.2f} mm'


def three_arm_table(r: dict[str, Any]) -> str:
    """Human table: mm and degrees, labelled."""
    lines = [f"scene {r['params']}: three-arm, {r['interpolant']} pitch curve",
             f"centre distance a      {r['centre_distance'] * 1000:.6f} mm "
             f"(closure residual {r['closure_residual']:.2g}, {r['closure_method']})",
             f"pitch radius range     {r['pitch_radius_range'][0] * 1000:.2f} … "
             f"{r['pitch_radius_range'][1] * 1000:.2f} mm",
             '']
    rows = [('goal', 'value', 'lower', 'upper', 'pass', 'basis')]
    for g in r['goals']:
        rows.append((g['name'], _show(g['value'], g['unit']), _show(g['lower'], g['unit']),
                     _show(g['upper'], g['unit']), 'yes' if g['passed'] else 'NO',
                     g['basis'] + _assumed(g)))
    lines += _columns(rows, right=(1, 2, 3, 4))
    lines.append(f"goals passed           {r['goals_passed']} of {len(r['goals'])}: "
                 f"{r['paper_goals_passed']} of {r['paper_goals']} the paper fixes, "
                 f"{r['assumption_goals_passed']} of {r['assumption_goals']} on assumptions")
    lines.append(f"picking, planting at   θ = {math.degrees(r['picking_phase']):.1f}°, "
                 f"{math.degrees(r['planting_phase']):.1f}° (arm I; "
                 f"{r['phases_from']['picking_phase']}, {r['phases_from']['planting_phase']})")
    if r['zero_slip_spacing'] > 0:
        lines.append(f"zero-slip spacing      {r['zero_slip_spacing'] * 1000:.1f} mm (the plant "
                     f"spacing at which the ground keeps pace with the tip at planting; scene "
                     f"{r['plant_spacing'] * 1000:.0f} mm)")
    else:
        lines.append('zero-slip spacing      none: the tip moves forward in the frame at '
                     'planting, so no forward ground speed keeps pace with it')
    if 'carrier_speed' in r:
        lines.append(f"carrier speed          {r['carrier_speed']:.4f} rad/s at "
                     f"{r['nominal_ground_speed']:.3g} m/s "
                     f"({r['carrier_speed'] * 60 / (2 * math.pi):.2f} r/min)")
    if 'plot' in r:
        lines.append(f"plot                   {r['plot']}")
    if 'paper_comparison' in r:
        lines += ['', *_comparison_table(r['paper_comparison'])]
    return '\n'.join(lines)


def _assumed(g: Mapping[str, Any]) -> str:
    """The assumed values (all lengths) in mm, for the basis column."""
    shown = ', '.join(f'{k} {v * 1000:g} mm' for k, v in g['assumed'].items())
    return f' ({shown})' if shown else ''


def _comparison_table(c: PaperComparison) -> list[str]:
    """Model against the paper's Table 1, per arm, in degrees."""
    def deg(v: float) -> str:
        return f'{math.degrees(v):.1f}'
    rows = [('arm', 'picking θ', 'Table 1', 'Δ', 'planting θ', 'Table 1', 'Δ',
             'picking angle at Table 1 θ', 'pushing angle at Table 1 θ')]
    for a in c['arms']:
        rows.append((a['arm'], deg(a['picking_phase']), deg(a['paper_picking_phase']),
                     f"{math.degrees(a['picking_phase_difference']):+.1f}",
                     deg(a['planting_phase']), deg(a['paper_planting_phase']),
                     f"{math.degrees(a['planting_phase_difference']):+.1f}",
                     deg(a['picking_angle_at_paper_phase']),
                     deg(a['pushing_angle_at_paper_phase'])))
    return ["against the paper's Table 1 (carrier angle θ of each arm, deg; the model picks at "
            'the highest tip point and plants at the lowest)',
            *_columns(rows, right=tuple(range(1, 9)))]


def _columns(rows: Sequence[Sequence[str]], right: tuple[int, ...] = ()) -> list[str]:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return ['  '.join(c.rjust(w) if i in right else c.ljust(w)
                      for i, (c, w) in enumerate(zip(row, widths))).rstrip() for row in rows]
