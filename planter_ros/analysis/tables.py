"""The season's tables as Arrow (pyarrow), built from `planter replay --json`, for people:
each in its own folder (`bags/`, `plants/`), so `**/*.parquet` never mixes them.

* `plants`: one row per plant: `bag` (the bag's name: its path relative to the analysed root),
  `bag_id` (its content fingerprint: the key the tables join by, analysis.season), then the
  JSON's plant fields under names that carry their unit
  (PLANTS_COLUMNS): `index` and `row` int64, `row_name` (text: the row's name, `row` for a
  machine without named rows) after `row`, `time_utc` a UTC timestamp (ns; the planting instant
  on the recording's clock, ROS time = s since 1970-01-01 UTC), `upright` bool, lengths `_m`,
  speeds `_m_s` and `_rad_s`, `tilt_rad`, `latitude_deg` / `longitude_deg`, `input_gap` bool,
  `seedlings` int64, `status` and `reason` as text (prediction.seedlings), `heading_rad` (the
  machine's heading at the instant, counter-clockwise from east, null without a map position:
  where the ISOXML export places the machine). A field the model
  gains later is a new column under its JSON name. Null where the JSON has null (the first
  plant's spacing). `plant_dicts` turns a table back into the JSON's plant dicts.
* `bags`: one row per bag: `bag` and `bag_id` (as in plants), `status` (ok | warnings | failed |
  error), `reason` (one line, null unless failed or error), the re-run key (`file_size`,
  `file_mtime_ns`, `model_version`, `options`), `analysed_at` (UTC timestamp),
  `analysis_seconds`, `analysis_cpu_seconds`, `plants_file` (the part of the plants dataset
  holding the bag's rows), then the replay JSON without its plants, flattened: nested objects
  become dotted columns (`summary.spacing_error_mean`, `settings.window`, `design.l1`,
  `messages.joint_states`), lists stay lists (`warnings`, `rows` = each row's record and
  summary). The JSON's own `bag` (the path replay read) is `path`.

Column types: numbers are float64 (int64 when every value is an integer), booleans bool, text
string, a column of nulls only float64, anything else as pyarrow infers it. Units (SI; '1' =
dimensionless) go into each field's metadata (`unit`) and into the schema metadata
(`planter_ros` = JSON {"table", "units", "root"}), from UNITS by the column's last dotted part
(a unit suffix `_m`, `_rad` ... of a people's name taken off first), a summary statistic
(`..._mean`, `_std`, `_max`, `_min`) taking its quantity's unit, the prediction settings' and
acceptance limits' units from their declarations. A column the table does not know has no unit.
"""

from functools import lru_cache
import json
from typing import Any

import numpy as np
import pyarrow as pa

from planter_ros import prediction
from planter_ros.config import specs
from planter_ros.prediction import AcceptanceLimits, PredictionSettings

PLANTS = 'plants'
BAGS = 'bags'
METADATA_KEY = b'planter_ros'

