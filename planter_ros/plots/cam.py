"""The electronic cam in one PNG: the sun-bar angle θ(s) over a plant and the tip in the soil for
constant speed and the cam; tip sweep and tilt against spacing with the region where the cam's
rule exceeds a limit shaded; the feasibility map (up to what ground speed each law holds); the
cam's loads against the limits."""

import math

from matplotlib.figure import Figure
import numpy as np

from planter_ros.cam.errors import CamInputError
from planter_ros.cam.mechanism import constant_law
from planter_ros.cam.plan import constant_profile, plan_cam, rule_top_speeds

GRID = 9                 # spacings planned between the smallest and the largest asked


def _grid(mech, spacings):
    lo, hi = min(spacings), max(spacings)
    if hi - lo < 1e-9:
        lo, hi = max(0.05, 0.7 * lo), min(2.0, 1.4 * hi)
    lo = max(lo, 1.05 * 2.0 * mech.a * mech.psi)         # the design-speed rule's soil arc
    return sorted(set(np.linspace(lo, hi, GRID).tolist()) | set(spacings))


def plot_cam(asked, cases, tops, path):
    """Six labelled panels (mm and degrees for people) for the command's inputs (`asked`, a
    cam.report.CamStudy) and results; `cases` and `tops` as in `planter cam --json`."""
    mech, drive, rule = asked.mech, asked.drive, asked.rule
    spacings, speeds = list(asked.spacings), list(asked.speeds)


    mm = 1000.0
    top = max(speeds)
    grid = _grid(mech, spacings)
    plans = [plan_cam(mech, d, top, drive, rule, top_speeds=False) for d in grid]
    known = {t['spacing']: t for t in tops}
    grid_tops = [known.get(d) or {k: {'ground_speed': v, 'limit': why} for k, (v, why) in
                                  rule_top_speeds(mech, d, drive, top).items()} for d in grid]
    rule_name = rule.replace('_', '-')

    fig = Figure(figsize=(19, 11))
    axes = fig.subplots(2, 3)
    fig.suptitle(f'Electronic cam on a geared five-bar designed for d = '
                 f'{mech.design_spacing * mm:.0f} mm (D = {mech.depth * mm:.0f} mm, '
                 f'l1 = {mech.l1 * mm:.1f} mm, l2 = {mech.l2 * mm:.1f} mm): constant sun-bar '
                 f'speed against the {rule_name} cam, top ground speed {top:.3g} m/s')

    # (a) θ(s) over one plant at the largest spacing: constant speed and both cam rules
    d_show = max(spacings)
    const = constant_profile(mech, d_show, drive)
    shown = [(const, 'constant speed')]
    for name in ('design_speed', 'zero_slip'):
        try:
            plan = plan_cam(mech, d_show, top, drive, name, top_speeds=False)
        except CamInputError:                    # zero slip undefined at this depth
            continue
        shown.append((plan.profile, f'cam: {plan.profile.law.name}'))
    s = np.linspace(-0.5 * d_show, 0.5 * d_show, 1201)
    ax = axes[0, 0]
    twin = ax.twinx()
    for i, (profile, label) in enumerate(shown):
        ax.plot(s * mm, np.degrees(profile.values(s)), color=f'C{i}', label=label)
        twin.plot(s * mm, profile.values(s, 1), color=f'C{i}', ls=':', lw=1)
    half = max(p.entry for p, _ in shown[1:]) if len(shown) > 1 else const.entry
    ax.axvspan(-half * mm, half * mm, color='saddlebrown', alpha=0.15, label='the cams\' tip '
               'in the soil')
    ax.set(title=f'sun-bar angle θ(s) over one plant, d = {d_show * mm:.0f} mm, '
                 f'{top:.3g} m/s\n(θ = 180° at the planting instant; dotted: θ′(s), right axis)',
           xlabel='travelled distance s from the planting instant (mm)', ylabel='θ (deg)')
    ax.legend(loc='upper left', fontsize=8)
    twin.set_ylabel('θ′(s) (rad/m)')

    # (b) the tip in the soil frame around the hole, the same profiles
    ax = axes[0, 1]
    reach = 1.6 * max(p.entry for p, _ in shown)
    near = np.linspace(-reach, reach, 4001)
    x0, _ = mech.tip(np.array([math.pi]), np.array([0.0]))
    for i, (profile, label) in enumerate(shown):
        x, y = mech.tip(profile.values(near), near)
        inside = y <= mech.depth
        ax.plot((x - x0) * mm, y * mm, color=f'C{i}', lw=0.7, alpha=0.5)
        ax.plot(np.where(inside, (x - x0) * mm, np.nan), np.where(inside, y * mm, np.nan),
                color=f'C{i}', lw=2.2, label=f'{label}: sweep {profile.tip_sweep * mm:.2f} mm, '
                                              f'tilt {math.degrees(profile.tilt):+.1f}°')
    ax.axhline(mech.depth * mm, color='saddlebrown', label='soil surface (y = D)')
    ax.set(title=f'tip in the soil frame, d = {d_show * mm:.0f} mm (bold: in the soil)',
           xlabel='x along the row from the planting point (mm)',
           ylabel='height above the hole bottom (mm)', ylim=(-5, 4.2 * mech.depth * mm))
    ax.legend(loc='upper center', fontsize=8)

    # (c), (d) sweep and tilt against spacing, infeasible region shaded
    dense = np.linspace(min(grid), max(grid), 200)
    c_sweep = [constant_law(d).tip_sweep(mech) for d in dense]
    c_tilt = [constant_law(d).tilt(mech) for d in dense]
    exceeded = [not p.rule_runs for p in plans]
    for ax, values, c_values, label, unit in (
            (axes[0, 2], [p.profile.tip_sweep * mm for p in plans],
             np.array(c_sweep) * mm, 'tip sweep', 'mm'),
            (axes[1, 0], [math.degrees(p.profile.tilt) for p in plans],
             np.degrees(c_tilt), 'tilt from vertical (+ forward)', 'deg')):
        ax.plot(dense * mm, c_values, label='constant speed')
        ax.plot(np.array(grid) * mm, values, 'o-', label=f'cam ({rule_name} rule, fallback '
                'where it exceeds a limit)')
        if unit == 'mm':
            ax.axhline(mech.design_hole * mm, color='0.5', ls='--', label='design hole')
        else:
            ax.axhline(1.0, color='0.5', ls='--', label='±1°')
            ax.axhline(-1.0, color='0.5', ls='--')
        for d, bad in zip(grid, exceeded):
            if bad:
                step = (max(grid) - min(grid)) / (2 * (GRID - 1))
                ax.axvspan((d - step) * mm, (d + step) * mm, color='red', alpha=0.12, lw=0)
        ax.plot([], [], 's', color='red', alpha=0.3, label=f'the {rule_name} rule exceeds a '
                f'limit at {top:.3g} m/s')
        ax.set(title=f'{label} against spacing, top speed {top:.3g} m/s',
               xlabel='plant spacing d (mm)', ylabel=f'{label} ({unit})')
        ax.legend(loc='upper left', fontsize=8)

    # (e) the feasibility map
    ax = axes[1, 1]
    labels = (('zero_slip', 'exact zero slip'), ('design_speed', 'design-speed rule'),
              ('constant', 'constant speed'))
    x = np.array(grid) * mm
    for key, label in labels:
        ax.plot(x, [t[key]['ground_speed'] for t in grid_tops], 'o-', label=f'{label} holds '
                'below')
    rule_top = np.array([t[rule]['ground_speed'] for t in grid_tops])
    ceiling = max(max(speeds), float(np.max([t[k]['ground_speed'] for t in grid_tops
                                              for k, _ in labels[:2]]))) * 1.3
    ax.fill_between(x, rule_top, ceiling, color='red', alpha=0.12,
                    label=f'{rule_name} rule exceeds a limit')
    for k, v in enumerate(speeds):
        ax.axhline(v, color='0.3', ls=':', lw=1,
                   label='top speed(s) asked' if k == 0 else None)
    ax.set(title='feasibility map: top ground speed of each law within the limits',
           xlabel='plant spacing d (mm)', ylabel='ground speed (m/s)', ylim=(0, ceiling))
    ax.legend(loc='upper right', fontsize=8)

    # (f) the cam's loads against the limits
    ax = axes[1, 2]
    for name in ('speed', 'acceleration', 'jerk', 'torque', 'rms torque'):
        u = [p.figures.utilisation.get(name) for p in plans]
        if all(v is not None for v in u):
            ax.plot(x, np.array(u) * 100, 'o-', label=name)
    ax.axhline(100.0, color='red', label='limit (100 %)')
    ax.set_ylim(0, 135)                          # the legend above the limit line
    lim = drive.effective(mech)
    ax.set(title=f'cam loads at {top:.3g} m/s against the limits\n(ω ≤ {lim.speed:.3g} rad/s, '
                 f'jerk ≤ {lim.jerk:.3g} rad/s³, T ≤ {lim.torque:.3g} N·m peak, '
                 f'{lim.rms_torque:.3g} N·m RMS)',
           xlabel='plant spacing d (mm)', ylabel='peak over limit (%)')
    ax.legend(loc='upper center', fontsize=8, ncol=3)

    for case in cases:
        if case['ground_speed'] == top:
            axes[0, 2].plot(case['spacing'] * mm, case['cam']['tip_sweep'] * mm, 'k+')
    for ax in axes.ravel():
        ax.title.set_fontsize(10)
    fig.tight_layout()
    fig.savefig(path, dpi=110, format='png')
