"""The season's two tables as Arrow (pyarrow), built generically from `planter replay --json`.

* `plants`: one row per plant, the column `bag` (the bag's absolute path) then every key of
  the JSON's plant dicts, in their order (PLANT_FIELDS today; a field the model gains is a new
  column without a change here). Values as in the JSON: numbers, null where the JSON has null
  (a non-finite value, e.g. the first plant's spacing).
* `bags`: one row per bag: `bag`, `status` (ok | warnings | failed | error), `reason` (one
  line, null unless failed or error), the re-run key (`file_size`, `file_mtime_ns`,
  `model_version`, `options`), `analysed_at`, `analysis_seconds`, `analysis_cpu_seconds`,
  `plants_file` (the part of the plants dataset holding the bag's rows), then the replay JSON
  without its plants, flattened: nested objects become dotted columns
  (`summary.spacing_error_mean`, `settings.window`, `design.l1`, `messages.joint_states`),
  lists stay lists (`warnings`, `rows` = each row's record and summary).

Column types: numbers are float64 (int64 when every value is an integer), booleans bool, text
string, a column of nulls only float64, anything else as pyarrow infers it. Units (SI; '1' =
dimensionless) go into each field's metadata (`unit`) and into the schema metadata
(`planter_ros` = JSON {"table", "units"}), from UNITS by the column's last dotted part, a
summary statistic (`..._mean`, `_std`, `_max`, `_min`) taking its quantity's unit, the
prediction settings' units from their declarations. A column the table does not know has no
unit.
"""

import json

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
    'analysed_at': 's since the epoch', 'plant_spacing': 'm', 'planting_depth': 'm',
    'nominal_ground_speed': 'm/s',
}
_STATISTICS = ('_mean', '_std', '_max', '_min', '_rms')


def unit_of(column):
    """The unit of a column by its last dotted part, or None."""
    leaf = column.rsplit('.', 1)[-1]
    if column.startswith('messages.'):          # message counts, named after their topics
        return '1'
    if column.startswith('settings.'):
        return _setting_units().get(leaf)
    if leaf in UNITS:
        return UNITS[leaf]
    for suffix in _STATISTICS:
        if leaf.endswith(suffix) and leaf[:-len(suffix)] in UNITS:
            return UNITS[leaf[:-len(suffix)]]
    return None


def _setting_units():
    from planter_ros.config import specs
    from planter_ros.prediction import PredictionSettings
    return {spec.name: spec.unit or '1' for spec in specs(PredictionSettings)}


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
    out = {}
    for name, value in row.items():
        parts = name.split('.')
        node = out
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return out


# columns of text whatever values a table happens to hold (a table where every `reason` is
# null or every `warnings` list is empty keeps their types)
TEXT = ('bag', 'status', 'reason', 'model_version', 'options', 'plants_file')
TEXT_LISTS = ('warnings',)


def column(values, name=''):
    """One column's Python values as a pyarrow array (types: see the module doc)."""
    import pyarrow as pa
    if name in TEXT:
        return pa.array(values, type=pa.string())
    if name in TEXT_LISTS:
        return pa.array(values, type=pa.list_(pa.string()))
    present = [v for v in values if v is not None]
    if all(isinstance(v, bool) for v in present) and present:
        return pa.array(values, type=pa.bool_())
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
        if present and all(isinstance(v, int) for v in present):
            return pa.array(values, type=pa.int64())
        return pa.array(values, type=pa.float64())
    if all(isinstance(v, str) for v in present):
        return pa.array(values, type=pa.string())
    return pa.array(values)


def table_of(rows, kind):
    """An Arrow table of row dicts (columns in first-seen order), units in its metadata."""
    import pyarrow as pa
    names = {}
    for row in rows:
        for name in row:
            names.setdefault(name, None)
    arrays = [column([row.get(name) for row in rows], name) for name in names]
    return with_units(pa.Table.from_arrays(arrays, names=list(names)), kind)


def plants_table(bag, plants):
    """The plants table of one bag: the JSON plant dicts of `planter replay --json`."""
    import pyarrow as pa
    keys = list(plants[0]) if plants else []
    if not plants or any(list(plant) != keys for plant in plants):
        return table_of([{'bag': bag, **plant} for plant in plants], PLANTS)
    table = pa.Table.from_pylist(plants)        # the fast reader when every plant has the
    arrays = [pa.array([bag] * table.num_rows, type=pa.string())]    # same fields
    for array in table.columns:
        arrays.append(array.cast(pa.float64()) if pa.types.is_null(array.type) else array)
    return with_units(pa.Table.from_arrays(arrays, names=['bag', *table.column_names]),
                      PLANTS)


def with_units(table, kind):
    """`table` with each known column's unit in its field metadata and the schema's."""
    import pyarrow as pa
    units = {}
    fields = []
    for f in table.schema:
        unit = unit_of(f.name)
        if unit is not None:
            units[f.name] = unit
            f = f.with_metadata({b'unit': unit.encode()})
        fields.append(f)
    meta = {METADATA_KEY: json.dumps({'table': kind, 'units': units}).encode()}
    return pa.Table.from_arrays(table.columns, schema=pa.schema(fields, metadata=meta))


def units(schema):
    """{column: unit} stored in a table's schema metadata."""
    raw = (schema.metadata or {}).get(METADATA_KEY)
    return json.loads(raw)['units'] if raw else {}


def concat(tables, kind):
    """One table of several (the same columns, or some missing: filled with nulls)."""
    import pyarrow as pa
    return with_units(pa.concat_tables([t.replace_schema_metadata(None) for t in tables],
                                       promote_options='default'), kind)
