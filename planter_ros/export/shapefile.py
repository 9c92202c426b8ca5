"""The as-planted map as an ESRI Shapefile: one Point per plant, WGS 84, written with pyshp.

The set: `.shp` (points, longitude/latitude in degrees), `.shx` (its index), `.dbf` (the
attribute table), `.prj` (WGS 84 as ESRI WKT, from pyproj), `.cpg` (`UTF-8`, the DBF's text
encoding). A `.zip` path holds the set (named after the zip, `plants.zip` -> `plants.shp`, ...)
in one file, which web farm-management uploads take; a `.shp` path writes the set next to it.

Attributes (DBF names are at most 10 characters): ATTRIBUTES maps each plant record key
(export.runs) to its column, in this order; a key not listed (a field the records gain later)
becomes a column named by its first 10 characters (made unique), typed by its values (text,
number, true/false). `bag` (the recording) and `utc` (the planting instant, ISO 8601 UTC) are
added to every plant. Undefined values are null as GDAL (and so QGIS, pyogrio, GeoPandas) reads
them: a numeric cell is filled with '*' (pyshp's undefined number), a logical cell holds '?'
(dBASE's unknown: a blank logical, which pyshp writes for None, reads as False in GDAL, so the
cells are set after pyshp wrote the table, `_null_logicals`), a text cell is empty (GDAL reads
null, pyshp ''). A plant without a map position is a Null shape (the Shapefile's own "no
geometry"), like GeoJSON's null geometry.
"""

from dataclasses import dataclass
import math
from pathlib import Path
import tempfile
import zipfile

from planter_ros.output_files import atomic_output, atomic_outputs, check_output

from . import ExportError
from .runs import utc_text

__all__ = ['ATTRIBUTES', 'Attribute', 'SIDECARS', 'check_path', 'write_shapefile']


@dataclass(frozen=True)
class Attribute:
    """One DBF column: the record key it holds, its DBF name, type (C text, N number, L
    logical), width and decimals, unit and meaning (doc/exports.md lists them)."""

    key: str
    name: str
    kind: str
    size: int = 0            # C: widened to the longest value (at most 254 bytes)
    decimals: int = 0
    unit: str = ''
    text: str = ''


ATTRIBUTES = (
    Attribute('bag', 'bag', 'C', text='the recording (file name, or path from the analysed '
              'root)'),
    Attribute('row', 'row', 'N', 5, 0, '1', "the planting unit's index in the machine's rows"),
    Attribute('row_name', 'row_name', 'C', text="the row's name (empty: a one-row machine)"),
    Attribute('index', 'index', 'N', 10, 0, '1', "the plant's number in its row (0, 1, ...)"),
    Attribute('time', 'time_s', 'N', 20, 6, 's', 'planting instant, s since 1970-01-01 UTC '
              "(the recording's clock)"),
    Attribute('utc', 'utc', 'C', 24, text='the same instant, ISO 8601 UTC'),
    Attribute('spacing', 'spacing_m', 'N', 16, 6, 'm', 'distance to the previous seedling of '
              'the row along its travelled path (null for the first of a sequence and for an '
              'empty cup)'),
    Attribute('spacing_error', 'sp_err_m', 'N', 16, 6, 'm', 'spacing minus the design spacing'),
    Attribute('design_spacing', 'design_m', 'N', 16, 6, 'm', 'the design spacing d in force at '
              'the planting instant (a spacing change or a cam schedule changes it)'),
    Attribute('hole_width', 'hole_w_m', 'N', 16, 6, 'm', 'the hole along the row: tip sweep + '
              'nozzle width'),
    Attribute('tilt', 'tilt_rad', 'N', 12, 6, 'rad', 'stem from vertical, + leaning forward'),
    Attribute('upright', 'upright', 'L', text="stem's angle to the ground >= the upright "
              'threshold'),
    Attribute('ground_speed', 'speed_mps', 'N', 12, 6, 'm/s', 'ground speed at the planting '
              'instant'),
    Attribute('status', 'status', 'C', text='planted, empty, double or unknown (when the '
              'records carry it)'),
    Attribute('reason', 'reason', 'C', text='why the status is what it is'),
    Attribute('input_gap', 'input_gap', 'L', text='the instant fell in a gap of the inputs '
              '(position interpolated; hole, tilt, upright unknown)'),
)
LATER = ('status', 'reason', 'input_gap')  # keys records gain with a seedling sensor
# record keys that place the point, not attributes (the machine's heading is in the Parquet
# plants table and places the ISOXML time log's machine)
GEOMETRY = ('longitude', 'latitude', 'heading')
SIDECARS = ('.shx', '.dbf', '.prj', '.cpg')
STALE = ('.qix', '.sbn', '.sbx')           # spatial indexes other programs build from a .shp
MAX_TEXT = 254                             # bytes in a DBF text cell
NAME_LENGTH = 10                           # characters in a DBF field name
MAX_FILE = 2**31 - 1                       # bytes in a .shp or .dbf (32-bit offsets, signed)
ENCODING = 'utf-8'


