"""The as-planted map as ISO 11783-10 task data (ISOXML V4.3), built with the `isoxml` library's
bindings of the standard's schema (xsdata); the binary time log is packed here (numpy/struct),
in the layout its header declares.

A TASKDATA directory (or a .zip holding one, `TASKDATA/...`) with:

* `TASKDATA.XML`: one device (DVC) per machine (row layout), described so that farm software can
  draw the worked area: a device element (DET, type device) for the planter, whose point is the
  device reference point (DRP: the machine's reference point the rows are placed from), with the
  machine's working width; one Section per row with its offsets from the DRP and its working
  width as device properties (DPT), and its process data (DPD, DDIs below); value presentations
  (DVP: mm, m, km/h, %, plants) for people. One Task (TSK, status completed) per recording, with
  its device allocation (DAN), its time (TIM: effective, first to last planting instant, each
  row's totals as DLV values) and its time log (TLG).
* `TLGnnnnn.XML` + `TLGnnnnn.BIN`: the time log. One record per planting instant in time order:
  the instant (TimeStart: ms since midnight and days since 1980-01-01, UTC), the position of the
  DRP at that instant (north and east, int32 in 1e-7 degrees WGS 84; status 6, "estimated (DR)",
  since the machine is placed by dead reckoning between GNSS fixes; 0/0 with status 15, "not
  available", without one) and the process data of the row that planted (below). The plant
  itself is at its row's offsets from that point, turned by the machine's heading (`drp`).

Geometry (ISO 11783-10: X + in the direction of travel, Y + to the right, Z + down; mm): a
row's X is its longitudinal offset, its Y the negative of its lateral offset (REP 103's y is
+ to the left), Z 0 (the planting points on the ground line). A row's working width is the mean
of its gaps to its neighbours across the machine (an edge row: its one gap); the device's is
their sum. A machine of one row has no gap to give a width: its elements have no width.

DDIs (ISO 11783-11 data dictionary; names, units and resolutions as the isoxml library's copy of
it gives them, ranges in RANGES), per row element:

    logged with every plant (TLG)        0x008D Actual Work State (1 = on)
                                         0x0010 Setpoint Spacing Application Rate (mm): the
                                                design spacing in force at that instant
                                         0x0011 Actual Spacing Application Rate (mm)
                                         0x01A5 Actual Seed Spacing Deviation (mm): |spacing − d|,
                                                a magnitude (0..2147483647)
                                         0x018D Actual Speed (mm/s)
                                         0x0052 Application Total Count (plants so far)
    totals of the task (TIM, DLV B)      0x0052 Application Total Count (plants)
                                         0x01A0 Average Seed Singulation Percentage (ppm)
                                         0x01A2 Average Seed Skip Percentage (ppm)
                                         0x01A4 Average Seed Multiple Percentage (ppm)
                                         0x01A8 Average Coefficient of Variation of Seed
                                                Spacing Percentage (ppm)
    properties (DPT)                     0x0086, 0x0087, 0x0088 Device Element Offset X, Y, Z
                                         0x0043 Actual Working Width, 0x0046 Maximum Working
                                                Width (mm)

Singulation, skip and multiple are ISO 7256-1's quality of feed, miss and multiple indices; the
CV is its precision. An undefined value (the first plant's spacing, an index without spacings)
or one outside its DDI's range is not logged. A record counts its plants by its `status` when
the records carry one: an empty cell adds 0, a double 2, anything else 1.

The device's localization label (DVC G) says English, a decimal point, 24-hour time, dates
year-month-day and metric units everywhere (ISO 11783-7's language command bytes, LOCALIZATION),
written as ISOXML writes the 7 bytes: byte 7 first.
"""

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from decimal import Decimal
from functools import lru_cache
import hashlib
import importlib.metadata
import math
from pathlib import Path
import re
import struct
import tempfile
import zipfile

import numpy as np

from planter_ros.output_files import (
    OutputError, atomic_directory, atomic_output, check_directory, check_output)

from . import ExportError
from .runs import ExportRun, RowPlace, utc_datetime

