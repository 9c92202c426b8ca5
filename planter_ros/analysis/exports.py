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

import numpy as np

from .season import ANALYSED, BAGS_FILE, EXPORTS, ISOXML, PLANTS_DIR, SHAPEFILE, read_bags

__all__ = ['EXPORTS', 'ISOXML', 'SHAPEFILE', 'format_exports', 'season_exports', 'season_runs',
           'write_season_exports']


def season_runs(out):
    """ExportRuns (export.runs) of every analysed bag in the tables under `out`, in the bags
    table's order, each once (its plants by its content id); a run is named by the bag's name,
    its path from the analysed root."""
    import pyarrow.parquet as pq

    from planter_ros.export.runs import RowPlace, run_of_plants
    from planter_ros.prediction import PLANT_FIELDS, Plants

    from .tables import HEADING, plant_columns
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
        runs.append(run_of_plants(row['bag'], Plants.from_table(columns[mine]),
                                  [(r['index'], r['name']) for r in rows],
                                  row.get('summary.design_spacing'), quality, places,
                                  heading[mine]))
    return runs


def write_season_exports(out, force=False):
    """Write as_planted.zip and TASKDATA.zip under `out` from its tables (unless both exist
    and not `force`): {'shapefile', 'isoxml': paths, 'plants', 'placed', 'tasks', 'skipped':
    [(bag, reason)]} or None when nothing was written."""
    from planter_ros.export.isoxml import write_isoxml
    from planter_ros.export.shapefile import write_shapefile
    out = Path(out)
    if not force and all((out / name).is_file() for name in EXPORTS):
        return None
    runs = season_runs(out)
    plants, placed = write_shapefile(out / SHAPEFILE, runs)
    tasks, _, skipped = write_isoxml(out / ISOXML, runs)
    return {'shapefile': str(out / SHAPEFILE), 'isoxml': str(out / ISOXML), 'plants': plants,
            'placed': placed, 'tasks': tasks,
            'skipped': [{'bag': bag, 'reason': reason} for bag, reason in skipped]}


def season_exports(out, force):
    """The season's Shapefile and ISOXML next to the tables (analysis.exports), with the time
    it took: written when `force` (bags were analysed) or one is missing; None otherwise."""
    import time
    started = time.monotonic()
    exports = write_season_exports(out, force)
    if exports is not None:
        exports['seconds'] = time.monotonic() - started
    return exports


def format_exports(exports):
    """The exports' line for people."""
    return (f'exports: {exports["shapefile"]} (Shapefile, {exports["plants"]} plants, '
            f'{exports["placed"]} with a map position), {exports["isoxml"]} (ISOXML, '
            f'{exports["tasks"]} tasks) in {exports["seconds"]:.1f} s')