UNITS = {
    # plants
    'index': '1', 'time': 's', 'position': 'm', 'spacing': 'm', 'spacing_error': 'm',
    'speed_ratio': '1', 'ground_speed': 'm/s', 'shaft_speed': 'rad/s', 'hole_width': 'm',
    'tilt': 'rad', 'upright': '1', 'uprightness_rate': '1', 'row': '1', 'tip_sweep': 'm',
    'latitude': 'deg (WGS 84)', 'longitude': 'deg (WGS 84)', 'altitude': 'm',
    # bags
    'plants': '1', 'design_spacing': 'm', 'duration': 's', 'file_size': 'B',
    'file_mtime_ns': 'ns since the epoch', 'analysis_seconds': 's',
    'analysis_cpu_seconds': 's', 'lateral_offset': 'm',
    'analysed_at': 'UTC timestamp', 'plant_spacing': 'm', 'planting_depth': 'm',
    'nominal_ground_speed': 'm/s', 'top_ground_speed': 'm/s', 'time_utc': 'UTC timestamp',
    'nozzle_width': 'm', 'drive_node_id': '1', 'spacings': '1', 'fixes': '1',
    'multiple_index': '1', 'miss_index': '1', 'quality_of_feed_index': '1', 'precision': '1',
    'tilt_max': 'rad', 'total_read': '1',
    'l1': 'm', 'l2': 'm', 'l3': 'm', 'l4': 'm', 'l5': 'm', 'hole_ratio': '1',
    'sun_bar_speed': 'rad/s', 'min_transmission_angle': 'rad', 'arm_width': 'm',
    'seedling_height': 'm', 'arm_length': 'm', 'pusher_offset': 'm',
    'carrier_initial_angle': 'rad', 'arm_initial_angle': 'rad', 'planet_carrier_angle': 'rad',
    'planting_phase': 'rad', 'plants_per_revolution': '1', 'track_length': 'm',
    'fix_window': 's', 'max_fix_sigma': 'm', 'max_fix_age': 's', 'origin': 'deg (WGS 84)',
    'antenna_position': 'm', 'nominal_mechanism_speed': 'rad/s', 'centre_distance': 'm',
    'closure_residual': '1', 'goals_passed': '1', 'carrier_speed': 'rad/s',
    'requested_hole': 'm', 'psi': 'rad', 'depth': 'm', 'seedlings': '1', 'planted': '1',
    'dyad_ratios': '1', 'longitudinal_offset': 'm', 'heading': 'rad',
    'empty': '1', 'double': '1', 'unknown': '1', 'input_gap': '1', 'instants': '1',
}
# the plants table's column of each JSON plant field (a unit in the name where one is needed)
PLANTS_COLUMNS = {
    'index': 'index', 'time': 'time_utc', 'position': 'position_m', 'spacing': 'spacing_m',
    'spacing_error': 'spacing_error_m', 'speed_ratio': 'speed_ratio',
    'ground_speed': 'ground_speed_m_s', 'shaft_speed': 'shaft_speed_rad_s',
    'hole_width': 'hole_width_m', 'tilt': 'tilt_rad', 'upright': 'upright',
    'uprightness_rate': 'uprightness_rate', 'row': 'row', 'tip_sweep': 'tip_sweep_m',
    'latitude': 'latitude_deg', 'longitude': 'longitude_deg',
}
INTEGER_FIELDS = ('index', 'row')
BOOLEAN_FIELDS = ('upright', 'input_gap')
CODE_FIELDS = {'status': 'STATUSES', 'reason': 'REASONS'}     # codes -> their names (text)
UNIT_SUFFIXES = {'_m_s': 'm/s', '_rad_s': 'rad/s', '_m': 'm', '_rad': 'rad',
                 '_deg': 'deg (WGS 84)'}
_STATISTICS = ('_mean', '_std', '_max', '_min', '_rms')


def unit_of(column):
    """The unit of a column by its last dotted part, or None."""
    leaf = column.rsplit('.', 1)[-1]
    if column.startswith('messages.'):          # message counts, named after their topics
        return '1'
    if column.startswith('settings.') or column.startswith('acceptance.limits.'):
        return _setting_units().get(leaf)
    if '.' not in column:
        for suffix, unit in UNIT_SUFFIXES.items():
            if leaf.endswith(suffix):
                return unit
    if leaf in UNITS:
        return UNITS[leaf]
    for suffix in _STATISTICS:
        if leaf.endswith(suffix) and leaf[:-len(suffix)] in UNITS:
            return UNITS[leaf[:-len(suffix)]]
    return None


def _setting_units():
    return {spec.name: spec.unit or '1' for cls in (PredictionSettings, AcceptanceLimits)
            for spec in specs(cls)}


def load_pyarrow():
    """Import pyarrow and what it loads when it builds its first array (pandas: a second or
    more), so the first table of a run does not pay for it."""
    pa.array([0.0])


def flatten(value, prefix=''):
    """A JSON object as {dotted name: value}; lists are kept as they are, less the empty
    objects in them; an empty object gives no column (Parquet has no type for a struct
    without fields)."""
    out = {}
    for key, item in value.items():
        name = f'{prefix}{key}'
        if isinstance(item, dict):
            out.update(flatten(item, name + '.'))
        else:
            out[name] = _without_empty_objects(item)
    return out


