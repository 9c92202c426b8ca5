"""A season's as-planted map for farm software, next to its tables (doc/exports.md):

    as_planted.zip     the Shapefile set (as_planted.shp, .shx, .dbf, .prj, .cpg) of every
                       plant of the season, column `bag` naming its recording
    TASKDATA.zip       ISO 11783-10 task data (TASKDATA/): one task per recording, each with
                       its time log; one device per machine (row layout)

One file of each per season: a farm-management system imports a season's work as one upload,
in which ISOXML keeps each recording apart as a task and the Shapefile by its `bag` column.
Both are rebuilt from the tables (bags.parquet and plants/) whenever a run analysed a bag or
one of them is missing, so they always hold what the tables hold.
"""

from pathlib import Path
import time
from typing import TypedDict

import numpy as np

from planter_ros.analysis.season import (
    ANALYSED, BAGS_FILE, EXPORTS, ISOXML, PLANTS_DIR, SHAPEFILE, read_bags,
    written_after_the_tables)
from planter_ros.analysis.tables import HEADING, plant_columns
from planter_ros.prediction import PLANT_FIELDS, Plants
from planter_ros.recording.recovery import one_line

from . import isoxml, shapefile
from .runs import MachineRows, RowPlace, run_of_plants

__all__ = ['EXPORTS', 'ISOXML', 'SHAPEFILE', 'format_exports', 'season_exports', 'season_runs',
           'write_season_exports']


def season_runs(out):
    """ExportRuns (runs.py) of every analysed bag in the tables under `out`, in the bags
    table's order, each once (its plants by its content id); a run is named by the bag's name,
    its path from the analysed root."""
    import pyarrow.parquet as pq  # lazy: 150 ms, loaded only when a season is exported


    out = Path(out)
    bags = [row for row in read_bags(out / BAGS_FILE)
            if row.get('status') in ANALYSED and row.get('plants_file')]
    if not bags:
        return []
    table = pq.read_table(out / PLANTS_DIR)
    keys = table.column('bag_id').to_numpy(zero_copy_only=False)
    columns = np.column_stack(plant_columns(table, PLANT_FIELDS))
    (heading,) = plant_columns(table, (HEADING,))
    names, inverse = np.unique(keys, return_inverse=True)
    where = {name: np.flatnonzero(inverse == i) for i, name in enumerate(names)}
    runs = []
    for row in bags:
        rows = row.get('rows') or [{'index': 0, 'name': ''}]
        quality = {r['index']: (r.get('summary') or {}).get('spacing_quality') or {}
                   for r in rows}
        mine = where.get(row['bag_id'], np.zeros(0, dtype=int))
        places = {r['index']: RowPlace(r.get('lateral_offset') or 0.0,
                                       r.get('longitudinal_offset') or 0.0,
                                       r.get('enabled', True) is not False) for r in rows}
        machine = MachineRows(tuple((r['index'], r['name']) for r in rows), places)
        runs.append(run_of_plants(row['bag'], Plants.from_table(columns[mine]), machine,
                                  row.get('summary.design_spacing'), quality, heading[mine]))
    return runs


class Failed(TypedDict):
    """An export not written: its file and why (one line)."""

    file: str
    reason: str


class Skipped(TypedDict):
    """A recording the ISOXML cannot hold, and why."""

    bag: str
    reason: str


class SeasonExports(TypedDict, total=False):
    """What `write_season_exports` wrote (a plain mapping: the command's JSON summary holds
    it); `seconds` is added by `season_exports`."""

    shapefile: str | None       # path, None: not written
    isoxml: str | None
    plants: int
    placed: int
    tasks: int
    skipped: list[Skipped]
    failed: list[Failed]
    seconds: float


def write_season_exports(out: str | Path, force: bool = False) -> SeasonExports | None:
    """Write as_planted.zip and TASKDATA.zip under `out` from its tables (unless both exist,
    were written after the tables and not `force`), each on its own (one that fails never
    keeps the other from being written): {'shapefile', 'isoxml': paths (None: not written),
    'plants', 'placed', 'tasks', 'skipped': [{bag, reason}] (bags the ISOXML cannot hold),
    'failed': [{file, reason}]} or None when nothing was to be written."""
    out = Path(out)
    if not force and all(written_after_the_tables(out / name, out) for name in EXPORTS):
        return None
    runs = season_runs(out)
    result: SeasonExports = {'shapefile': None, 'isoxml': None, 'plants': 0, 'placed': 0,
                             'tasks': 0, 'skipped': [], 'failed': []}
    try:
        result['plants'], result['placed'] = shapefile.write_shapefile(out / SHAPEFILE, runs)
        result['shapefile'] = str(out / SHAPEFILE)
    except Exception as exc:           # a disk full, a bug on odd data: the ISOXML still goes
        result['failed'].append({'file': str(out / SHAPEFILE), 'reason': one_line(exc)})
    try:
        result['tasks'], _, skipped = isoxml.write_isoxml(out / ISOXML, runs)
        result['isoxml'] = str(out / ISOXML)
        result['skipped'] = [{'bag': bag, 'reason': reason} for bag, reason in skipped]
    except Exception as exc:
        result['failed'].append({'file': str(out / ISOXML), 'reason': one_line(exc)})
    return result


def season_exports(out: str | Path, force: bool) -> SeasonExports | None:
    """The season's Shapefile and ISOXML next to the tables (export.season), with the time
    it took: written when `force` (bags were analysed) or one is missing or older than a
    table (a run stopped before them); None otherwise."""
    started = time.monotonic()
    exports = write_season_exports(out, force)
    if exports is not None:
        exports['seconds'] = time.monotonic() - started
    return exports


def format_exports(exports: SeasonExports) -> str:
    """The exports' line for people (what was written; the failures go to stderr)."""
    written = []
    if exports['shapefile']:
        written.append(f'{exports["shapefile"]} (Shapefile, {exports["plants"]} plants, '
                       f'{exports["placed"]} with a map position)')
    if exports['isoxml']:
        written.append(f'{exports["isoxml"]} (ISOXML, {exports["tasks"]} tasks)')
    return f'exports: {", ".join(written) or "none written"} in {exports["seconds"]:.1f} s'
