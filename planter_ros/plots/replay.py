"""Replay figure: spacing error and hole width along the row (one line per row of a machine),
and the tilt histogram."""

import math

import numpy as np


def plot_replay(result, path):
    """Three labelled panels (mm and degrees for people) in one PNG."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    p = result.plants
    s = result.summary
    rows = getattr(result, 'rows', None) or []
    named = len(rows) > 1 or bool(rows and rows[0].name)
    labels = {row.index: row.label for row in rows}
    fig, axes = plt.subplots(3, 1, figsize=(10, 10))
    ax = axes[0]
    ax.axhline(0.0, color='0.6', lw=0.8)
    for index in np.unique(p.row):
        mine = (p.row == index) & np.isfinite(p.spacing_error)
        ax.plot(p.position[mine], p.spacing_error[mine] * 1e3, '.-', ms=4, lw=0.8,
                label=labels.get(int(index), f'row {int(index)}') if named else None)
    if named:
        ax.legend(fontsize='small', ncol=min(len(rows), 4))
    ax.set_xlabel('position along the row [m]')
    ax.set_ylabel('spacing error [mm]')
    ax.set_title(f'spacing error (design spacing {s["design_spacing"] * 1e3:.0f} mm)')
    ax.grid(alpha=0.3)

    ax = axes[1]
    for index in np.unique(p.row):
        mine = p.row == index
        ax.plot(p.position[mine], p.hole_width[mine] * 1e3, '.-', ms=4, lw=0.8,
                color=None if named else 'tab:brown')
    ax.set_xlabel('position along the row [m]')
    ax.set_ylabel('hole width [mm]')
    ax.set_title(f'hole width at depth (nozzle width {result.settings.nozzle_width * 1e3:.1f} mm '
                 'included)')
    ax.grid(alpha=0.3)
    twin = ax.twinx()
    for index in np.unique(p.row):
        mine = p.row == index
        twin.plot(p.position[mine], p.speed_ratio[mine], color='tab:green', lw=0.6, alpha=0.7)
    twin.set_ylabel('speed ratio λ', color='tab:green')

    ax = axes[2]
    tilt = np.degrees(p.tilt)
    limit = 90.0 - math.degrees(result.settings.upright_threshold)
    span = max(np.abs(tilt).max() * 1.1, 2.0) if tilt.size else 2.0
    if limit < 2.0 * span:
        span = max(span, 1.1 * limit)
    if tilt.size:
        ax.hist(tilt, bins=np.linspace(-span, span, 41), color='tab:blue', alpha=0.8)
    ax.set_xlim(-span, span)
    if limit <= span:
        for sign in (-1, 1):
            ax.axvline(sign * limit, color='tab:red', ls='--', lw=1)
    ax.set_xlabel('predicted tilt from vertical [deg] (+ = leaning forward; red: upright limit '
                  f'±{limit:.0f} deg)')
    ax.set_ylabel('plants')
    rate = s['uprightness_rate']
    ax.set_title(f'tilt: {s["plants"]} plants, '
                 f'{"n/a" if rate is None else f"{100 * rate:.1f} %"} upright')
    ax.grid(alpha=0.3)
    fig.suptitle(f'replay of {result.path}')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