def _without_empty_objects(value):
    if isinstance(value, list):
        return [_without_empty_objects(item) for item in value]
    if isinstance(value, dict):
        return {key: _without_empty_objects(item) for key, item in value.items()
                if item != {}}
    return value


def unflatten(row):
    """The inverse of flatten (dotted names back to nested objects)."""
    out: dict[str, Any] = {}
    for name, value in row.items():
        parts = name.split('.')
        node = out
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return out


# columns of text whatever values a table happens to hold (a table where every `reason` is
# null or every `warnings` list is empty keeps their types)
TEXT = ('bag', 'bag_id', 'path', 'status', 'reason', 'model_version', 'options', 'plants_file',
        'row_name')
TEXT_LISTS = ('warnings',)
TIMESTAMPS = ('analysed_at',)            # s since the epoch in the row dicts


def _epoch_seconds(value):
    """s since the epoch of a number, or of a datetime a table was read back as; None."""
    if value is None:
        return float('nan')
    if hasattr(value, 'timestamp'):
        return value.timestamp()
    return float(value)


def utc_timestamps(seconds):
    """s since 1970-01-01 UTC (None: null; a datetime as it is) as a pyarrow timestamp array
    (ns, UTC)."""
    values = np.array([_epoch_seconds(v) for v in seconds], dtype=float)
    ok = np.isfinite(values)
    ns = np.where(ok, np.round(np.where(ok, values, 0.0) * 1e9), 0).astype(np.int64)
    return pa.array(ns, type=pa.timestamp('ns', tz='UTC'), mask=~ok)


def column(values, name=''):
    """One column's Python values as a pyarrow array (types: see the module doc)."""
    if name in TEXT:
        return pa.array(values, type=pa.string())
    if name in TEXT_LISTS:
        return pa.array(values, type=pa.list_(pa.string()))
    if name in TIMESTAMPS:
        return utc_timestamps(values)
    present = [v for v in values if v is not None]
    kinds = set(map(type, present))
    if kinds and kinds <= {int, float}:       # the usual column: decided in one pass
        return pa.array(values, type=pa.int64() if kinds == {int} else pa.float64())
    if all(isinstance(v, bool) for v in present) and present:
        return pa.array(values, type=pa.bool_())
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
        if present and all(isinstance(v, int) for v in present):
            return pa.array(values, type=pa.int64())
        return pa.array(values, type=pa.float64())
    if all(isinstance(v, str) for v in present):
        return pa.array(values, type=pa.string())
    return pa.array(values)


def table_of(rows, kind, root=None):
    """An Arrow table of row dicts (columns in first-seen order), units in its metadata."""
    names: dict[str, None] = {}            # an ordered set
    for row in rows:
        for name in row:
            names.setdefault(name, None)
    arrays = [column([row.get(name) for row in rows], name) for name in names]
    return with_units(pa.Table.from_arrays(arrays, names=list(names)), kind, root)


def plants_table(bag, plants, rows=()):
    """The plants table of one bag (`bag`: its key) from the JSON plant dicts of `planter
    replay --json` and the machine's rows [(index, name)] (module doc)."""
    names = {int(i): str(n) for i, n in rows}
    keys = []
    for plant in plants:
        keys += [k for k in plant if k not in keys]
    arrays, columns = [pa.array([bag] * len(plants), type=pa.string())], ['bag']
    for key in keys:
        values = [plant.get(key) for plant in plants]
        name = PLANTS_COLUMNS.get(key, key)
        if key == 'time':
            array = utc_timestamps(values)
        elif key in INTEGER_FIELDS:
            array = pa.array([None if v is None else int(v) for v in values], type=pa.int64())
        elif key in BOOLEAN_FIELDS:
            array = pa.array([None if v is None else bool(v) for v in values], type=pa.bool_())
        elif key in CODE_FIELDS:
            array = pa.array([_code_name(key, v) for v in values], type=pa.string())
        elif key == 'seedlings':
            array = pa.array([None if v is None else int(v) for v in values], type=pa.int64())
        elif all(v is None or isinstance(v, (int, float)) for v in values):
            array = pa.array(np.array([np.nan if v is None else v for v in values], dtype=float),
                             mask=np.array([v is None for v in values], dtype=bool))
        else:
            array = column(values, name)
        arrays.append(array)
        columns.append(name)
        if key == 'row':
            arrays.append(pa.array(['' if v is None else names.get(int(v), '')
                                    for v in values], type=pa.string()))
            columns.append('row_name')
    return with_units(pa.Table.from_arrays(arrays, names=columns), PLANTS)


