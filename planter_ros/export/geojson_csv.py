"""The as-planted map of a replay as files: GeoJSON (RFC 7946) and CSV, one plant per feature or
line, SI units and WGS 84 degrees. Pure Python: no ROS.

GeoJSON: a FeatureCollection of Point features, coordinates [longitude, latitude] (RFC 7946's
order, WGS 84), with COORDINATE_DECIMALS decimals (1e-9 degrees is about 0.1 mm: the 6 decimals
RFC 7946 suggests are 0.1 m, half a plant spacing); a plant without a map position (no GNSS) is
a Feature whose geometry is null, as RFC 7946 allows for unlocated features. Properties: row
(index), row_name, index, time (s, the recording's clock), spacing, spacing_error, hole_width (m),
tilt (rad, + leaning forward), upright (true/false), status (planted | empty | double |
unknown), reason (sensed | no seedling sensor | no sensor reading | input gap), input_gap
(true: the instant fell in a gap of the inputs, its position interpolated); an undefined value
is null. Every planting instant is a feature: an empty cup's and an input gap's too.
CSV: the same table, a header line naming each column with its unit (CSV_HEADER: `time_s`,
`longitude_deg`, `spacing_m`, `tilt_rad`, ...; row, index, upright and input_gap are
dimensionless), empty cells for undefined values (pandas and DuckDB read them as null), upright and
input_gap as 1/0.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Mapping
import math
from typing import TYPE_CHECKING, Any

from planter_ros.output_files import write_text_atomically
from planter_ros.prediction import reason_name, status_name

if TYPE_CHECKING:
    from pathlib import Path

    from planter_ros.prediction import Plants
    from planter_ros.recording.replay import ReplayResult

COORDINATE_DECIMALS = 9
PROPERTIES = ('row', 'row_name', 'index', 'time', 'spacing', 'spacing_error', 'hole_width',
              'tilt', 'upright', 'status', 'reason', 'input_gap')
CSV_COLUMNS = ('row', 'row_name', 'index', 'time', 'longitude', 'latitude', 'spacing',
               'spacing_error', 'hole_width', 'tilt', 'upright', 'status', 'reason',
               'input_gap')
# each column's header: its unit in the name, as the Parquet tables and the Shapefile have them
CSV_HEADER = {'time': 'time_s', 'longitude': 'longitude_deg', 'latitude': 'latitude_deg',
              'spacing': 'spacing_m', 'spacing_error': 'spacing_error_m',
              'hole_width': 'hole_width_m', 'tilt': 'tilt_rad'}


def _number(value: float) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


def _flag(value: float) -> bool | None:
    value = float(value)
    return bool(value) if math.isfinite(value) else None


def plant_records(result: ReplayResult) -> list[dict[str, Any]]:
    """One dict per plant of a ReplayResult: the CSV columns, None for undefined values."""
    return records_of_plants(result.plants, {row.index: row.name for row in result.rows})


def records_of_plants(p: Plants, names: Mapping[int, str]) -> list[dict[str, Any]]:
    """One dict per plant of a Plants table whose rows are named `names` {index: name}: the
    CSV columns, None for undefined values."""
    out = []
    for i in range(len(p)):
        row = int(p.row[i])
        out.append({'row': row, 'row_name': names.get(row, ''), 'index': int(p.index[i]),
                    'time': _number(p.time[i]), 'longitude': _number(p.longitude[i]),
                    'latitude': _number(p.latitude[i]), 'spacing': _number(p.spacing[i]),
                    'spacing_error': _number(p.spacing_error[i]),
                    'hole_width': _number(p.hole_width[i]), 'tilt': _number(p.tilt[i]),
                    'upright': _flag(p.upright[i]), 'status': status_name(p.status[i]),
                    'reason': reason_name(p.reason[i]), 'input_gap': bool(p.input_gap[i] == 1)})
    return out


def geojson(result: ReplayResult) -> dict:
    """The RFC 7946 FeatureCollection (a dict) of a ReplayResult's plants."""
    features = []
    for record in plant_records(result):
        lon, lat = record['longitude'], record['latitude']
        geometry = None if lon is None or lat is None else {
            'type': 'Point',
            'coordinates': [round(lon, COORDINATE_DECIMALS), round(lat, COORDINATE_DECIMALS)]}
        features.append({'type': 'Feature', 'geometry': geometry,
                         'properties': {k: record[k] for k in PROPERTIES}})
    return {'type': 'FeatureCollection', 'features': features}


def geojson_text(result: ReplayResult) -> str:
    return json.dumps(geojson(result), allow_nan=False, separators=(',', ':')) + '\n'


def csv_text(result: ReplayResult) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator='\n')
    writer.writerow([CSV_HEADER.get(c, c) for c in CSV_COLUMNS])
    for record in plant_records(result):
        cells = []
        for column in CSV_COLUMNS:
            value = record[column]
            if column in ('upright', 'input_gap') and value is not None:
                value = int(value)
            elif column in ('longitude', 'latitude') and value is not None:
                value = f'{value:.{COORDINATE_DECIMALS}f}'
            elif isinstance(value, float):
                value = repr(value)
            cells.append('' if value is None else value)
        writer.writerow(cells)
    return out.getvalue()


def _counts(result: ReplayResult) -> str:
    placed = int(sum(1 for v in result.plants.latitude if math.isfinite(v)))
    return f'({len(result.plants)} plants, {placed} with a map position)'


def write_geojson(result: ReplayResult, path: str | Path) -> str:
    """Write the GeoJSON of a ReplayResult at `path` (atomically): the line for people."""
    write_text_atomically(path, geojson_text(result))
    return f'GeoJSON written to {path} {_counts(result)}'


def write_csv(result: ReplayResult, path: str | Path) -> str:
    """Write the CSV of a ReplayResult at `path` (atomically): the line for people."""
    write_text_atomically(path, csv_text(result))
    return f'CSV written to {path} {_counts(result)}'
