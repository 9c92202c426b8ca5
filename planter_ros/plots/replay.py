"""Replay figure: spacing error and hole width (with λ) along the row (one line per row of a
machine), the tilt histogram with the upright limits, and the as-planted map."""

import math

from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
import numpy as np

from planter_ros.output_files import atomic_output

ROW_MARKERS = 'osD^v<>ph*'


def plot_replay(result, path):
    """Four labelled panels (mm and degrees for people) in one PNG."""
    p = result.plants
    s = result.summary
    rows = getattr(result, 'rows', None) or []
    named = len(rows) > 1 or bool(rows and rows[0].name)
    labels = {row.index: row.label for row in rows}
    fig = Figure(figsize=(16, 10))
    grid = fig.add_gridspec(3, 2, width_ratios=(1.25, 1.0))
    axes = [fig.add_subplot(grid[i, 0]) for i in range(3)]

    ax = axes[0]
    ax.axhline(0.0, color='0.4', lw=0.8, label='on d (target)')
    for index in np.unique(p.row):
        mine = (p.row == index) & np.isfinite(p.spacing_error)
        ax.plot(p.position[mine], p.spacing_error[mine] * 1e3, '.-', ms=4, lw=0.8,
                label=labels.get(int(index), f'row {int(index)}') if named else None)
    # the ISO 7256-1 limits, where the errors come near them (else they would flatten the rest)
    half = 0.5 * s['design_spacing'] * 1e3
    worst = float(np.nanmax(np.abs(p.spacing_error))) * 1e3 \
        if np.isfinite(p.spacing_error).any() else 0.0
    if worst > 0.3 * half:
        ax.axhline(half, color='tab:red', ls='--', lw=0.8, label='miss above (x > 1.5 d)')
        ax.axhline(-half, color='tab:purple', ls='--', lw=0.8,
                   label='multiple below (x ≤ 0.5 d)')
    _headroom(ax)
    ax.legend(fontsize='small', ncol=min(len(rows) + 3, 5), loc='upper center')
    ax.set_xlabel('position along the row [m]')
    ax.set_ylabel('spacing error [mm]')
    ax.set_title(f'spacing error: gap to the previous plant − d (d = '
                 f'{s["design_spacing"] * 1e3:.0f} mm), plants at the recorded ground speed')
    ax.grid(alpha=0.3)

    ax = axes[1]
    twin = ax.twinx()
    handles = []
    for k, index in enumerate(np.unique(p.row)):
        mine = p.row == index
        first = k == 0
        handles += ax.plot(p.position[mine], p.hole_width[mine] * 1e3, '.-', ms=4, lw=0.8,
                           color='tab:brown', label='hole width' if first else None)
        handles += ax.plot(p.position[mine], p.tip_sweep[mine] * 1e3, ':', lw=0.8,
                           color='tab:brown', label='tip sweep' if first else None)
        handles += twin.plot(p.position[mine], p.speed_ratio[mine], color='tab:green', lw=0.6,
                             alpha=0.7, label='speed ratio λ (right axis)' if first else None)
    design_hole = _design_hole(result)
    if design_hole is not None:
        handles.append(ax.axhline(design_hole * 1e3, color='tab:brown', ls='--', lw=0.8,
                                  label='design hole (k·D + nozzle)'))
    ax.set_xlabel('position along the row [m]')
    ax.set_ylabel('hole width, tip sweep [mm]')
    ax.set_title(f'hole at depth: tip sweep + nozzle width {_nozzle_mm(result)}; speed ratio '
                 'λ (1 = in sync)')
    ax.grid(alpha=0.3)
    twin.set_ylabel('speed ratio λ (1 = in sync)', color='tab:green')
    twin.axhline(1.0, color='tab:green', lw=0.5, ls=':')
    _headroom(ax, bottom=0.0)
    _headroom(twin)
    labelled = [h for h in handles if not str(h.get_label()).startswith('_')]
    if labelled:
        ax.legend(labelled, [str(h.get_label()) for h in labelled], fontsize='small',
                  loc='upper center', ncol=len(labelled))

    ax = axes[2]
    tilt = np.degrees(p.tilt)
    unknown = int(np.count_nonzero(~np.isfinite(tilt)))      # an input gap's, say
    tilt = tilt[np.isfinite(tilt)]
    limit = 90.0 - math.degrees(result.settings.upright_threshold)
    # the axis always shows the upright limits, however narrow the tilts are
    span = 1.1 * max(float(np.abs(tilt).max()) if tilt.size else 0.0, limit, 1.0)
    if tilt.size:
        # bins over the tilts found, each at least 1/100 of the axis wide (else unseen)
        lo, hi = float(tilt.min()), float(tilt.max())
        width = max((hi - lo) / 30.0, span / 50.0)
        count = max(int(math.ceil((hi - lo) / width)), 1)
        mid = 0.5 * (lo + hi)
        edges = np.linspace(mid - 0.5 * count * width, mid + 0.5 * count * width, count + 1)
        ax.hist(tilt, bins=edges.tolist(), color='tab:blue', alpha=0.8)
    ax.set_xlim(-span, span)
    for sign in (-1, 1):
        ax.axvline(sign * limit, color='tab:red', ls='--', lw=1)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel('predicted tilt from vertical [deg] (+ = leaning forward; red: upright limit '
                  f'±{limit:.0f} deg)')
    ax.set_ylabel('plants')
    rate = s['uprightness_rate']
    ax.set_title(f'tilt: {s["plants"]} plants, '
                 f'{"n/a" if rate is None else f"{100 * rate:.1f} %"} upright'
                 + (f', {unknown} of unknown tilt (not drawn)' if unknown else '')
                 + (' (not validated for this mechanism)' if _tilt_note(result) else ''))
    ax.grid(alpha=0.3)

    _map_panel(fig, fig.add_subplot(grid[:, 1]), result, labels, named)
    fig.suptitle(f'replay of {result.path}')
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def write_plot(result, path):
    """plot_replay into the PNG `path` (atomically): the line for people."""
    with atomic_output(path) as tmp:
        plot_replay(result, tmp)
    return f'plot written to {path}'