__all__ = ['LOCALIZATION', 'LOGGED', 'PROPERTIES', 'RANGES', 'TOTALS', 'check_path', 'drp',
           'row_widths', 'taskdata', 'write_isoxml']

WORK_STATE = 0x008D
SETPOINT_SPACING = 0x0010
ACTUAL_SPACING = 0x0011
SPACING_DEVIATION = 0x01A5
ACTUAL_SPEED = 0x018D
TOTAL_COUNT = 0x0052
SINGULATION = 0x01A0
SKIP = 0x01A2
MULTIPLE = 0x01A4
CV = 0x01A8
OFFSET_X, OFFSET_Y, OFFSET_Z = 0x0086, 0x0087, 0x0088
ACTUAL_WIDTH, MAXIMUM_WIDTH = 0x0043, 0x0046
LOGGED = (WORK_STATE, SETPOINT_SPACING, ACTUAL_SPACING, SPACING_DEVIATION, ACTUAL_SPEED,
          TOTAL_COUNT)
TOTALS = (TOTAL_COUNT, SINGULATION, SKIP, MULTIPLE, CV)
OFFSETS = (OFFSET_X, OFFSET_Y, OFFSET_Z)
WIDTHS = (ACTUAL_WIDTH, MAXIMUM_WIDTH)
PROPERTIES = OFFSETS + WIDTHS
# each DDI's range in the data dictionary (its integer: the value in its unit over its
# resolution); a value outside it is not written
INT32 = (-2**31, 2**31 - 1)
MAGNITUDE = (0, 2**31 - 1)
PPM = (0, 1_000_000)
RANGES = {WORK_STATE: (0, 3), SETPOINT_SPACING: MAGNITUDE, ACTUAL_SPACING: MAGNITUDE,
          SPACING_DEVIATION: MAGNITUDE, ACTUAL_SPEED: INT32, TOTAL_COUNT: MAGNITUDE,
          SINGULATION: PPM, SKIP: PPM, MULTIPLE: PPM, CV: PPM, OFFSET_X: INT32,
          OFFSET_Y: INT32, OFFSET_Z: INT32, ACTUAL_WIDTH: MAGNITUDE, MAXIMUM_WIDTH: MAGNITUDE}
WORKING = 1                                      # Actual Work State: 01 = enabled/on
# the ISO 7256-1 index behind each average DDI (a fraction; logged in ppm)
QUALITY_OF = {SINGULATION: 'quality_of_feed_index', SKIP: 'miss_index',
              MULTIPLE: 'multiple_index', CV: 'precision'}
# SI -> each data dictionary unit the DDIs above use
SCALE = {'mm': 1e3, 'mm/s': 1e3, 'ppm': 1e6, '#': 1.0, 'n.a.': 1.0}
# what a farm-management system shows as each process data's or property's name (designator)
DESIGNATORS = {WORK_STATE: 'work state', SETPOINT_SPACING: 'design spacing',
               ACTUAL_SPACING: 'plant spacing', SPACING_DEVIATION: 'spacing error (size)',
               ACTUAL_SPEED: 'ground speed', TOTAL_COUNT: 'plants',
               SINGULATION: 'quality of feed (ISO 7256-1)', SKIP: 'miss index (ISO 7256-1)',
               MULTIPLE: 'multiple index (ISO 7256-1)', CV: 'precision, CV (ISO 7256-1)',
               OFFSET_X: 'offset X (forward)', OFFSET_Y: 'offset Y (right)',
               OFFSET_Z: 'offset Z (down)', ACTUAL_WIDTH: 'working width',
               MAXIMUM_WIDTH: 'maximum working width'}
# value presentations for people (DVP: unit, scale from the DDI's integer, decimals) and the
# one each DDI is shown with
PRESENTATIONS = {'mm': ('mm', 1.0, 0), 'm': ('m', 0.001, 3), 'km/h': ('km/h', 0.0036, 2),
                 '%': ('%', 0.0001, 1), 'plants': ('plants', 1.0, 0)}
