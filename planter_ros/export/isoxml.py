"""The as-planted map as ISO 11783-10 task data (ISOXML V4.3), built with the `isoxml` library's
bindings of the standard's schema (xsdata); the binary time log is packed here (numpy/struct),
in the layout its header declares.

A TASKDATA directory (or a .zip holding one, `TASKDATA/...`) with:

* `TASKDATA.XML`: one device (DVC) per row layout of the machine, a device element (DET) for
  the planter and one Section per row, each row's process data (DPD, DDIs below); one Task
  (TSK, status completed) per recording, with its device allocation (DAN), its time (TIM:
  effective, first to last planting instant, each row's totals as DLV values) and its time log
  (TLG).
* `TLGnnnnn.XML` + `TLGnnnnn.BIN`: the time log. One record per planting instant in time order:
  the instant (TimeStart: ms since midnight and days since 1980-01-01, UTC), the plant's own
  position (north and east, int32 in 1e-7 degrees WGS 84; status 6, "estimated (DR)", since a
  plant is placed by dead reckoning between GNSS fixes; 0/0 with status 15, "not available",
  for a plant without a map position) and its row's process data (below). A record's position
  is the plant, not the machine, so the row elements carry no offsets.

DDIs (ISO 11783-11 data dictionary; names, units and resolutions as the isoxml library's copy of
it gives them), per row element:

    logged with every plant (TLG)        0x008D Actual Work State (1)
                                         0x0010 Setpoint Spacing Application Rate (mm)
                                         0x0011 Actual Spacing Application Rate (mm)
                                         0x01A5 Actual Seed Spacing Deviation (mm)
                                         0x018D Actual Speed (mm/s)
                                         0x0052 Application Total Count (plants so far)
    totals of the task (TIM, DLV B)      0x0052 Application Total Count (plants)
                                         0x01A0 Average Seed Singulation Percentage (ppm)
                                         0x01A2 Average Seed Skip Percentage (ppm)
                                         0x01A4 Average Seed Multiple Percentage (ppm)
                                         0x01A8 Average Coefficient of Variation of Seed
                                                Spacing Percentage (ppm)

Singulation, skip and multiple are ISO 7256-1's quality of feed, miss and multiple indices; the
CV is its precision. An undefined value (the first plant's spacing, an index without spacings)
is not logged. A record counts its plants by its `status` when the records carry one: an empty
cell adds 0, a double 2, anything else 1.
"""

from dataclasses import dataclass
from datetime import datetime, timezone
from functools import lru_cache
import hashlib
import math
from pathlib import Path
import re
import struct

from . import ExportError
from .runs import utc_datetime

__all__ = ['LOGGED', 'TOTALS', 'check_path', 'taskdata', 'write_isoxml']

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
LOGGED = (WORK_STATE, SETPOINT_SPACING, ACTUAL_SPACING, SPACING_DEVIATION, ACTUAL_SPEED,
          TOTAL_COUNT)
TOTALS = (TOTAL_COUNT, SINGULATION, SKIP, MULTIPLE, CV)
# the ISO 7256-1 index behind each average DDI (a fraction; logged in ppm)
QUALITY_OF = {SINGULATION: 'quality_of_feed_index', SKIP: 'miss_index',
              MULTIPLE: 'multiple_index', CV: 'precision'}
# SI -> each data dictionary unit the DDIs above use
SCALE = {'mm': 1e3, 'mm/s': 1e3, 'ppm': 1e6, '#': 1.0, 'n.a.': 1.0}
# what a farm-management system shows as each process data's name (DPD designator)
DESIGNATORS = {WORK_STATE: 'work state', SETPOINT_SPACING: 'design spacing',
               ACTUAL_SPACING: 'plant spacing', SPACING_DEVIATION: 'spacing error',
               ACTUAL_SPEED: 'ground speed', TOTAL_COUNT: 'plants',
               SINGULATION: 'quality of feed (ISO 7256-1)', SKIP: 'miss index (ISO 7256-1)',
               MULTIPLE: 'multiple index (ISO 7256-1)', CV: 'precision, CV (ISO 7256-1)'}
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
    from isoxml.models.ddi_entities import DDEntity
    return DDEntity.from_id(ddi)


def dd_value(ddi, value):
    """An SI value (m, m/s, a fraction, a count) as the DDI's integer: in its data dictionary
    unit over its resolution; None for an undefined value."""
    if value is None or not math.isfinite(value):
        return None
    entity = _dd(ddi)
    return int(round(value * SCALE[entity.unit] / entity.bit_resolution))


def check_path(path, option):
    """Refuse (OutputError) an ISOXML output that cannot be written: a .zip as check_output
    does; a directory that exists and holds anything but files of an earlier export
    (TASKDATA.XML, TLGnnnnn.XML/.BIN), is not writable, or whose parent is missing or
    read-only. Returns a Path."""
    from planter_ros.output_files import OutputError, check_directory, check_output
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
    """A device: the rows of one machine, its element and process data ids."""

    device_id: str
    rows: tuple                  # (index, name)
    elements: dict               # row index -> DET id
    name: bytes                  # the ISO 11783-5 NAME (8 bytes)


def _device_name(rows):
    """An ISO 11783-5 NAME for a machine that is not on an ISOBUS: self-configurable address,
    industry group 2 (agricultural), device class 4 (planters/seeders), function 255 (not
    available), no manufacturer code, identity number from the row layout."""
    identity = int.from_bytes(hashlib.sha256(repr(rows).encode()).digest()[:4], 'big') \
        & 0x1FFFFF
    value = (1 << 63) | (2 << 60) | (4 << 49) | (255 << 40) | identity
    return value.to_bytes(8, 'big')


