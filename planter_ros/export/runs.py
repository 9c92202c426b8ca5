"""What the exports take: one recording's plants as records, the same for `planter replay` (a
ReplayResult) and `planter analyze` (a bag's rows of the Parquet tables).

A record is `geojson_csv.plant_records`' dict of a plant (row, row_name, index, time,
longitude, latitude, spacing, spacing_error, hole_width, tilt, upright, status, reason,
input_gap; None where undefined) plus `ground_speed` (m/s), `heading` (the machine's heading at
the instant, rad counter-clockwise from east, REP 103; None without a map position) and
`design_spacing` (m, the design spacing in force at the instant: `design_spacings`). A key the
records gain later is carried by the exports without a change here: the Shapefile makes it a
column (shapefile.py), the ISOXML time log counts a plant by its `status` (isoxml.py).
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .geojson_csv import records_of_plants

if TYPE_CHECKING:
    from planter_ros.prediction import Plants
    from planter_ros.recording.replay import ReplayResult

__all__ = ['ExportRun', 'MachineRows', 'RowPlace', 'design_spacings', 'run_of_plants',
           'run_of_replay', 'utc_text']

Record = dict[str, Any]     # one plant: module doc


@dataclass(frozen=True)
class RowPlace:
    """Where a row plants on the machine (rows.Row's, REP 103): m to the left of and ahead of
    the machine's reference point; a row not enabled plants nothing."""

    lateral: float = 0.0
    longitudinal: float = 0.0
    enabled: bool = True


@dataclass(frozen=True)
class MachineRows:
    """The machine a recording was made on, as the exports draw it: its rows (index, name)
    in the scene's order and where each plants on it {index: RowPlace} (a row not listed: at
    the reference point)."""

    rows: tuple[tuple[int, str], ...]
    places: Mapping[int, RowPlace] = field(default_factory=dict)


@dataclass
class ExportRun:
    """One recording's plants for the exports."""

    key: str                     # the recording as the files name it (its file name, or its
    # path relative to the analysed root)
    records: list[Record]        # one dict per plant, in the recording's order (module doc)
    rows: list[tuple[int, str]]  # (index, name) of the machine's rows, in the scene's order
    design_spacing: float | None = None  # m, the design's plant spacing (the last design's)
    # row index -> the row's ISO 7256-1 indices (prediction.quality: multiple_index,
    # miss_index, quality_of_feed_index, precision; None where undefined)
    row_quality: dict[int, dict[str, Any]] = field(default_factory=dict)
    # row index -> its RowPlace on the machine (a row not listed: at the reference point)
    places: dict[int, RowPlace] = field(default_factory=dict)

    @property
    def plants(self) -> int:
        return len(self.records)


def run_of_plants(key: str, plants: Plants, machine: MachineRows,
                  design_spacing: float | None = None,
                  row_quality: Mapping[int, dict[str, Any]] | None = None,
                  heading: npt.NDArray[np.float64] | None = None) -> ExportRun:
    """An ExportRun of a Plants table (planter_ros.prediction) made on `machine` (its rows
    and their places) and the machine's heading at each plant (rad, counter-clockwise from
    east; None or NaN: unknown)."""
    rows = [(int(i), str(n)) for i, n in machine.rows]
    records = records_of_plants(plants, dict(rows))
    headings: Sequence[float | None] | npt.NDArray[np.float64] = (
        [None] * len(records) if heading is None else heading)
    for record, speed, turned in zip(records, plants.ground_speed, headings):
        record['ground_speed'] = _finite(speed)
        record['heading'] = _finite(turned)
    for record, d in zip(records, design_spacings(records, design_spacing)):
        record['design_spacing'] = d
    return ExportRun(str(key), records, rows, design_spacing, dict(row_quality or {}),
                     dict(machine.places))


def _finite(value: float | None) -> float | None:
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def design_spacings(records: Sequence[Record],
                    fallback: float | None = None) -> list[float | None]:
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
    out: list[float | None] = []
    for r in records:
        if r.get('spacing') is not None and r.get('spacing_error') is not None:
            out.append(r['spacing'] - r['spacing_error'])
        elif known and r.get('time') is not None:
            out.append(known[max(bisect_right(times, r['time']) - 1, 0)][1])
        else:
            out.append(fallback)
    return out


def run_of_replay(result: ReplayResult, key: str | None = None) -> ExportRun:
    """The ExportRun of a ReplayResult (`key`: default the bag's file name)."""
    quality = {row.index: summary.get('spacing_quality') or {}
               for row, summary in zip(result.rows, result.row_summaries)}
    places = {row.index: RowPlace(row.lateral_offset, row.longitudinal_offset, row.enabled)
              for row in result.rows}
    placement = getattr(result, 'placement', None)
    machine = MachineRows(tuple((row.index, row.name) for row in result.rows), places)
    return run_of_plants(key or Path(result.path).name, result.plants, machine,
                         result.summary.get('design_spacing'), quality,
                         None if placement is None else placement.heading)


def utc_datetime(seconds: float) -> datetime:
    """A time of the recording's clock (s since 1970-01-01 UTC) as an aware datetime."""
    return datetime.fromtimestamp(seconds, tz=timezone.utc)


def utc_text(seconds: float | None) -> str | None:
    """ISO 8601 in UTC with milliseconds: '2026-11-24T10:15:00.123Z' (None for None)."""
    if seconds is None:
        return None
    return utc_datetime(seconds).isoformat(timespec='milliseconds').replace('+00:00', 'Z')
