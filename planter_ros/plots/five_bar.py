"""The four views of the paper's design platform in one labelled PNG."""

import math

import numpy as np

from planter_ros.kinematics.five_bar import (
    dyad_positions, soil_acceleration, soil_trajectory, soil_velocity, static_trajectory,
    sun_bar_speed)


def plot_design(design, path, ground_speed=None):
    """Static and soil-frame trajectories, velocity and acceleration of the nozzle tip C.

    Without a ground speed the time axes use the paper's field test rate, 60 r/min.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    mm = 1000.0
    if ground_speed is None:
        omega = 2.0 * math.pi
        ground_speed = design.spacing * omega / (2.0 * math.pi)
        speed_note = f'ω1 = 60 r/min ⇒ v = {ground_speed:.3g} m/s'
    else:
        omega = sun_bar_speed(ground_speed, design.spacing)
        speed_note = f'v = {ground_speed:.3g} m/s ⇒ ω1 = {omega:.3g} rad/s'
    theta = np.linspace(0.0, 2.0 * math.pi, 721)
    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    fig.suptitle(f'Geared five-bar, {design.method} design: D = {design.depth * mm:.1f} mm, '
                 f'd = {design.spacing * mm:.1f} mm, k = {design.hole_ratio:.3g}; '
                 f'l1 = {design.l1 * mm:.2f} mm, l2 = {design.l2 * mm:.2f} mm; {speed_note}')

    ax = axes[0, 0]
    x, y = static_trajectory(design.l1, design.l2, theta)
    ax.plot(x * mm, y * mm, label='nozzle tip C')
    if design.assemblable:
        dx, dy, _ = dyad_positions(design, theta)
        ax.plot(dx * mm, dy * mm, '--', label='dyad joint D')
    ax.plot([0, -design.l5 * mm], [0, 0], 'ko-', label='frame A–E')
    ax.set(title='static trajectory (frame of A)', xlabel='x (mm)', ylabel='y (mm)')
    ax.set_aspect('equal')
    ax.legend(loc='best', fontsize=8)

    ax = axes[0, 1]
    t3 = np.linspace(0.0, 3 * 2.0 * math.pi, 2161)
    sx, sy = soil_trajectory(design.l1, design.l2, t3, design.advance)
    ax.plot(sx * mm, sy * mm, label='tip C, in sync (λ = 1)')
    ax.axhline(design.depth * mm, color='saddlebrown', label='soil surface (y = D)')
    ax.axhline(0.0, color='gray', ls=':', label='hole bottom')
    ax.set(title='soil-frame trajectory, three plants', xlabel='x along the row (mm)',
           ylabel='height above hole bottom (mm)')
    ax.legend(loc='upper right', fontsize=8)

    time = theta / omega
    vx, vy = soil_velocity(design.l1, design.l2, theta, omega, ground_speed)
    ax = axes[1, 0]
    ax.plot(time, vx, label='v_x')
    ax.plot(time, vy, label='v_y')
    ax.axvline(math.pi / omega, color='gray', ls=':', label='bottom (planting)')
    ax.set(title='velocity, one sun-bar turn', xlabel='time (s)', ylabel='m/s')
    ax.legend(fontsize=8)

    ax_, ay = soil_acceleration(design.l1, design.l2, theta, omega)
    ax = axes[1, 1]
    ax.plot(time, ax_, label='a_x')
    ax.plot(time, ay, label='a_y')
    ax.set(title='acceleration, one sun-bar turn', xlabel='time (s)', ylabel='m/s²')
    ax.legend(fontsize=8)
    for a in axes.flat:
        a.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