def plants_arrays_table(bag, plants, rows=(), bag_id=None):
    """`plants_table(bag, plants.rows(), rows)` straight from a prediction.Plants (its arrays,
    no dict per plant): the same table, value for value (a non-finite value is null); with
    `bag_id` (the bag's content id, the key planter analyze joins the tables by) after `bag`."""

    names = {int(i): str(n) for i, n in rows}
    n = len(plants)
    arrays, columns = [pa.array([bag] * n, type=pa.string())], ['bag']
    if bag_id is not None:
        arrays.append(pa.array([bag_id] * n, type=pa.string()))
        columns.append('bag_id')
    for key in prediction.PLANT_FIELDS:
        values = np.asarray(getattr(plants, key), dtype=float)
        null = ~np.isfinite(values)
        whole = np.where(null, 0.0, values).astype(np.int64)       # int(v) of each v
        name = PLANTS_COLUMNS.get(key, key)
        if key == 'time':
            ns = np.where(null, 0, np.round(np.where(null, 0.0, values) * 1e9)).astype(np.int64)
            array = pa.array(ns, type=pa.timestamp('ns', tz='UTC'), mask=null)
        elif key in INTEGER_FIELDS or key == 'seedlings':
            array = pa.array(whole, type=pa.int64(), mask=null)
        elif key in BOOLEAN_FIELDS:
            array = pa.array(values != 0.0, type=pa.bool_(), mask=null)
        elif key in CODE_FIELDS:
            codes = getattr(prediction, CODE_FIELDS[key])
            known = ~null & (whole >= 0) & (whole < len(codes))
            name_of = np.array([*codes, None], dtype=object)     # the last: not a code
            array = pa.array(name_of[np.where(known, whole, len(codes))], type=pa.string())
        else:
            array = pa.array(np.where(null, np.nan, values), mask=null)
        arrays.append(array)
        columns.append(name)
        if key == 'row':
            rows_seen, which = np.unique(whole, return_inverse=True)
            name_of = np.array([names.get(r, '') for r in rows_seen.tolist()] + [''],
                               dtype=object)                     # the last: no row
            arrays.append(pa.array(name_of[np.where(null, rows_seen.size, which)],
                                   type=pa.string()))
            columns.append('row_name')
    return with_units(pa.Table.from_arrays(arrays, names=columns), PLANTS)


HEADING = 'heading_rad'         # the machine's heading at each plant (not a JSON plant field)


def with_heading(table, heading):
    """A plants table with `heading_rad`: the machine's heading at each plant (rad,
    counter-clockwise from east, REP 103; null where the plant has no map position), what the
    ISOXML export places the machine with."""
    values = np.full(table.num_rows, np.nan) if heading is None else \
        np.asarray(heading, dtype=float)
    null = ~np.isfinite(values)
    column = pa.array(np.where(null, np.nan, values), mask=null)
    return with_units(table.append_column(HEADING, column), PLANTS)


def _code_name(field, value):
    names = getattr(prediction, CODE_FIELDS[field])
    return None if value is None or not 0 <= int(value) < len(names) else names[int(value)]


def _name_code(field, value):
    names = getattr(prediction, CODE_FIELDS[field])
    return None if value is None else float(names.index(value))


def plant_dicts(table):
    """The JSON plant dicts (`planter replay --json`'s `plants`) of a plants table's rows,
    without `bag`, `bag_id`, `row_name` and `heading_rad`: the inverse of plants_table (times
    to 1 µs)."""
    back = {column: field for field, column in PLANTS_COLUMNS.items()}
    out = []
    for row in table.to_pylist():
        plant = {}
        for name, value in row.items():
            if name in ('bag', 'bag_id', 'row_name', HEADING):
                continue
            field = back.get(name, name)
            if field == 'time' and value is not None:
                value = value.timestamp() if not hasattr(value, 'value') else value.value * 1e-9
            elif field in CODE_FIELDS:
                value = _name_code(field, value)
            elif field in BOOLEAN_FIELDS + INTEGER_FIELDS + ('seedlings',) and \
                    value is not None:
                value = float(value)
            plant[field] = value
        out.append(plant)
    return out