SHOWN_AS = {SETPOINT_SPACING: 'mm', ACTUAL_SPACING: 'mm', SPACING_DEVIATION: 'mm',
            ACTUAL_SPEED: 'km/h', TOTAL_COUNT: 'plants', SINGULATION: '%', SKIP: '%',
            MULTIPLE: '%', CV: '%', OFFSET_X: 'm', OFFSET_Y: 'm', OFFSET_Z: 'm',
            ACTUAL_WIDTH: 'm', MAXIMUM_WIDTH: 'm'}
# ISO 11783-7's language command, as a device's localization label: language code 'en';
# decimal point (01) and 24-hour time (00), the low 4 bits reserved (1111); dates year-month-day
# (4); metric distance, area, volume, mass (byte 5) and temperature, pressure, force, generic
# units (byte 6); byte 7 reserved (FF)
LOCALIZATION = b'en' + bytes([0b01_00_1111, 4, 0x00, 0x00, 0xFF])
PLANTS_BY_STATUS = {'empty': 0, 'double': 2}     # plants a record adds (others: 1)
TRIGGER_ON_CHANGE, TRIGGER_TOTAL = 8, 16         # DPD trigger methods (bit field)
PROPERTY_DEFAULT_SET = 1                         # DPD property: in the default data set
STATUS_ESTIMATED, STATUS_NOT_AVAILABLE = 6, 15   # PTN position status
EPOCH_1980 = datetime(1980, 1, 1, tzinfo=timezone.utc).timestamp()
DAY_MS = 86_400_000
MAX_DAYS = 65_534                                # uint16 days, 0xFFFF reserved
MAX_DLVS = 255                                   # DLV index is one byte
DEGREE_STEP = 1e-7                               # the binary position's resolution
TASKDATA = 'TASKDATA.XML'
FILE_NAME = re.compile(r'(TASKDATA\.XML|TLG\d{5}\.(XML|BIN))', re.IGNORECASE)


@lru_cache(maxsize=None)
def _dd(ddi):
    """The data dictionary entity (name, unit, resolution) of a DDI, from the isoxml library."""
    from isoxml.models.ddi_entities import DDEntity  # lazy: 50 ms, only for ISOXML
    return DDEntity.from_id(ddi)


def dd_value(ddi, value):
    """An SI value (m, m/s, a fraction, a count) as the DDI's integer: in its data dictionary
    unit over its resolution; None for an undefined value or one outside the DDI's range."""
    if value is None or not math.isfinite(value):
        return None
    entity = _dd(ddi)
    number = int(round(value * SCALE[entity.unit] / entity.bit_resolution))
    low, high = RANGES[ddi]
    return number if low <= number <= high else None


def localization_label():
    """LOCALIZATION as ISOXML's DVC G holds it: the 7 bytes as hex, byte 7 first (as task
    controllers and FMIS write it: 'FF000000406564' is German)."""
    return LOCALIZATION[::-1].hex().upper()


def check_path(path, option):
    """Refuse (OutputError) an ISOXML output that cannot be written: a .zip as check_output
    does; a directory that exists and holds anything but files of an earlier export
    (TASKDATA.XML, TLGnnnnn.XML/.BIN), is not writable, or whose parent is missing or
    read-only. Returns a Path."""
    if path is None or str(path) == '':
        raise OutputError(f'{option} is empty: allowed a directory or a file name ending in '
                          '.zip')
    path = Path(path)
    if path.suffix.lower() == '.zip' and not path.is_dir():
        return check_output(path, option, ('.zip',))
    if path.exists() or path.is_symlink():
        if not path.is_dir() or path.is_symlink():
            raise OutputError(f'{option} = {path} exists and is not a directory: allowed a '
                              'new directory, one of an earlier ISOXML export, or a .zip')
        others = [e.name for e in path.iterdir() if not (e.is_file() and FILE_NAME.fullmatch(
            e.name))]
        if others:
            raise OutputError(f'{option} = {path} holds other files ({others[0]}): allowed a '
                              'new directory, one of an earlier ISOXML export, or a .zip')
        check_directory(path, option)
    check_directory(path.parent if str(path.parent) else Path('.'), option, path)
    return path


@dataclass
class _Layout:
    """A device: the rows of one machine and their places, its element ids and NAME."""

    device_id: str
    rows: tuple                  # (index, name)
    places: dict                 # row index -> runs.RowPlace
    elements: dict               # 'device' and each row index -> DET id number
    name: bytes                  # the ISO 11783-5 NAME (8 bytes)