def check_path(path, option):
    """Refuse (OutputError) a Shapefile path that cannot be written: not .shp or .zip, or (for
    .shp) a sidecar of the set that exists and is not a writable regular file. Returns a
    Path."""
    path = check_output(path, option, ('.shp', '.zip'))
    if path.suffix.lower() == '.shp':
        for suffix in SIDECARS:
            check_output(path.with_suffix(suffix), option, (suffix,))
    return path


def attributes_of(records):
    """The columns of `records` (ATTRIBUTES' order, then unknown keys as they first appear):
    [(Attribute, size)] with text widths fitted to the values (no records: today's
    columns)."""
    known = {a.key: a for a in ATTRIBUTES}
    keys: dict[str, None] = {}       # in the order they first appear
    for record in records:
        for key in record:
            keys.setdefault(key, None)
    present = [a for a in ATTRIBUTES if a.key in keys or (not records and a.key not in LATER)]
    taken = {a.name.lower() for a in ATTRIBUTES}
    extra = []
    for key in keys:
        if key in known or key in GEOMETRY:
            continue
        name = _unique_name(key, taken)
        taken.add(name.lower())
        extra.append(_attribute_for(key, name, [r.get(key) for r in records]))
    columns = []
    for attribute in present + extra:
        size = attribute.size
        if attribute.kind == 'C':
            longest = max((len(_text(r.get(attribute.key)).encode(ENCODING)) for r in records),
                          default=0)
            size = min(MAX_TEXT, max(size, longest, 1))
        columns.append((attribute, size))
    return columns


def _unique_name(key, taken):
    name = ''.join(c if c.isalnum() or c == '_' else '_' for c in key)[:NAME_LENGTH] or 'field'
    n = 1
    while name.lower() in taken:
        suffix = f'_{n}'
        name = name[:NAME_LENGTH - len(suffix)] + suffix
        n += 1
    return name


def _attribute_for(key, name, values):
    present = [v for v in values if v is not None]
    if present and all(isinstance(v, bool) for v in present):
        return Attribute(key, name, 'L')
    if present and all(isinstance(v, int) and not isinstance(v, bool) for v in present):
        return Attribute(key, name, 'N', 19, 0)
    if present and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       for v in present):
        return Attribute(key, name, 'N', 24, 9)
    return Attribute(key, name, 'C')


def _text(value):
    return '' if value is None else str(value)


def _cell(attribute, size, value):
    if value is None:
        return '' if attribute.kind == 'C' else None
    if attribute.kind == 'C':
        raw = str(value).encode(ENCODING)[:size]
        return raw.decode(ENCODING, errors='ignore')     # cut at a character boundary
    if attribute.kind == 'L':
        return bool(value)
    value = float(value)
    if not math.isfinite(value):
        return None
    return int(round(value)) if attribute.decimals == 0 else value


UNKNOWN_LOGICAL = b'?'                     # dBASE's null of a logical cell
DBF_HEADER, DBF_FIELD = 32, 32             # bytes of the table header, of a field descriptor


