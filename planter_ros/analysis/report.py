"""The season report's figures for people, from the tables under --out (analysis.tables): one
line per field, day and row with its planting instants, the ISO 7256-1 indices, uprightness,
hole width and the verdict of the crop's acceptance limits. Pure (pandas, numpy): the HTML page
and its figures are plots.season.

* **field**: the bag's folder relative to the analysed root (`.` for bags at the root): a
  season laid out as `<field>/<day>/...` or `<field>/...` groups by field; a flat folder of
  bags is one field.
* **day**: the UTC date of the plant's planting instant.
* **row**: the row's name (`row` for a machine without named rows).

The indices of a group come from its seedling spacings (prediction.seedlings: a double adds a
spacing of 0), each against its own design spacing; uprightness is the share of the plants
whose uprightness is known; hole width the mean of the known ones. A group passes when it meets
the acceptance limits its bags recorded (the most recent bag's, when they differ:
prediction.acceptance).
"""

from pathlib import Path
import posixpath
from typing import Any

import numpy as np

from planter_ros.config import from_mapping
from planter_ros.prediction import AcceptanceLimits, judge_acceptance, spacing_quality

from .season import ANALYSED, BAGS_FILE, PLANTS_DIR

__all__ = ['COLUMNS', 'format_season_table', 'read_season', 'season_groups']

# (key, header, width): the printed table
COLUMNS = (('field', 'field', 12), ('day', 'day (UTC)', 10), ('row', 'row', 11),
           ('instants', 'instants', 8), ('empty', 'empty', 5), ('double', 'double', 6),
           ('unknown', 'unknown', 7), ('quality_of_feed_index', 'feed %', 6),
           ('miss_index', 'miss %', 6), ('multiple_index', 'mult %', 6),
           ('precision', 'CV %', 5), ('uprightness_rate', 'upright %', 9),
           ('hole_width_mean', 'hole mm', 7), ('verdict', 'verdict', 7))


def read_season(out):
    """(plants, bags) of the tables under `out` as pandas DataFrames (only analysed bags; the
    plants with `field` and `day` columns). Empty frames when nothing was analysed."""
    import pandas as pd  # lazy: 330 ms, only where the tables are read back
    out = Path(out)
    bags = pd.read_parquet(out / BAGS_FILE) if (out / BAGS_FILE).is_file() else pd.DataFrame()
    if bags.empty or not any((out / PLANTS_DIR).glob('*.parquet')):
        return pd.DataFrame(), bags
    bags = bags[bags['status'].isin(ANALYSED)]
    plants = pd.read_parquet(out / PLANTS_DIR)
    plants = plants[plants['bag'].isin(set(bags['bag']))].copy()
    plants['field'] = [posixpath.dirname(b) or '.' for b in plants['bag']]
    plants['day'] = plants['time_utc'].dt.strftime('%Y-%m-%d')
    return plants, bags


def _limits(bags, keys):
    """The acceptance limits the group's bags recorded (the latest bag's)."""
    mine = bags[bags['bag'].isin(keys)]
    columns = [c for c in mine.columns if c.startswith('acceptance.limits.')]
    if mine.empty or not columns:
        return AcceptanceLimits()
    latest = mine.sort_values('analysed_at').iloc[-1]
    values = {c.split('.')[-1]: latest[c] for c in columns if latest[c] == latest[c]}
    return from_mapping(AcceptanceLimits, values)


def group_figures(group):
    """The summary of one group of plant rows (a DataFrame): what summarize gives a run, from
    the table's columns."""
    status = group['status'].to_numpy(dtype=object) if 'status' in group else \
        np.full(len(group), 'unknown', dtype=object)
    spacing = group['spacing_m'].to_numpy(dtype=float)
    d = spacing - group['spacing_error_m'].to_numpy(dtype=float)
    d_known = d[np.isfinite(d)]
    d = np.where(np.isfinite(d), d, np.median(d_known) if d_known.size else np.nan)
    seedlings = group['seedlings'].to_numpy(dtype=float) if 'seedlings' in group else \
        np.full(len(group), np.nan)
    extra = np.where(status == 'double', np.maximum(np.nan_to_num(seedlings, nan=2.0) - 1, 1),
                     0).astype(int)
    x = np.concatenate((spacing, np.zeros(int(extra.sum()))))
    x_d = np.concatenate((d, np.repeat(d, extra)))
    upright = group['upright'].to_numpy(dtype=object)
    known = np.array([u is not None and u == u for u in upright], dtype=bool)
    hole = group['hole_width_m'].to_numpy(dtype=float)
    hole = hole[np.isfinite(hole)]
    quality = spacing_quality(x, x_d)
    counts = {name: int(np.count_nonzero(status == name))
              for name in ('planted', 'empty', 'double', 'unknown')}
    # seedlings in the ground, as prediction.status_counts counts them (an unknown instant: 1)
    usual = np.array([{'empty': 0.0, 'double': 2.0}.get(s, 1.0) for s in status])
    counted = np.where(np.isfinite(seedlings) & (status != 'unknown'), seedlings, usual)
    counts['seedlings'] = int(counted.sum())
    return {'plants': len(group), 'instants': counts,
            'uprightness_rate': float(np.mean(upright[known].astype(bool))) if known.any()
            else None,
            'hole_width_mean': float(hole.mean()) if hole.size else None,
            'spacing_quality': quality}


def season_groups(plants, bags):
    """One dict per (field, day, row), sorted: its figures (group_figures), the acceptance
    judgement and the flat values of COLUMNS."""
    out: list[dict[str, Any]] = []
    if plants.empty:
        return out
    for (field, day, row), group in plants.groupby(['field', 'day', 'row_name'], sort=True):
        figures = group_figures(group)
        limits = _limits(bags, set(group['bag']))
        judged = judge_acceptance(limits, [(row, figures)])
        q = figures['spacing_quality']
        out.append({'field': field, 'day': day, 'row': row, 'bags': int(group['bag'].nunique()),
                    'instants': figures['plants'], **figures['instants'],
                    **{k: q[k] for k in ('quality_of_feed_index', 'miss_index',
                                         'multiple_index', 'precision')},
                    'uprightness_rate': figures['uprightness_rate'],
                    'hole_width_mean': figures['hole_width_mean'],
                    'verdict': 'PASS' if judged['passed'] else 'FAIL',
                    'failed': [f['index'] for f in judged['failed']],
                    'acceptance': judged})
    return out


def _cell(key, value):
    if value is None:
        return 'n/a'
    if key in ('quality_of_feed_index', 'miss_index', 'multiple_index', 'precision',
               'uprightness_rate'):
        return f'{100 * value:.1f}'
    if key == 'hole_width_mean':
        return f'{1e3 * value:.1f}'
    return str(value)


def format_season_table(groups):
    """The per field, day and row table for people (percentages, mm; a FAIL names what)."""
    if not groups:
        return 'season report: no analysed plants'
    lines = [' '.join(f'{head:>{width}}' for _, head, width in COLUMNS)]
    for g in groups:
        cells = [f'{_cell(key, g[key]):>{width}}' for key, _, width in COLUMNS]
        line = ' '.join(cells)
        if g['failed']:
            line += '  (' + ', '.join(g['failed']) + ')'
        lines.append(line)
    return '\n'.join(lines)