def _device_name(machine):
    """An ISO 11783-5 NAME for a machine that is not on an ISOBUS: self-configurable address,
    industry group 2 (agricultural), device class 4 (planters/seeders), function 255 (not
    available), no manufacturer code, identity number from the machine (rows and places)."""
    identity = int.from_bytes(hashlib.sha256(repr(machine).encode()).digest()[:4], 'big') \
        & 0x1FFFFF
    value = (1 << 63) | (2 << 60) | (4 << 49) | (255 << 40) | identity
    return value.to_bytes(8, 'big')


def row_widths(places):
    """{row index: working width (m)} of the enabled rows of `places` ({index: RowPlace}): the
    mean of a row's gaps to its neighbours across the machine (an edge row: its one gap);
    empty for a machine of fewer than two rows (no gap gives a width)."""
    across = sorted((place.lateral, row) for row, place in places.items() if place.enabled)
    if len(across) < 2:
        return {}
    gaps = [b[0] - a[0] for a, b in zip(across, across[1:])]
    widths = {}
    for k, (_, row) in enumerate(across):
        near = gaps[max(k - 1, 0):k + 1]
        widths[row] = sum(near) / len(near)
    return widths


def _device(iso, layout, number):
    """The DVC of a layout: the planter (DET, type device: the DRP, with the machine's width)
    and one Section per row (its offsets and width as DPT, its process data as DPD), each
    referenced from its element (DOR); the DVPs they are shown with."""
    version = _version()
    ids = iter(range(len(layout.rows) + 2, 65535))       # after the elements' object ids
    shown = {name: next(ids) for name in PRESENTATIONS}
    properties, process_data = [], []

    def prop(ddi, value):
        properties.append(iso.DeviceProperty(
            object_id=next(ids), ddi=ddi.to_bytes(2, 'big'), value=dd_value(ddi, value),
            designator=DESIGNATORS[ddi],
            device_value_presentation_object_id=shown[SHOWN_AS[ddi]]))
        return iso.DeviceObjectReference(device_object_id=properties[-1].object_id)

    widths = row_widths(layout.places)
    machine = [prop(ddi, sum(widths.values())) for ddi in WIDTHS] if widths else []
    elements = [iso.DeviceElement(id=f'DET{layout.elements["device"]}', object_id=1,
                                  type=iso.DeviceElementType.Device,
                                  designator='planter', number=0, parent_object_id=0,
                                  device_object_references=machine)]
    for k, (row, name) in enumerate(layout.rows):
        place = layout.places.get(row)
        refs = [prop(OFFSET_X, place.longitudinal if place else 0.0),
                prop(OFFSET_Y, -place.lateral if place else 0.0),   # ISO: + to the right
                prop(OFFSET_Z, 0.0)]
        refs += [prop(ddi, widths[row]) for ddi in WIDTHS if row in widths]
        for ddi in dict.fromkeys(LOGGED + TOTALS):
            trigger = TRIGGER_TOTAL if ddi in TOTALS and ddi not in LOGGED else \
                TRIGGER_ON_CHANGE | (TRIGGER_TOTAL if ddi == TOTAL_COUNT else 0)
            process_data.append(iso.DeviceProcessData(
                object_id=next(ids), ddi=ddi.to_bytes(2, 'big'),
                property=PROPERTY_DEFAULT_SET, trigger_methods=trigger,
                designator=DESIGNATORS[ddi],
                device_value_presentation_object_id=(
                    shown.get(SHOWN_AS[ddi]) if ddi in SHOWN_AS else None)))
            refs.append(iso.DeviceObjectReference(device_object_id=process_data[-1].object_id))
        elements.append(iso.DeviceElement(
            id=f'DET{layout.elements[row]}', object_id=k + 2, type=iso.DeviceElementType.Section,
            designator=(name or 'row')[:32], number=k + 1,
            parent_object_id=1, device_object_references=refs))
    presentations = [iso.DeviceValuePresentation(object_id=shown[key], offset=0,
                                                 scale=Decimal(str(scale)),
                                                 number_of_decimals=decimals,
                                                 unit_designator=unit)
                     for key, (unit, scale, decimals) in PRESENTATIONS.items()]
    structure = hashlib.sha256(repr((layout.rows, sorted(layout.places.items()))).encode())
    return iso.Device(id=layout.device_id, designator=f'planter_ros planter {number}'[:32],
                      software_version=version, client_name=layout.name,
                      structure_label=''.join(str(int(c, 16) % 10)
                                              for c in structure.hexdigest()[:14]),
                      localization_label=localization_label(), elements=elements,
                      properties=properties, process_data=process_data,
                      value_presentations=presentations)


