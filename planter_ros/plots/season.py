"""The season report: one self-contained HTML page (report.html next to the Parquet tables of
`planter analyze`): the per field, day and row table with its verdicts, maps of the planting
instants (empty cups, doubles, spacing misses and multiples, input gaps) and of the tilt,
spacing histograms per row and the trends over the season. Every figure is a matplotlib PNG
embedded as base64: the page needs no other file and no network. The figures come from
analysis.report."""

import base64
from contextlib import contextmanager
import html
import io
import math
import os
from pathlib import Path
import sys
import tempfile

import numpy as np

from planter_ros.analysis import season as seasons
from planter_ros.analysis.report import (
    COLUMNS, _cell, format_season_table, read_season, season_groups)
from planter_ros.export.season import season_exports
from planter_ros.geo import LocalFrame
from planter_ros.output_files import write_text_atomically
from planter_ros.prediction.quality import MISS_LIMIT, MULTIPLE_LIMIT

__all__ = ['season_report', 'write_season_report']

REPORT_FILE = 'report.html'
MAX_MAPS = 8                    # recordings drawn as maps


def season_report(out, force=True):
    """Read the tables under `out`, write report.html there (atomically) when `force` (the
    tables changed), it is missing or older than a table: (the table for people, the report's
    path). The report is drawn from the tables alone, so unchanged tables keep it (its figures
    are most of a re-run's time: 1-2 s of matplotlib)."""
    plants, bags = read_season(out)
    groups = season_groups(plants, bags)
    path = Path(out) / REPORT_FILE
    if force or not seasons.written_after_the_tables(path, out):
        with _matplotlib_home():
            write_season_report(path, groups, plants, bags)
    return format_season_table(groups), path


def season_outputs(out, force):
    """The season's exports (export.season) and its report under `out`, each written when
    `force` (bags were analysed: the tables changed) or missing or older than a table (a run
    stopped before it: season.written_after_the_tables), each on its own and recorded
    as the command's (season.record_written):
    (exports or None, the table for people, the report's path or None, [(path, reason)] of
    each output not written)."""
    exports = season_exports(out, force)
    seasons.record_written(out, seasons.EXPORTS)
    failed = [(item['file'], item['reason']) for item in (exports or {}).get('failed', [])]
    try:
        table, path = season_report(out, force)
    except Exception as exc:                 # the tables and exports are written
        text = str(exc).strip().splitlines()
        failed.append((str(Path(out) / REPORT_FILE),
                       f'{type(exc).__name__}{": " + text[0] if text else ""}'))
        return exports, '', None, failed
    seasons.record_written(out, (seasons.REPORT_FILE,))
    return exports, table, path, failed


@contextmanager
def _matplotlib_home():
    """`planter analyze` writes nothing it was not asked to: matplotlib's font cache goes to
    a temporary folder, removed afterwards, unless the user has one (MPLCONFIGDIR set, or a
    matplotlib cache or config folder in the home directory) or matplotlib is loaded already."""
    home = Path.home()
    if ('matplotlib' in sys.modules or os.environ.get('MPLCONFIGDIR')
            or (home / '.cache' / 'matplotlib').is_dir()
            or (home / '.config' / 'matplotlib').is_dir()):
        yield
        return
    with tempfile.TemporaryDirectory(prefix='planter-mpl-') as scratch:
        os.environ['MPLCONFIGDIR'] = scratch
        try:
            yield
        finally:
            os.environ.pop('MPLCONFIGDIR', None)


DPI = 90                        # pixels per inch of the figures
PAD = 0.1                       # inches of white around what a figure draws


def _png(fig):
    """The figure as an <img> of a PNG cropped to what it draws and PAD around it: what
    savefig(bbox_inches='tight') gives, drawn once (tight draws it twice: to find the box, then
    the picture). A figure drawn up to its edge (something reaches beyond it, which tight would
    enlarge the canvas for) is saved with tight."""
    # lazy: loaded in _matplotlib_home (its font cache)
    import matplotlib.image
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_rgba
    fig.set_dpi(DPI)
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    background = np.round(np.array(to_rgba(fig.get_facecolor())) * 255).astype(np.uint8)
    ink = (rgba != background).any(axis=2)
    rows, cols = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    buffer = io.BytesIO()
    if rows.size and 0 < rows[0] and rows[-1] < ink.shape[0] - 1 and \
            0 < cols[0] and cols[-1] < ink.shape[1] - 1:
        pad = round(PAD * DPI)
        crop = rgba[max(rows[0] - pad, 0):rows[-1] + pad + 1,
                    max(cols[0] - pad, 0):cols[-1] + pad + 1]
        matplotlib.image.imsave(buffer, np.ascontiguousarray(crop), format='png', dpi=DPI)
    else:
        fig.savefig(buffer, format='png', dpi=DPI, bbox_inches='tight', pad_inches=PAD)
    plt.close(fig)
    return ('<img alt="figure" src="data:image/png;base64,'
            + base64.b64encode(buffer.getvalue()).decode('ascii') + '">')