def _map_panel(fig, ax, result, labels, named):
    """Plants on the map's local frame (east, north from the first usable fix), a marker per
    row, coloured by spacing error."""
    p = result.plants
    placement = getattr(result, 'placement', None)
    east = placement.east if placement is not None else np.full(len(p), np.nan)
    north = placement.north if placement is not None else np.full(len(p), np.nan)
    ok = np.isfinite(east) & np.isfinite(north)
    ax.set_title('as-planted map (colour: spacing error)')
    if placement is None or not ok.any():
        ax.text(0.5, 0.5, 'no GNSS fixes in the bag:\nno plant has a map position',
                ha='center', va='center', transform=ax.transAxes)
        ax.set_axis_off()
        return
    err = p.spacing_error * 1e3
    scale = max(float(np.nanmax(np.abs(err[ok]))) if np.isfinite(err[ok]).any() else 1.0, 1.0)
    mappable = None
    for k, index in enumerate(np.unique(p.row[ok])):
        mine = ok & (p.row == index)
        ax.plot(east[mine], north[mine], '-', color='0.8', lw=0.6, zorder=1)
        known = mine & np.isfinite(err)
        mappable = ax.scatter(east[known], north[known], c=err[known], cmap='coolwarm',
                              vmin=-scale, vmax=scale, s=18, zorder=2,
                              marker=ROW_MARKERS[k % len(ROW_MARKERS)],
                              label=labels.get(int(index), f'row {int(index)}')
                              if named else 'plants')
        ax.scatter(east[mine & ~np.isfinite(err)], north[mine & ~np.isfinite(err)],
                   facecolors='none', edgecolors='0.3', s=18, zorder=2,
                   marker=ROW_MARKERS[k % len(ROW_MARKERS)])
    fig.colorbar(mappable, ax=ax, label='spacing error [mm] (hollow: no spacing)',
                 shrink=0.8)
    ax.legend(fontsize='small', loc='best')
    ax.set_aspect('equal', adjustable='datalim')
    origin = placement.origin
    ax.set_xlabel(f'east [m] from {origin[0]:.6f}°, {origin[1]:.6f}°')
    ax.set_ylabel('north [m]')
    ax.grid(alpha=0.3)


def _headroom(ax, bottom=None, share=0.3):
    """Room above the data for a legend drawn at the top (no line under it)."""
    lo, hi = ax.get_ylim()
    lo = lo if bottom is None else bottom
    ax.set_ylim(lo, hi + share * (hi - lo) / (1.0 - share))


def _design_hole(result):
    """The hole the design asks for (m): k·D plus the nozzle's width; None if unknown."""
    design = getattr(result, 'design', None)
    k = getattr(design, 'hole_ratio', None)
    if k is None or design is None:
        return None
    return k * design.planting_depth + (getattr(result, 'nozzle_width', None) or 0.0)


def _nozzle_mm(result):
    width = getattr(result, 'nozzle_width', None)
    return 'n/a' if width is None else f'{width * 1e3:.1f} mm'


def _tilt_note(result):
    return any('tilt' in note['fields'] and 'validated' in note['text']
               for note in (getattr(result, 'notes', None) or []))
