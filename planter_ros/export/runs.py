"""What the exports take: one recording's plants as records, the same for `planter replay` (a
ReplayResult) and `planter analyze` (a bag's rows of the Parquet tables).

A record is `recording.export.plant_records`' dict of a plant (row, row_name, index, time,
longitude, latitude, spacing, spacing_error, hole_width, tilt, upright, status, reason,
input_gap; None where undefined) plus `ground_speed` (m/s), `heading` (the machine's heading at
the instant, rad counter-clockwise from east, REP 103; None without a map position) and
`design_spacing` (m, the design spacing in force at the instant: `design_spacings`). A key the
records gain later is carried by the exports without a change here: the Shapefile makes it a
column (shapefile.py), the ISOXML time log counts a plant by its `status` (isoxml.py).
"""

from bisect import bisect_right
from dataclasses import dataclass, field
from datetime import datetime, timezone
import math
from types import SimpleNamespace

__all__ = ['ExportRun', 'RowPlace', 'design_spacings', 'run_of_plants', 'run_of_replay',
           'utc_text']


@dataclass(frozen=True)
class RowPlace:
    """Where a row plants on the machine (rows.Row's, REP 103): m to the left of and ahead of
    the machine's reference point; a row not enabled plants nothing."""

    lateral: float = 0.0
    longitudinal: float = 0.0
    enabled: bool = True


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
    # row index -> its RowPlace on the machine (a row not listed: at the reference point)
    places: dict = field(default_factory=dict)

    @property
    def plants(self):
        return len(self.records)


def run_of_plants(key, plants, rows, design_spacing=None, row_quality=None, places=None,
                  heading=None):
    """An ExportRun of a Plants table (planter_ros.prediction) and the machine's rows
    [(index, name)], their places {index: RowPlace} and the machine's heading at each plant
    (rad, counter-clockwise from east; None or NaN: unknown)."""
    from planter_ros.recording.export import plant_records
    view = SimpleNamespace(plants=plants,
                           rows=[SimpleNamespace(index=int(i), name=str(n)) for i, n in rows])
    records = plant_records(view)
    headings = [None] * len(records) if heading is None else heading
    for record, speed, turned in zip(records, plants.ground_speed, headings):
        record['ground_speed'] = _finite(speed)
        record['heading'] = _finite(turned)
    for record, d in zip(records, design_spacings(records, design_spacing)):
        record['design_spacing'] = d
    return ExportRun(str(key), records, [(int(i), str(n)) for i, n in rows], design_spacing,
                     dict(row_quality or {}), dict(places or {}))


def _finite(value):
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def design_spacings(records, fallback=None):
    """The design spacing d in force at each record's instant (m): spacing − spacing_error
    where the record has both (what the model judged it by); else the d of the last record
    before it that has one, of any row (a design change is in force for every row from the
    next planting instant after it), or of the first after it for records before any; else
    `fallback` (the run's last design). Only between the last plant planted at the old d and
    the first at the new one, when neither has a spacing (an empty cup, a sequence's first
    plant), is the change's instant unknown: such a record gets the old d."""
    known = sorted((r['time'], r['spacing'] - r['spacing_error']) for r in records
                   if r.get('spacing') is not None and r.get('spacing_error') is not None
                   and r.get('time') is not None)
    times = [t for t, _ in known]
    out = []
    for r in records:
        if r.get('spacing') is not None and r.get('spacing_error') is not None:
            out.append(r['spacing'] - r['spacing_error'])
        elif known and r.get('time') is not None:
            out.append(known[max(bisect_right(times, r['time']) - 1, 0)][1])
        else:
            out.append(fallback)
    return out


def run_of_replay(result, key=None):
    """The ExportRun of a ReplayResult (`key`: default the bag's file name)."""
    from pathlib import Path
    quality = {row.index: summary.get('spacing_quality') or {}
               for row, summary in zip(result.rows, result.row_summaries)}
    places = {row.index: RowPlace(row.lateral_offset, row.longitudinal_offset, row.enabled)
              for row in result.rows}
    placement = getattr(result, 'placement', None)
    return run_of_plants(key or Path(result.path).name, result.plants,
                         [(row.index, row.name) for row in result.rows],
                         result.summary.get('design_spacing'), quality, places,
                         None if placement is None else placement.heading)


def utc_datetime(seconds):
    """A time of the recording's clock (s since 1970-01-01 UTC) as an aware datetime."""
    return datetime.fromtimestamp(seconds, tz=timezone.utc)


def utc_text(seconds):
    """ISO 8601 in UTC with milliseconds: '2026-11-24T10:15:00.123Z' (None for None)."""
    if seconds is None:
        return None
    return utc_datetime(seconds).isoformat(timespec='milliseconds').replace('+00:00', 'Z')