def _null_logicals(dbf, columns, records):
    """Set every undefined logical cell of the written table `dbf` to '?' (module doc): the
    cells' places from the table's own header and field descriptors."""
    logical = [(k, a) for k, (a, _) in enumerate(columns) if a.kind == 'L']
    nulls = [(k, i) for k, a in logical for i, r in enumerate(records) if r.get(a.key) is None]
    if not nulls:
        return
    with open(dbf, 'r+b') as f:
        head = f.read(DBF_HEADER)
        header_length = int.from_bytes(head[8:10], 'little')
        record_length = int.from_bytes(head[10:12], 'little')
        offsets, at = [], 1                    # byte 0 of a record: its deletion flag
        for _ in columns:
            offsets.append(at)
            at += f.read(DBF_FIELD)[16]        # the field's length
        if at != record_length:
            raise ExportError(f'{dbf}: the attribute table has {record_length}-byte records, '
                              f'its fields {at} bytes: not a table this writer can mark')
        for k, i in nulls:
            f.seek(header_length + i * record_length + offsets[k])
            f.write(UNKNOWN_LOGICAL)


def prj_text():
    """WGS 84 (EPSG:4326) as the ESRI WKT a .prj holds."""
    from pyproj import CRS  # lazy: 80 ms, loaded only by a run that writes a Shapefile
    from pyproj.enums import WktVersion  # lazy: with pyproj, above
    return CRS.from_epsg(4326).to_wkt(WktVersion.WKT1_ESRI)


def _write_set(shp, shx, dbf, prj, cpg, runs):
    """The set's five files at the given paths; returns (plants, placed)."""
    import shapefile  # lazy: pyshp, 40 ms,, loaded only by a run that writes a Shapefile
    records = [dict(record, bag=run.key, utc=utc_text(record.get('time')))
               for run in runs for record in run.records]
    columns = attributes_of(records)
    record_bytes = 1 + sum(1 if a.kind == 'L' else size for a, size in columns)
    dbf_bytes = 33 + 32 * len(columns) + record_bytes * len(records)
    if dbf_bytes > MAX_FILE:
        raise ExportError(f'{len(records)} plants of {record_bytes} bytes each make a '
                          f'{dbf_bytes / 2**30:.1f} GiB attribute table: a Shapefile holds at '
                          'most 2 GiB per file (export fewer bags at a time)')
    placed = 0
    with open(shp, 'wb') as f_shp, open(shx, 'wb') as f_shx, open(dbf, 'wb') as f_dbf:
        # (autoBalance: a write that fails between a point and its record still closes)
        writer = shapefile.Writer(shp=f_shp, shx=f_shx, dbf=f_dbf, shapeType=shapefile.POINT,
                                  encoding=ENCODING, autoBalance=True)
        with writer:          # (its __enter__ is typed as its base class's: `as` loses Writer)
            for attribute, size in columns:
                if attribute.kind == 'L':
                    writer.field(attribute.name, 'L')
                else:
                    writer.field(attribute.name, attribute.kind, size, attribute.decimals)
            for record in records:
                lon, lat = record.get('longitude'), record.get('latitude')
                if lon is None or lat is None:
                    writer.null()
                else:
                    writer.point(lon, lat)
                    placed += 1
                writer.record(*[_cell(a, size, record.get(a.key)) for a, size in columns])
    _null_logicals(dbf, columns, records)
    Path(prj).write_text(prj_text(), encoding='ascii')
    Path(cpg).write_text('UTF-8', encoding='ascii')
    return len(records), placed


def write_shapefile(path, runs):
    """Write the plants of `runs` (export.runs.ExportRun) as a Shapefile at `path` (.shp: the
    set next to it; .zip: the set in one archive), atomically. Returns (plants, placed)."""
    path = Path(path)
    if path.suffix.lower() == '.zip':
        with tempfile.TemporaryDirectory(dir=path.parent, prefix=f'.{path.name}.') as work:
            names = [Path(work) / f'{path.stem}{s}' for s in ('.shp',) + SIDECARS]
            shp, shx, dbf, prj, cpg = names
            counts = _write_set(shp, shx, dbf, prj, cpg, runs)
            with atomic_output(path) as tmp:
                with zipfile.ZipFile(tmp, 'w', zipfile.ZIP_DEFLATED) as archive:
                    for name in names:
                        archive.write(name, name.name)
        return counts
    paths = [path.with_suffix(s) for s in SIDECARS] + [path]      # the .shp renamed last
    with atomic_outputs(paths) as tmp:
        shx, dbf, prj, cpg, shp = tmp
        counts = _write_set(shp, shx, dbf, prj, cpg, runs)
    for suffix in STALE:                     # an index of the old points would misplace them
        stale = path.with_suffix(suffix)
        if stale.is_file():
            stale.unlink()
    return counts