def _version():
    try:
        return importlib.metadata.version('planter_ros')
    except importlib.metadata.PackageNotFoundError:
        return 'unknown'


# a run's machine: its rows (index, name) and their places ((index, RowPlace), by index)
_Machine = tuple[tuple[tuple[int, str], ...], tuple[tuple[int, RowPlace], ...]]


def _machine(run: ExportRun) -> _Machine:
    """What makes a run's machine one device: its rows and their places."""
    return tuple(run.rows), tuple(sorted(run.places.items()))


def _layouts(runs: Sequence[ExportRun]) -> dict[_Machine, _Layout]:
    """One _Layout per distinct machine of the runs, element ids numbered across them."""
    layouts: dict[_Machine, _Layout] = {}
    next_element = 1
    for run in runs:
        machine = _machine(run)
        if machine in layouts:
            continue
        rows = tuple(run.rows)
        elements: dict[str | int, int] = {'device': next_element}
        for k, (row, _) in enumerate(rows):
            elements[row] = next_element + 1 + k
        next_element += 1 + len(rows)
        layouts[machine] = _Layout(f'DVC{len(layouts) + 1}', rows, dict(run.places), elements,
                                   _device_name(machine))
    return layouts


def drp(records, places):
    """(latitude, longitude) in degrees of the device reference point (the machine's
    reference point) at each record's instant: the plant moved back by its row's place on the
    machine, turned by the machine's heading (on the WGS 84 ellipsoid, pyproj); None where
    the plant has no map position, or no heading and a row off the reference point."""
    from pyproj import Geod  # lazy: 80 ms, loaded only by a run that writes ISOXML
    n = len(records)
    lat = np.array([np.nan if r.get('latitude') is None else r['latitude'] for r in records])
    lon = np.array([np.nan if r.get('longitude') is None else r['longitude'] for r in records])
    heading = np.array([np.nan if r.get('heading') is None else r['heading'] for r in records])
    left = np.array([getattr(places.get(r['row']), 'lateral', 0.0) for r in records])
    ahead = np.array([getattr(places.get(r['row']), 'longitudinal', 0.0) for r in records])
    # the plant -> DRP vector east, north: −R(heading)·(ahead, left)
    c, s = np.cos(heading), np.sin(heading)
    east, north = -(c * ahead - s * left), -(s * ahead + c * left)
    at_drp = (left == 0.0) & (ahead == 0.0)
    east, north = np.where(at_drp, 0.0, east), np.where(at_drp, 0.0, north)
    ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(east) & np.isfinite(north)
    out_lat, out_lon = np.full(n, np.nan), np.full(n, np.nan)
    if ok.any():
        azimuth = np.degrees(np.arctan2(east[ok], north[ok]))
        out_lon[ok], out_lat[ok], _ = Geod(ellps='WGS84').fwd(
            lon[ok], lat[ok], azimuth, np.hypot(east[ok], north[ok]))
    return [(None, None) if not k else (float(a), float(b))
            for k, a, b in zip(ok, out_lat, out_lon)]


def _ordered(run):
    """The run's records in time order (stable: a row's plants keep their order)."""
    return sorted(run.records, key=lambda r: (r['time'] if r.get('time') is not None
                                              else math.inf))


def _time_start(seconds):
    """(ms since midnight, days since 1980-01-01), UTC."""
    total = int(round((seconds - EPOCH_1980) * 1000.0))
    days, ms = divmod(total, DAY_MS)
    return ms, days