def _margins(fig, left, right, bottom, top, between=None):
    """Place the panels of `fig` with margins in inches (left, right, bottom, top; `between`:
    (width, height) between two panels), as the text around them needs: tick labels, axis
    labels and titles have a size in points, whatever the figure's."""
    width, height = fig.get_size_inches()
    grid = fig.axes[0].get_subplotspec().get_gridspec()
    lines, cols = grid.get_geometry()
    space = {}
    if between is not None:
        w = (width - left - right - (cols - 1) * between[0]) / cols
        h = (height - bottom - top - (lines - 1) * between[1]) / lines
        space = dict(wspace=between[0] / w, hspace=between[1] / h)
    fig.subplots_adjust(left=left / width, right=1 - right / width, bottom=bottom / height,
                        top=1 - top / height, **space)


def _pct(value):
    return 'n/a' if value is None else f'{100 * value:.1f} %'


def _kinematic(plants):
    """Ratio x/d of each plant's spacing (NaN without one)."""
    d = plants['spacing_m'] - plants['spacing_error_m']
    return (plants['spacing_m'] / d).to_numpy(dtype=float)


def _miss_or_multiple(ratio):
    """Spacings (over the design spacing) counted as a miss or a multiple by the ISO 7256-1
    indices (prediction.quality): > MISS_LIMIT, or <= MULTIPLE_LIMIT; NaN is neither."""
    return (ratio > MISS_LIMIT) | (ratio <= MULTIPLE_LIMIT)


def _maps(plants):
    """Two panels per recording (misses, multiples and gaps; tilt), the MAX_MAPS recordings
    with the most of them first: a recording is one place, a field's bags may be far apart."""
    import matplotlib.pyplot as plt  # lazy: loaded in _matplotlib_home (its font cache)
    placed = plants[np.isfinite(plants['latitude_deg'].to_numpy(dtype=float))]
    if placed.empty:
        return '<p>No plant has a map position (no usable GNSS fix in the bags).</p>'
    trouble = placed.assign(bad=(placed['status'].isin(('empty', 'double'))
                                 | placed['input_gap'].astype(bool)
                                 | _miss_or_multiple(_kinematic(placed))))
    ranked = trouble.groupby('bag')['bad'].sum().sort_values(ascending=False, kind='stable')
    out = [f'<p>{min(len(ranked), MAX_MAPS)} of {len(ranked)} recordings, those with the most '
           'misses, multiples and gaps first.</p>']
    for bag in ranked.index[:MAX_MAPS]:
        mine = placed[placed['bag'] == bag]
        frame = LocalFrame(float(mine['latitude_deg'].mean()),
                           float(mine['longitude_deg'].mean()))
        east, north = frame.to_east_north(mine['longitude_deg'].to_numpy(float),
                                          mine['latitude_deg'].to_numpy(float))
        ratio = _kinematic(mine)
        status = mine['status'].to_numpy(dtype=object)
        fig, (a, b) = plt.subplots(1, 2, figsize=(14, 5))
        a.scatter(east, north, s=3, c='0.7', label='planted / unknown')
        for mask, style, label in (
                (status == 'empty', dict(c='red', marker='x', s=30), 'empty cup'),
                (status == 'double', dict(c='blue', marker='+', s=40), 'double'),
                (ratio > MISS_LIMIT, dict(facecolors='none', edgecolors='darkorange', s=50),
                 f'spacing > {MISS_LIMIT:g} d (miss)'),
                (ratio <= MULTIPLE_LIMIT, dict(facecolors='none', edgecolors='purple', s=50),
                 f'spacing <= {MULTIPLE_LIMIT:g} d (multiple)'),
                (mine['input_gap'].to_numpy(dtype=bool), dict(c='black', marker='s', s=12),
                 'input gap (position interpolated)')):
            if mask.any():
                a.scatter(east[mask], north[mask], label=f'{label}: {int(mask.sum())}', **style)
        a.set_title(f'{bag}: misses, multiples, gaps')
        tilt = np.degrees(np.abs(mine['tilt_rad'].to_numpy(dtype=float)))
        sc = b.scatter(east, north, s=5, c=tilt, cmap='viridis_r')
        fig.colorbar(sc, ax=b, label='|tilt| from vertical [deg]')
        b.set_title(f'{bag}: tilt (black: not known)')
        gap = ~np.isfinite(tilt)
        if gap.any():
            b.scatter(east[gap], north[gap], s=12, c='black', marker='s')
        for ax in (a, b):
            ax.set_xlabel('east [m]')
            ax.set_ylabel('north [m]')
            ax.set_aspect('equal', adjustable='datalim')
            ax.grid(alpha=0.3)
        a.legend(fontsize='small', loc='best')
        out.append(_png(fig))
    return '\n'.join(out)


