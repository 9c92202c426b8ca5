"""What the exports take: one recording's plants as records, the same for `planter replay` (a
ReplayResult) and `planter analyze` (a bag's rows of the Parquet tables).

A record is `recording.export.plant_records`' dict of a plant (row, row_name, index, time,
longitude, latitude, spacing, spacing_error, hole_width, tilt, upright; None where undefined)
plus `ground_speed` (m/s). A key the records gain later (e.g. a per-plant `status` and its
`reason`) is carried by the exports without a change here: the Shapefile makes it a column
(shapefile.py) and the ISOXML time log counts a plant by its `status` (isoxml.py).
"""

from dataclasses import dataclass, field
from datetime import datetime, timezone
import math
from types import SimpleNamespace

__all__ = ['ExportRun', 'run_of_plants', 'run_of_replay', 'utc_text']


@dataclass
class ExportRun:
    """One recording's plants for the exports."""

    key: str                     # the recording as the files name it (its file name, or its
    # path relative to the analysed root)
    records: list                # one dict per plant, in the recording's order (module doc)
    rows: list                   # (index, name) of the machine's rows, in the scene's order
    design_spacing: float = None  # m, the design's plant spacing (the last design's)
    # row index -> the row's ISO 7256-1 indices (prediction.quality: multiple_index,
    # miss_index, quality_of_feed_index, precision; None where undefined)
    row_quality: dict = field(default_factory=dict)

    @property
    def plants(self):
        return len(self.records)


def run_of_plants(key, plants, rows, design_spacing=None, row_quality=None):
    """An ExportRun of a Plants table (planter_ros.prediction) and the machine's rows
    [(index, name)]."""
    from planter_ros.recording.export import plant_records
    view = SimpleNamespace(plants=plants,
                           rows=[SimpleNamespace(index=int(i), name=str(n)) for i, n in rows])
    records = plant_records(view)
    for record, speed in zip(records, plants.ground_speed):
        speed = float(speed)
        record['ground_speed'] = speed if math.isfinite(speed) else None
    return ExportRun(str(key), records, [(int(i), str(n)) for i, n in rows], design_spacing,
                     dict(row_quality or {}))


def run_of_replay(result, key=None):
    """The ExportRun of a ReplayResult (`key`: default the bag's file name)."""
    from pathlib import Path
    quality = {row.index: summary.get('spacing_quality') or {}
               for row, summary in zip(result.rows, result.row_summaries)}
    return run_of_plants(key or Path(result.path).name, result.plants,
                         [(row.index, row.name) for row in result.rows],
                         result.summary.get('design_spacing'), quality)


def utc_datetime(seconds):
    """A time of the recording's clock (s since 1970-01-01 UTC) as an aware datetime."""
    return datetime.fromtimestamp(seconds, tz=timezone.utc)


def utc_text(seconds):
    """ISO 8601 in UTC with milliseconds: '2026-11-24T10:15:00.123Z' (None for None)."""
    if seconds is None:
        return None
    return utc_datetime(seconds).isoformat(timespec='milliseconds').replace('+00:00', 'Z')
