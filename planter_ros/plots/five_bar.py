"""The four views of the paper's design platform in one labelled PNG."""

import math

from matplotlib.figure import Figure
import numpy as np

from planter_ros.kinematics.five_bar import (
    dyad_positions, soil_acceleration, soil_trajectory, soil_velocity, static_trajectory,
    sun_bar_speed)


def plot_design(design, path, ground_speed=None):
    """Static and soil-frame trajectories, velocity and acceleration of the nozzle tip C.

    Without a ground speed the time axes use the paper's field test rate, 60 r/min.
    """

    mm = 1000.0
    if ground_speed is None:
        omega = 2.0 * math.pi
        ground_speed = design.spacing * omega / (2.0 * math.pi)
        speed_note = f'ω1 = 60 r/min ⇒ v = {ground_speed:.3g} m/s'
    else:
        omega = float(sun_bar_speed(ground_speed, design.spacing))
        speed_note = f'v = {ground_speed:.3g} m/s ⇒ ω1 = {omega:.3g} rad/s'
    theta = np.linspace(0.0, 2.0 * math.pi, 721)
    fig = Figure(figsize=(15, 9))
    grid = fig.add_gridspec(2, 6)
    top = [fig.add_subplot(grid[0, 2 * i:2 * i + 2]) for i in range(3)]
    bottom = [fig.add_subplot(grid[1, 3 * i:3 * i + 3]) for i in range(2)]
    fig.suptitle(f'Geared five-bar, {design.method} design: D = {design.depth * mm:.1f} mm, '
                 f'd = {design.spacing * mm:.1f} mm, k = {design.hole_ratio:.3g}; '
                 f'l1 = {design.l1 * mm:.2f} mm, l2 = {design.l2 * mm:.2f} mm; {speed_note}')

    ax = top[0]
    x, y = static_trajectory(design.l1, design.l2, theta)
    ax.plot(x * mm, y * mm, label='nozzle tip C')
    if design.assemblable:
        dx, dy, _ = dyad_positions(design, theta)
        ax.plot(dx * mm, dy * mm, '--', label='dyad joint D')
    ax.plot([0, -design.l5 * mm], [0, 0], 'ko-', label='frame A–E')
    ax.set(title='static trajectory (frame of A, sun-bar pivot at 0)', xlabel='x (mm)',
           ylabel='y (mm)')
    ax.set_aspect('equal')
    ax.legend(loc='best', fontsize=8)

    ax = top[1]
    t3 = np.linspace(0.0, 3 * 2.0 * math.pi, 2161)
    sx, sy = soil_trajectory(design.l1, design.l2, t3, design.advance)
    ax.plot(sx * mm, sy * mm, label='tip C, in sync (λ = 1)')
    ax.axhline(design.depth * mm, color='saddlebrown', label='soil surface (y = D)')
    ax.axhline(0.0, color='gray', ls=':', label='hole bottom')
    ax.set(title='soil-frame trajectory, three plants', xlabel='x along the row (mm)',
           ylabel='height above hole bottom (mm)')
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, hi + 0.3 * (hi - lo))            # room for the legend above the loops
    ax.legend(loc='upper center', fontsize=8, ncol=2)

    _hole_panel(top[2], design, mm)

    time = theta / omega
    vx, vy = soil_velocity(design.l1, design.l2, theta, omega, ground_speed)
    ax = bottom[0]
    ax.plot(time, vx, label='v_x (along the row)')
    ax.plot(time, vy, label='v_y (up)')
    ax.axvline(math.pi / omega, color='gray', ls=':', label='bottom (planting)')
    ax.axhline(0.0, color='0.5', lw=0.6)
    ax.set(title='tip C velocity in the soil frame, one sun-bar turn (v_x = 0 at the bottom: '
           'zero-speed planting)', xlabel='time (s)', ylabel='velocity (m/s)')
    ax.legend(fontsize=8)

    ax_, ay = soil_acceleration(design.l1, design.l2, theta, omega)
    ax = bottom[1]
    ax.plot(time, ax_, label='a_x (along the row)')
    ax.plot(time, ay, label='a_y (up)')
    ax.axvline(math.pi / omega, color='gray', ls=':', label='bottom (planting)')
    ax.set(title='tip C acceleration, one sun-bar turn', xlabel='time (s)',
           ylabel='acceleration (m/s²)')
    ax.legend(fontsize=8)
    for a in top + bottom:
        a.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def _hole_panel(ax, design, mm):
    """The first plant's hole, zoomed: the tip below the soil and the hole it cuts (entry to
    exit at the surface) against the hole the design asks for, k·D."""
    theta = np.linspace(0.5 * math.pi, 1.5 * math.pi, 4001)     # around the bottom (θ = π)
    sx, sy = map(np.asarray, soil_trajectory(design.l1, design.l2, theta, design.advance))
    below = sy <= design.depth
    x0 = float(np.interp(math.pi, theta, sx))
    target = design.hole_ratio * design.depth
    achieved = design.hole_width if design.hole_width is not None else (
        float(sx[below].max() - sx[below].min()) if below.any() else 0.0)
    half = max(achieved, target, 1e-3) * 2.2         # room beside the tip for the legend
    ax.plot((sx - x0) * mm, sy * mm, label='tip C (λ = 1)')
    ax.axhline(design.depth * mm, color='saddlebrown', label='soil surface (y = D)')
    ax.axhline(0.0, color='gray', ls=':')
    y_mark = design.depth * mm * 1.08
    ax.errorbar([0.0], [y_mark], xerr=[[0.5 * target * mm], [0.5 * target * mm]], fmt='none',
                ecolor='tab:red', capsize=5, label=f'design hole k·D = {target * mm:.3g} mm')
    if below.any():
        ax.plot([(sx[below].min() - x0) * mm, (sx[below].max() - x0) * mm],
                [design.depth * mm] * 2, color='tab:blue', lw=4, alpha=0.5,
                label=f'hole cut = {achieved * mm:.3g} mm')
    ax.set_xlim(-half * mm, half * mm)
    ax.set_ylim(-0.05 * design.depth * mm, 1.35 * design.depth * mm)
    ax.set(title='the hole, zoomed: cut against the design (k·D)',
           xlabel='x from the planting point (mm)', ylabel='height above hole bottom (mm)')
    ax.legend(loc='lower right', fontsize=8)