def _histograms(plants):
    import matplotlib.pyplot as plt  # lazy: loaded in _matplotlib_home (its font cache)
    rows = sorted(plants['row_name'].unique())
    cols = min(len(rows), 4)
    lines = math.ceil(len(rows) / cols)
    fig, axes = plt.subplots(lines, cols, figsize=(4 * cols, 3 * lines), squeeze=False)
    for ax, row in zip(axes.ravel(), rows):
        ratio = _kinematic(plants[plants['row_name'] == row])
        ratio = ratio[np.isfinite(ratio)]
        # one filled outline: the 70 bars (they have no edges) as one patch, drawn alike
        ax.hist(np.clip(ratio, 0, 3.5), bins=np.linspace(0, 3.5, 71), color='tab:green',
                histtype='stepfilled')
        for limit in (MULTIPLE_LIMIT, MISS_LIMIT):
            ax.axvline(limit, color='red', lw=0.8, ls='--')
        ax.set_title(f'row {row}: {ratio.size} spacings')
        ax.set_xlabel('spacing / design spacing')
        ax.set_ylabel('count')
    for ax in axes.ravel()[len(rows):]:
        ax.axis('off')
    # room for a panel's title above it and the axis labels of the panel above
    _margins(fig, left=0.7, right=0.2, bottom=0.6, top=0.4, between=(0.8, 0.9))
    return _png(fig)


def _trends(groups):
    import matplotlib.pyplot as plt  # lazy: loaded in _matplotlib_home (its font cache)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    keys = (('quality_of_feed_index', 'quality of feed [%]'),
            ('miss_index', 'miss index [%]'), ('uprightness_rate', 'upright [%]'))
    for ax, (key, label) in zip(axes, keys):
        for (field, row) in sorted({(g['field'], g['row']) for g in groups}):
            mine = [g for g in groups if g['field'] == field and g['row'] == row]
            days = [g['day'] for g in mine]
            values = [np.nan if g[key] is None else 100 * g[key] for g in mine]
            ax.plot(days, values, 'o-', label=f'{field} / {row}')
        ax.set_title(label)
        ax.grid(alpha=0.3)
        ax.tick_params(axis='x', rotation=45)
    axes[0].legend(fontsize='small')
    _margins(fig, left=0.7, right=0.2, bottom=1.0, top=0.4, between=(0.7, 0))  # (dates at 45°)
    return _png(fig)


def _table(groups):
    head = ''.join(f'<th>{html.escape(h)}</th>' for _, h, _ in COLUMNS) + '<th>failed</th>'
    rows = []
    for g in groups:
        cells = ''.join(f'<td>{html.escape(_cell(k, g[k]))}</td>' for k, _, _ in COLUMNS)
        cls = 'fail' if g['failed'] else 'pass'
        failed = '; '.join(f['text'] for f in g['acceptance']['failed'])
        rows.append(f'<tr class="{cls}">{cells}<td>{html.escape(failed)}</td></tr>')
    return f'<table><tr>{head}</tr>{"".join(rows)}</table>'


STYLE = """body{font-family:sans-serif;margin:2em;max-width:1400px}
table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:3px 6px;
text-align:right}tr.fail td{background:#fde0dc}tr.pass td:nth-child(14){color:#1b5e20}
img{max-width:100%;margin:1em 0}"""


def write_season_report(path, groups, plants, bags):
    """The HTML page (module doc) at `path`, written atomically."""
    # lazy: matplotlib loads inside _matplotlib_home (season_report), so that its font cache
    # goes to the scratch MPLCONFIGDIR and `planter analyze` leaves nothing in the home folder
    import matplotlib
    matplotlib.use('Agg')

    parts = ['<!DOCTYPE html><html><head><meta charset="utf-8">',
             '<title>planter_ros season report</title>', f'<style>{STYLE}</style></head><body>',
             '<h1>Season report</h1>']
    if not groups:
        parts.append('<p>No analysed plants in the tables.</p></body></html>')
        write_text_atomically(path, '\n'.join(parts) + '\n')
        return
    failed = sum(1 for g in groups if g['failed'])
    parts += [f'<p>{len(bags)} recordings, {len(plants)} planting instants in '
              f'{len({g["field"] for g in groups})} field(s) over '
              f'{len({g["day"] for g in groups})} day(s): {len(groups) - failed} field-day-rows '
              f'pass, {failed} fail the crop\'s acceptance limits. Percentages of the ISO 7256-1 '
              'indices count the spacings between the seedlings in the ground (an empty cup is '
              'a miss, a double a multiple); hole width in mm; day in UTC; field = the '
              "recordings' folder.</p>",
              '<h2>Per field, day and row</h2>', _table(groups),
              '<h2>Maps</h2>', _maps(plants),
              '<h2>Spacing per row</h2>', _histograms(plants),
              '<h2>Over the season</h2>', _trends(groups),
              '</body></html>']
    write_text_atomically(path, '\n'.join(parts) + '\n')