def plant_columns(table, fields):
    """The plants table's columns of the JSON plant `fields` as float arrays (NaN for null or a
    column the table lacks; times in s since the epoch): what the exports read."""
    out = []
    for field in fields:
        name = PLANTS_COLUMNS.get(field, field)
        if name not in table.column_names:
            out.append(np.full(table.num_rows, np.nan))
            continue
        array = table.column(name)
        if field in CODE_FIELDS:
            out.append(np.array([np.nan if v is None else _name_code(field, v)
                                 for v in array.to_pylist()], dtype=float))
            continue
        if pa.types.is_timestamp(array.type):
            ns = array.cast(pa.int64()).to_numpy(zero_copy_only=False)
            mask = array.is_null().to_numpy(zero_copy_only=False)
            values = np.where(mask, np.nan, np.asarray(ns, dtype=float) * 1e-9)
        else:
            values = array.cast(pa.float64()).to_numpy(zero_copy_only=False)
        out.append(np.asarray(values, dtype=float))
    return out


def with_units(table, kind, root=None):
    """`table` with each known column's unit in its field metadata and the schema's (and the
    analysed root its `bag` keys are relative to, if given)."""
    schema = _schema_with_units(table.schema, kind, None if root is None else str(root))
    return pa.Table.from_arrays(table.columns, schema=schema)


@lru_cache(maxsize=32)
def _schema_with_units(schema, kind, root):
    """`with_units`'s schema (made once per columns, kind and root: every bag's plants table
    has the same)."""
    units: dict[str, str] = {}
    fields = [_field_with_units(f, f.name, units) for f in schema]
    info = {'table': kind, 'units': units}
    if root is not None:
        info['root'] = root
    meta = {METADATA_KEY: json.dumps(info).encode()}
    return pa.schema(fields, metadata=meta)


# a figure whose unit is its limit's: a fraction, or m for the hole width (acceptance.failed)
FIGURE_UNIT = '1 (m for max_hole_width)'
NESTED_UNITS = {'acceptance.failed.value': FIGURE_UNIT, 'acceptance.failed.limit': FIGURE_UNIT}


def _field_with_units(f, name, units):
    """`f` with its unit in its metadata (and `units[name]`); a struct's or a list's fields
    each with their own, named `name.field` (`rows.summary.spacing_error_mean`)."""
    kind = f.type
    if pa.types.is_struct(kind):
        kind = pa.struct([_field_with_units(kind.field(i), f'{name}.{kind.field(i).name}', units)
                          for i in range(kind.num_fields)])
        return pa.field(f.name, kind, f.nullable, f.metadata)
    if pa.types.is_list(kind) and (pa.types.is_struct(kind.value_type)
                                   or pa.types.is_list(kind.value_type)):
        item = _field_with_units(kind.value_field, name, units)
        return pa.field(f.name, pa.list_(item), f.nullable, f.metadata)
    if not (_numeric(kind) or pa.types.is_boolean(kind)):
        return f
    unit = NESTED_UNITS.get(name) or unit_of(name)
    if unit is None:
        return f
    units[name] = unit
    return f.with_metadata({**(f.metadata or {}), b'unit': unit.encode()})


def _numeric(kind):
    """A number, a time or a list of them (not a flag, not text)."""
    if pa.types.is_list(kind):
        return _numeric(kind.value_type)
    return pa.types.is_integer(kind) or pa.types.is_floating(kind) or \
        pa.types.is_timestamp(kind)


def units(schema):
    """{column: unit} stored in a table's schema metadata."""
    raw = (schema.metadata or {}).get(METADATA_KEY)
    return json.loads(raw)['units'] if raw else {}


def concat(tables, kind):
    """One table of several (the same columns, or some missing: filled with nulls)."""
    return with_units(pa.concat_tables([t.replace_schema_metadata(None) for t in tables],
                                       promote_options='default'), kind)