def _device(iso, layout, number):
    """The DVC of a layout: the planter (DET, type device) and one Section per row, each with
    its process data (DPD) referenced by the element (DOR)."""
    version = _version()
    elements = [iso.DeviceElement(id=f'DET{layout.elements["device"]}', object_id=1,
                                  type=iso.DeviceElementType.Device,
                                  designator='planter', number=0, parent_object_id=0)]
    process_data = []
    object_id = len(layout.rows) + 2
    for k, (row, name) in enumerate(layout.rows):
        refs = []
        for ddi in dict.fromkeys(LOGGED + TOTALS):
            trigger = TRIGGER_TOTAL if ddi in TOTALS and ddi not in LOGGED else \
                TRIGGER_ON_CHANGE | (TRIGGER_TOTAL if ddi == TOTAL_COUNT else 0)
            process_data.append(iso.DeviceProcessData(
                object_id=object_id, ddi=ddi.to_bytes(2, 'big'),
                property=PROPERTY_DEFAULT_SET, trigger_methods=trigger,
                designator=DESIGNATORS[ddi]))
            refs.append(iso.DeviceObjectReference(device_object_id=object_id))
            object_id += 1
        elements.append(iso.DeviceElement(
            id=f'DET{layout.elements[row]}', object_id=k + 2, type=iso.DeviceElementType.Section,
            designator=(name or 'row')[:32], number=k + 1,
            parent_object_id=1, device_object_references=refs))
    structure = hashlib.sha256(repr(layout.rows).encode()).hexdigest()
    return iso.Device(id=layout.device_id, designator=f'planter_ros planter {number}'[:32],
                      software_version=version, client_name=layout.name,
                      structure_label=''.join(str(int(c, 16) % 10) for c in structure[:14]),
                      localization_label='FF000000000000', elements=elements,
                      process_data=process_data)


def _version():
    import importlib.metadata
    try:
        return importlib.metadata.version('planter_ros')
    except importlib.metadata.PackageNotFoundError:
        return 'unknown'


def _layouts(runs):
    """One _Layout per distinct row layout of the runs, element ids numbered across them."""
    layouts, next_element = {}, 1
    for run in runs:
        rows = tuple(run.rows)
        if rows in layouts:
            continue
        elements = {'device': next_element}
        for k, (row, _) in enumerate(rows):
            elements[row] = next_element + 1 + k
        next_element += 1 + len(rows)
        layouts[rows] = _Layout(f'DVC{len(layouts) + 1}', rows, elements, _device_name(rows))
    return layouts


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
    import isoxml.models.base.v4 as iso
    values = []                       # (row, ddi) of each DLV, its index in the header
    for row, _ in layout.rows:
        values += [(row, ddi) for ddi in LOGGED]
    index = {v: i for i, v in enumerate(values)}
    header = iso.Time(
        start='', type=iso.TimeType.Effective,
        positions=[iso.Position(north='', east='', status='')],
        data_log_values=[iso.DataLogValue(process_data_ddi=ddi.to_bytes(2, 'big'),
                                          process_data_value='',
                                          device_element_id_ref=f'DET{layout.elements[row]}')
                         for row, ddi in values])
    setpoint = dd_value(SETPOINT_SPACING, run.design_spacing)
    counts = {row: 0 for row, _ in layout.rows}
    data = bytearray()
    for record in _ordered(run):
        row = record['row']
        counts[row] += PLANTS_BY_STATUS.get(record.get('status'), 1)
        ms, days = _time_start(record['time'])
        lat, lon = record.get('latitude'), record.get('longitude')
        if lat is None or lon is None:
            north, east, status = 0, 0, STATUS_NOT_AVAILABLE
        else:
            north, east = int(round(lat / DEGREE_STEP)), int(round(lon / DEGREE_STEP))
            status = STATUS_ESTIMATED
        logged = {WORK_STATE: dd_value(WORK_STATE, 1), SETPOINT_SPACING: setpoint,
                  ACTUAL_SPACING: dd_value(ACTUAL_SPACING, record.get('spacing')),
                  SPACING_DEVIATION: dd_value(SPACING_DEVIATION, record.get('spacing_error')),
                  ACTUAL_SPEED: dd_value(ACTUAL_SPEED, record.get('ground_speed')),
                  TOTAL_COUNT: dd_value(TOTAL_COUNT, counts[row])}
        pairs = [(index[(row, ddi)], v) for ddi, v in logged.items() if v is not None]
        data += struct.pack(f'<IHiiBB{"Bi" * len(pairs)}', ms, days, north, east, status,
                            len(pairs), *[x for pair in pairs for x in pair])
    return header, bytes(data), counts


def _task_time(iso, run, layout, counts):
    """The task's TIM: effective, first to last planting instant, each row's totals."""
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
    import isoxml.models.base.v4 as iso
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
        layout = layouts[tuple(run.rows)]
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
    from isoxml.util.isoxml_io import isoxml_to_text
    (directory / TASKDATA).write_text(isoxml_to_text(root), encoding='utf-8')
    for name, content in files.items():
        if isinstance(content, bytes):
            (directory / name).write_bytes(content)
        else:
            (directory / name).write_text(isoxml_to_text(content), encoding='utf-8')


def write_isoxml(path, runs):
    """Write the task data of `runs` at `path` (a directory, or a .zip holding TASKDATA/),
    atomically. Returns (tasks, records logged, skipped [(key, reason)])."""
    from planter_ros.output_files import atomic_directory, atomic_output
    root, files, tasks, logged, skipped = taskdata(runs)
    path = Path(path)
    if path.suffix.lower() == '.zip' and not path.is_dir():
        import tempfile
        import zipfile
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