def check_run(run):
    """ExportError if the run cannot be a task: a plant without a time, a time the binary log
    cannot hold (before 1980-01-01 or after 2159), too many rows for one log."""
    header = len(run.rows) * len(LOGGED)
    if header > MAX_DLVS:
        raise ExportError(f'{run.key}: {len(run.rows)} rows log {header} values: an ISOXML '
                          f'time log holds at most {MAX_DLVS} (at most '
                          f'{MAX_DLVS // len(LOGGED)} rows)')
    for record in run.records:
        t = record.get('time')
        if t is None or not math.isfinite(t):
            raise ExportError(f'{run.key}: plant {record.get("index")} of row '
                              f'{record.get("row")} has no time: an ISOXML time log needs one')
        days = _time_start(t)[1]
        if not 0 <= days <= MAX_DAYS:
            raise ExportError(f'{run.key}: plant time {t:.3f} s is not a UTC time from '
                              '1980-01-01 to 2159-06-06: allowed a recording whose clock is '
                              'UTC (ROS time on a machine)')


def time_log(run, layout):
    """(TIM header, binary data, totals {row: plants}) of the run's time log."""
    import isoxml.models.base.v4 as iso  # lazy: 50 ms, loaded only by a run that writes ISOXML
    values = []                       # (row, ddi) of each DLV, its index in the header
    for row, _ in layout.rows:
        values += [(row, ddi) for ddi in LOGGED]
    index = {v: i for i, v in enumerate(values)}
    # ISO 11783-10's time log header: an attribute there but empty ('') says "each record in
    # the binary file holds this value"; isoxml's models type these attributes as values only
    header = iso.Time(
        start='',  # type: ignore[arg-type]  # '': in the binary file (above)
        type=iso.TimeType.Effective,
        positions=[iso.Position(
            north='',  # type: ignore[arg-type]  # '': in the binary file (above)
            east='',  # type: ignore[arg-type]  # '': in the binary file (above)
            status='')],  # type: ignore[arg-type]  # '': in the binary file (above)
        data_log_values=[iso.DataLogValue(
            process_data_ddi=ddi.to_bytes(2, 'big'),
            process_data_value='',  # type: ignore[arg-type]  # '': in the binary file (above)
            device_element_id_ref=f'DET{layout.elements[row]}') for row, ddi in values])
    counts = {row: 0 for row, _ in layout.rows}
    records = _ordered(run)
    data = bytearray()
    for record, (lat, lon) in zip(records, drp(records, layout.places)):
        row = record['row']
        counts[row] += PLANTS_BY_STATUS.get(record.get('status'), 1)
        ms, days = _time_start(record['time'])
        if lat is None:
            north, east, status = 0, 0, STATUS_NOT_AVAILABLE
        else:
            north, east = int(round(lat / DEGREE_STEP)), int(round(lon / DEGREE_STEP))
            status = STATUS_ESTIMATED
        error = record.get('spacing_error')
        logged = {WORK_STATE: dd_value(WORK_STATE, WORKING),
                  SETPOINT_SPACING: dd_value(SETPOINT_SPACING, record.get('design_spacing')),
                  ACTUAL_SPACING: dd_value(ACTUAL_SPACING, record.get('spacing')),
                  SPACING_DEVIATION: dd_value(SPACING_DEVIATION,
                                              None if error is None else abs(error)),
                  ACTUAL_SPEED: dd_value(ACTUAL_SPEED, record.get('ground_speed')),
                  TOTAL_COUNT: dd_value(TOTAL_COUNT, counts[row])}
        pairs = [(index[(row, ddi)], v) for ddi, v in logged.items() if v is not None]
        data += struct.pack(f'<IHiiBB{"Bi" * len(pairs)}', ms, days, north, east, status,
                            len(pairs), *[x for pair in pairs for x in pair])
    return header, bytes(data), counts


