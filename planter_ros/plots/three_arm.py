"""Three-arm design figure: pitch curves, relative and absolute trajectories, arm angles."""

import math

from matplotlib.figure import Figure
import numpy as np

from planter_ros.kinematics.three_arm.gear_train import ARMS
from planter_ros.kinematics.three_arm.goals import goal_settings, goal_values, goals_from_values

COLOURS = ('tab:blue', 'tab:orange', 'tab:green')
ARM_NAMES = ('I', 'II', 'III')


def plot_design(mech, params, path):
    """Write a 2×2 PNG: gears at θ = 0, carrier-frame and frame trajectories, arm angles."""

    mm = 1000.0
    cfg = goal_settings(params)
    values = goal_values(mech, cfg)
    goals = {g.name: g for g in goals_from_values(values, cfg)}
    theta = np.linspace(0.0, 2.0 * math.pi, 721)
    fig = Figure(figsize=(13, 11))
    axes = fig.subplots(2, 2)

    # (a) the three gear kinds in mesh at θ = 0 (arm I's intermediate and planet)
    ax = axes[0, 0]
    u = np.linspace(0.0, 2.0 * math.pi, 721)
    rho = mech.train.curve(u)
    phi0, a = mech.phi0, mech.a
    ax.plot(rho * np.cos(phi0 - u) * mm, rho * np.sin(phi0 - u) * mm, 'k', label='sun (fixed)')
    (o2x, o2y), (o3x, o3y) = mech.centres(0.0)
    d_int = phi0 + math.pi + mech.train.psi(u)
    ax.plot((o2x + (a - rho) * np.cos(d_int)) * mm, (o2y + (a - rho) * np.sin(d_int)) * mm,
            'tab:red', label='intermediate (a − ρ)')
    phi3 = mech.attitude(0.0) + mech.beta0
    ax.plot((o3x + rho * np.cos(phi3 - u)) * mm, (o3y + rho * np.sin(phi3 - u)) * mm,
            'tab:purple', label='planet (= sun curve)')
    for (cx, cy), name in (((0.0, 0.0), 'O1'), ((o2x, o2y), 'O2'), ((o3x, o3y), 'O3')):
        ax.plot(cx * mm, cy * mm, 'k+')
        ax.annotate(name, (cx * mm, cy * mm), textcoords='offset points', xytext=(4, 4))
    ax.set_title(f'Pitch curves in mesh at θ = 0 (a = {a * mm:.3f} mm)\n'
                 f'gear module {_goal_text(goals["gear_module"], mm, "mm")}')
    _finish(ax, 'x (mm)', 'y (mm)', equal=True)

    # (b) relative trajectories (carrier frame)
    ax = axes[0, 1]
    for k in range(ARMS):
        x, y = mech.tip_relative(theta, k)
        ax.plot(x * mm, y * mm, color=COLOURS[k], label=f'arm {ARM_NAMES[k]}')
    ax.plot(0, 0, 'k+')
    ax.set_title('Tip relative to the carrier (carrier frame, θ = 0 orientation)')
    _finish(ax, 'x (mm)', 'y (mm)', equal=True)

    # (c) absolute trajectories in the frame with attitudes at picking and pushing
    ax = axes[1, 0]
    marks = {'picking': float(values['picking_phase']),
             'planting': float(values['planting_phase'])}
    for k in range(ARMS):
        x, y = mech.tip(theta, k)
        ax.plot(x * mm, y * mm, color=COLOURS[k], lw=3.0 - k, alpha=0.8,
                label=f'arm {ARM_NAMES[k]}')
    ground = float(mech.tip(marks['planting'])[1]) + cfg['planting_depth']
    ax.axhline(ground * mm, color='saddlebrown', lw=1, label='ground')
    for label, th in marks.items():
        (_, _), (cx, cy) = mech.centres(th)
        tx, ty = mech.tip(th)
        pa = mech.pusher_attitude(th)
        length = mech.arm_length * math.cos(mech.delta)
        ax.plot([cx * mm, tx * mm], [cy * mm, ty * mm], 'k-', lw=2)
        ax.plot([(tx - length * math.cos(pa)) * mm, tx * mm],
                [(ty - length * math.sin(pa)) * mm, ty * mm], 'r--', lw=1.5)
        name = 'picking_angle' if label == 'picking' else 'pushing_angle'
        ax.annotate(f'{label} at θ = {math.degrees(th):.1f}°: pusher\n'
                    f'{_goal_text(goals[name], 180.0 / math.pi, "°")} below horizontal',
                    (tx * mm, ty * mm), textcoords='offset points',
                    xytext=(-170, 25) if label == 'picking' else (-150, 110), fontsize=8,
                    bbox=dict(boxstyle='round', fc='white', ec='0.7', alpha=0.9),
                    arrowprops=dict(arrowstyle='->', color='0.4'))
    ax.plot([], [], 'k-', lw=2, label='arm O3→tip')
    ax.plot([], [], 'r--', label='pusher axis')
    ax.plot(0, 0, 'k+')
    ax.set_title(f'Tip in the frame (static machine)\ntrajectory height '
                 f'{_goal_text(goals["trajectory_height"], mm, "mm")}')
    _finish(ax, 'x forward (mm)', 'y up (mm)', equal=True)

    # (d) arm angle against carrier angle
    ax = axes[1, 1]
    deg = np.degrees(theta)
    for k in range(ARMS):
        alpha = np.degrees(np.unwrap(mech.attitude(theta, k)))
        alpha -= 360.0 * round(alpha[0] / 360.0)
        ax.plot(deg, alpha, color=COLOURS[k], label=f'arm {ARM_NAMES[k]} absolute')
    ax.plot(deg, np.degrees(mech.planet_relative_angle(theta, 0)), 'k:',
            label='arm I relative to carrier')
    for label, th in marks.items():
        ax.axvline(math.degrees(th), color='grey', lw=0.8)
        ax.annotate(label, (math.degrees(th), ax.get_ylim()[1]), fontsize=8, rotation=90,
                    va='top', ha='right', bbox=dict(fc='white', ec='none', alpha=0.8))
    ax.set_xlim(0, 360)
    ax.set_xticks(range(0, 361, 60))
    ax.set_title('Arm angle (O3→tip) against carrier angle θ')
    _finish(ax, 'carrier angle θ (deg)', 'angle (deg)')

    passed = sum(g.passed for g in goals.values())
    failing = [name for name, g in goals.items() if not g.passed]
    fig.suptitle(f'Three-arm non-circular planetary mechanism — {passed}/{len(goals)} goals pass'
                 + (f' (not met: {", ".join(failing)})' if failing else ''), fontsize=13)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def _finish(ax, xlabel, ylabel, equal=False):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    if equal:
        ax.set_aspect('equal', adjustable='datalim')
    ax.legend(fontsize=8, loc='best', framealpha=0.9)


def _goal_text(goal, scale, unit):
    """'7.0° (goal −5…15°: met)': a goal's value next to its range, in the figure's units."""
    value = f'{goal.value * scale:.1f}{unit}' if unit == '°' else \
        f'{goal.value * scale:.2f} {unit}'
    lo = None if goal.lower is None else f'{goal.lower * scale:g}'
    hi = None if goal.upper is None else f'{goal.upper * scale:g}'
    space = '' if unit == '°' else ' '
    wanted = (f'{lo}…{hi}{space}{unit}' if lo is not None and hi is not None else
              f'≥ {lo}{space}{unit}' if lo is not None else f'≤ {hi}{space}{unit}')
    return f'{value} (goal {wanted}: {"met" if goal.passed else "NOT met"})'