def _task_time(iso, run, layout, counts):
    """The task's TIM: effective, first to last planting instant, each row's totals."""
    # lazy: xsdata comes with isoxml (50 ms), loaded only by a run that writes ISOXML
    from xsdata.models.datatype import XmlDateTime
    times = [r['time'] for r in run.records]
    totals = []
    for row, _ in layout.rows:
        quality = run.row_quality.get(row) or {}
        row_values = {TOTAL_COUNT: dd_value(TOTAL_COUNT, counts[row])}
        for ddi, key in QUALITY_OF.items():
            value = dd_value(ddi, quality.get(key))
            if value is not None:
                row_values[ddi] = value
        totals += [iso.DataLogValue(process_data_ddi=ddi.to_bytes(2, 'big'),
                                    process_data_value=v,
                                    device_element_id_ref=f'DET{layout.elements[row]}')
                   for ddi, v in row_values.items()]
    return iso.Time(start=XmlDateTime.from_datetime(utc_datetime(min(times))),
                    stop=XmlDateTime.from_datetime(utc_datetime(max(times))),
                    type=iso.TimeType.Effective, data_log_values=totals)


def taskdata(runs):
    """The task data of `runs` (export.runs.ExportRun): (ISO11783_TaskData, {file name: bytes
    or header}, tasks, records logged, skipped [(key, reason)]). A run without plants is no
    task; a run check_run refuses is skipped with its reason."""
    import isoxml.models.base.v4 as iso  # lazy: 50 ms, loaded only by a run that writes ISOXML
    usable, skipped = [], []
    for run in runs:
        if not run.records:
            continue
        try:
            check_run(run)
        except ExportError as exc:
            skipped.append((run.key, str(exc)))
            continue
        usable.append(run)
    layouts = _layouts(usable)
    files, tasks = {}, []
    for number, run in enumerate(usable, start=1):
        layout = layouts[_machine(run)]
        name = f'TLG{number:05d}'
        header, data, counts = time_log(run, layout)
        files[f'{name}.XML'], files[f'{name}.BIN'] = header, data
        tasks.append(iso.Task(
            id=f'TSK{number}', designator=run.key[-32:], status=iso.TaskStatus.Completed,
            device_allocations=[iso.DeviceAllocation(client_name_value=layout.name,
                                                     device_id_ref=layout.device_id)],
            times=[_task_time(iso, run, layout, counts)],
            time_logs=[iso.TimeLog(filename=name, filelength=len(data),
                                   type=iso.TimeLogType.BinaryTimelogFileType1)]))
    version = _version()
    root = iso.Iso11783TaskData(
        version_minor=iso.Iso11783TaskDataVersionMinor.VALUE_3,
        management_software_manufacturer='planter_ros', management_software_version=version,
        task_controller_manufacturer='planter_ros', task_controller_version=version,
        data_transfer_origin=iso.Iso11783TaskDataDataTransferOrigin.MICS,
        devices=[_device(iso, layout, n) for n, layout in enumerate(layouts.values(), 1)],
        tasks=tasks)
    return root, files, len(tasks), sum(run.plants for run in usable), skipped


def _write_files(directory, root, files):
    from isoxml.util.isoxml_io import isoxml_to_text  # lazy: 50 ms, only for ISOXML
    (directory / TASKDATA).write_text(isoxml_to_text(root), encoding='utf-8')
    for name, content in files.items():
        if isinstance(content, bytes):
            (directory / name).write_bytes(content)
        else:
            (directory / name).write_text(isoxml_to_text(content), encoding='utf-8')


def write_isoxml(path, runs):
    """Write the task data of `runs` at `path` (a directory, or a .zip holding TASKDATA/),
    atomically. Returns (tasks, records logged, skipped [(key, reason)])."""
    root, files, tasks, logged, skipped = taskdata(runs)
    path = Path(path)
    if path.suffix.lower() == '.zip' and not path.is_dir():
        with tempfile.TemporaryDirectory(dir=path.parent, prefix=f'.{path.name}.') as work:
            _write_files(Path(work), root, files)
            with atomic_output(path) as tmp:
                with zipfile.ZipFile(tmp, 'w', zipfile.ZIP_DEFLATED) as archive:
                    for file in sorted(Path(work).iterdir()):
                        archive.write(file, f'TASKDATA/{file.name}')
    else:
        with atomic_directory(path) as tmp:
            _write_files(tmp, root, files)
    return tasks, logged, skipped
