"""Exports farm software imports (doc/exports.md): the Shapefile read back by GDAL (pyogrio) and
pyshp, the ISOXML task data read back by the isoxml library (strict, against the schema's
facets its bindings carry) and its binary time log decoded here from the standard's layout;
both agree with replay's own numbers (plant count, positions, fields). Bad output paths are one
line and exit 2 before the replay; a failed write leaves the old files."""
import contextlib
import dataclasses
from decimal import Decimal
from enum import Enum
import io
import math
from pathlib import Path
import re
import struct
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from planter_ros.cli.main import main
from planter_ros.export import ExportError
from planter_ros.export.isoxml import check_run, taskdata, write_isoxml
from planter_ros.export.runs import ExportRun, run_of_replay
from planter_ros.export.shapefile import ATTRIBUTES, attributes_of, write_shapefile
from planter_ros.recording.replay import replay
from planter_ros.sim.season import simulate_bag

REPO = Path(__file__).resolve().parents[1]
NO_GNSS = REPO / 'bags' / 'sample_tomato.mcap'     # recorded before the map: no fixes


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    """A simulated two-row run with GNSS (a season's bag), 14 s."""
    path = tmp_path_factory.mktemp('exports') / 'run.mcap'
    simulate_bag(path, 11, 0, 14.0, 2)
    return path


@pytest.fixture(scope='module')
def result(bag):
    r = replay(str(bag))
    assert len(r.plants) >= 20 and np.isfinite(r.plants.latitude).all()
    return r


def run_cli(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def geodesic_m(lon1, lat1, lon2, lat2):
    from pyproj import Geod
    return Geod(ellps='WGS84').inv(lon1, lat1, lon2, lat2)[2]


def read_gdal(path):
    """(metadata, [(lon, lat) or None], {column: values}) through GDAL (pyogrio)."""
    import shapely
    from pyogrio import raw
    meta, _, geometry, values = raw.read(str(path))
    points = [None if g is None else shapely.from_wkb(g) for g in geometry]
    return meta, [None if p is None else (p.x, p.y) for p in points], \
        dict(zip(meta['fields'], values))


# ------------------------------------------------------------------------------ Shapefile

def check_against_replay(result, points, columns, rows_named=True, bag_name=None):
    """Every plant of the replay is its feature: position within 1 mm, fields as replay's."""
    p = result.plants
    assert len(points) == len(p)
    names = {row.index: row.name for row in result.rows}
    for i in range(len(p)):
        assert points[i] is not None
        assert geodesic_m(points[i][0], points[i][1], p.longitude[i], p.latitude[i]) < 1e-3
        assert columns['row'][i] == p.row[i] and columns['index'][i] == p.index[i]
        assert columns['row_name'][i] == (names[int(p.row[i])] if rows_named else None)
        assert columns['time_s'][i] == pytest.approx(p.time[i], abs=1e-6)
        assert columns['upright'][i] == bool(p.upright[i])
        for name, values in (('spacing_m', p.spacing), ('sp_err_m', p.spacing_error),
                             ('hole_w_m', p.hole_width), ('tilt_rad', p.tilt),
                             ('speed_mps', p.ground_speed)):
            if math.isfinite(values[i]):
                assert columns[name][i] == pytest.approx(values[i], abs=5e-7), name
            else:
                assert math.isnan(columns[name][i]), name       # null, read as NaN
    assert set(columns['bag']) == {bag_name or Path(result.path).name}
    assert columns['utc'][0].endswith('Z')


def test_the_shapefile_is_every_plant_where_replay_put_it_read_by_gdal(bag, result, tmp_path):
    shp = tmp_path / 'plants.shp'
    code, out, err = run_cli(['replay', bag, '--shapefile', shp])
    assert code == 0, err
    assert f'Shapefile written to {shp} ({len(result.plants)} plants, {len(result.plants)} ' \
           'with a map position)' in out
    assert sorted(f.name for f in tmp_path.iterdir()) == [
        'plants.cpg', 'plants.dbf', 'plants.prj', 'plants.shp', 'plants.shx']
    meta, points, columns = read_gdal(shp)
    assert meta['crs'] == 'EPSG:4326' and meta['encoding'] == 'UTF-8'
    assert meta['geometry_type'] == 'Point'
    assert all(len(name) <= 10 for name in meta['fields'])
    check_against_replay(result, points, columns)
    spacing = columns['spacing_m']
    assert np.isnan(spacing).sum() == len(result.rows)      # each row's first plant: null


def test_the_zip_holds_the_same_set_and_gdal_opens_it(bag, result, tmp_path):
    archive = tmp_path / 'plants.zip'
    assert run_cli(['replay', bag, '--shapefile', archive])[0] == 0
    import zipfile
    assert sorted(zipfile.ZipFile(archive).namelist()) == [
        'plants.cpg', 'plants.dbf', 'plants.prj', 'plants.shp', 'plants.shx']
    meta, points, columns = read_gdal(archive)
    assert meta['crs'] == 'EPSG:4326'
    check_against_replay(result, points, columns)
    assert list(tmp_path.iterdir()) == [archive]                 # no temporaries left


def test_pyshp_reads_nulls_where_replay_has_no_value(tmp_path):
    """A bag without GNSS: every plant is a Null shape; the first spacing is a null number."""
    import shapefile
    shp = tmp_path / 'x.shp'
    code, out, _ = run_cli(['replay', NO_GNSS, '--shapefile', shp])
    assert code == 0 and '0 with a map position' in out
    result = replay(str(NO_GNSS))
    reader = shapefile.Reader(str(shp))
    assert len(reader) == len(result.plants)
    assert {s.shapeType for s in reader.shapes()} == {shapefile.NULL}
    records = reader.records()
    assert records[0]['spacing_m'] is None and records[1]['spacing_m'] == pytest.approx(
        result.plants.spacing[1], abs=5e-7)
    assert records[0]['row_name'] == ''                       # the one implicit row
    _, points, columns = read_gdal(shp)
    assert points == [None] * len(result.plants)
    assert columns['row_name'][0] is None                     # GDAL: an empty text is null


def test_every_dbf_name_fits_and_new_record_keys_become_columns(result, tmp_path):
    """A plant record that gains keys later (a seedling sensor's status and reason, anything
    else) is written without a change: status/reason as listed, others by their first 10
    characters, made unique, typed by their values."""
    names = [a.name for a in ATTRIBUTES]
    assert all(len(n) <= 10 for n in names) and len(set(names)) == len(names)
    run = run_of_replay(result)
    for i, record in enumerate(run.records):
        record['status'] = ('planted', 'empty', 'double', 'unknown')[i % 4]
        record['reason'] = None if i % 4 == 0 else f'cup sensor said {record["status"]} ü'
        record['seedling_height'] = 0.1 + 0.001 * i            # a new number
        record['seedling_heavy'] = i % 2 == 0                   # a new flag
    columns = [a.name for a, _ in attributes_of(run.records)]
    assert columns[-5:] == ['status', 'reason', 'input_gap', 'seedling_h', 'seedling_1']
    shp = tmp_path / 'status.shp'
    write_shapefile(shp, [run])
    _, _, read = read_gdal(shp)
    assert list(read['status'][:4]) == ['planted', 'empty', 'double', 'unknown']
    assert read['reason'][0] is None and read['reason'][1] == 'cup sensor said empty ü'
    assert read['seedling_h'][5] == pytest.approx(0.105)
    assert list(read['seedling_1'][:2]) == [True, False]


# ------------------------------------------------------------------------------ ISOXML

def schema_problems(element, where='ISO11783_TaskData'):
    """What breaks the ISO 11783-10 schema's facets in a tree of the isoxml library's bindings
    (generated from the schema: required, pattern, length, range, fraction digits)."""
    problems = []
    for f in dataclasses.fields(element):
        meta, value = f.metadata, getattr(element, f.name)
        name = f'{where}/{meta.get("name", f.name)}'
        if meta.get('type') == 'Attribute':
            if value is None:
                if meta.get('required'):
                    problems.append(f'{name}: required')
                continue
            if isinstance(value, Enum):
                value = value.value[0] if isinstance(value.value, tuple) else value.value
            size = len(value) if isinstance(value, (bytes, str)) else None
            if isinstance(value, str) and meta.get('format') == 'base16':
                size = len(value) // 2                        # hexBinary: bytes
            text = value.hex().upper() if isinstance(value, bytes) else str(value)
            if 'pattern' in meta and not re.fullmatch(meta['pattern'], text):
                problems.append(f'{name} = {text}: pattern {meta["pattern"]}')
            if 'length' in meta and size != meta['length']:
                problems.append(f'{name} = {text}: length {meta["length"]}')
            if 'max_length' in meta and size > meta['max_length']:
                problems.append(f'{name} = {text}: longer than {meta["max_length"]}')
            if 'min_length' in meta and size < meta['min_length']:
                problems.append(f'{name} = {text}: shorter than {meta["min_length"]}')
            if 'min_inclusive' in meta and not meta['min_inclusive'] <= value:
                problems.append(f'{name} = {text}: below {meta["min_inclusive"]}')
            if 'max_inclusive' in meta and not value <= meta['max_inclusive']:
                problems.append(f'{name} = {text}: above {meta["max_inclusive"]}')
            if 'fraction_digits' in meta and isinstance(value, Decimal) and \
                    -value.as_tuple().exponent > meta['fraction_digits']:
                problems.append(f'{name} = {text}: more than {meta["fraction_digits"]} digits')
        else:
            for child in value if isinstance(value, list) else [value]:
                if dataclasses.is_dataclass(child):
                    problems += schema_problems(child, name)
    return problems


def read_taskdata(directory):
    """TASKDATA.XML through the isoxml library, strictly (an element or attribute the schema
    does not know fails), and its own reader of the directory."""
    import isoxml.models.base.v4 as iso
    from isoxml.util.isoxml_io import isoxml_from_path
    from xsdata.formats.dataclass.parsers import XmlParser
    from xsdata.formats.dataclass.parsers.config import ParserConfig
    strict = XmlParser(ParserConfig(fail_on_unknown_properties=True,
                                    fail_on_unknown_attributes=True,
                                    fail_on_converter_warnings=True))
    task_data = strict.from_path(Path(directory) / 'TASKDATA.XML', iso.Iso11783TaskData)
    assert schema_problems(task_data) == []
    loose, files = isoxml_from_path(Path(directory))
    assert len(loose.tasks) == len(task_data.tasks)
    return task_data, files


def decode_time_log(header_xml, data):
    """The binary time log as ISO 11783-10 lays it out (the header's empty attributes are in
    each record, little-endian): [(ms, days, {PTN attribute: value}, {DLV index: value})]."""
    header = ET.fromstring(header_xml)
    assert header.tag == 'TIM' and header.get('A') == '' and header.get('D') == '4'
    position = header.find('PTN')
    binary = [k for k in 'ABCDEFGHI' if position is not None and position.get(k) == '']
    formats = {'A': 'i', 'B': 'i', 'C': 'i', 'D': 'B', 'E': 'H', 'F': 'H', 'G': 'B',
               'H': 'I', 'I': 'H'}
    fixed = '<IH' + ''.join(formats[k] for k in binary) + 'B'
    records, offset = [], 0
    while offset < len(data):
        ms, days, *ptn, count = struct.unpack_from(fixed, data, offset)
        offset += struct.calcsize(fixed)
        values = {}
        for _ in range(count):
            index, value = struct.unpack_from('<Bi', data, offset)
            offset += 5
            values[index] = value
        records.append((ms, days, dict(zip(binary, ptn)), values))
    assert offset == len(data)
    return header, records


def test_the_isoxml_task_is_every_plant_read_back_by_the_isoxml_library(bag, result, tmp_path):
    from datetime import datetime, timezone
    out = tmp_path / 'TASKDATA'
    code, text, err = run_cli(['replay', bag, '--isoxml', out])
    assert code == 0, err
    assert f'ISOXML written to {out} (1 task, {len(result.plants)} plants' in text
    task_data, files = read_taskdata(out)
    assert sorted(f.name for f in out.iterdir()) == ['TASKDATA.XML', 'TLG00001.BIN',
                                                      'TLG00001.XML']
    (task,) = task_data.tasks
    (device,) = task_data.devices
    assert task.designator == bag.name and task.status.value == '4'
    assert task.device_allocations[0].device_id_ref == device.id
    rows = {e.id: e for e in device.elements if e.type.value == '4'}       # sections
    assert sorted(e.designator for e in rows.values()) == sorted(r.name for r in result.rows)
    row_of = {e.id: next(r.index for r in result.rows if r.name == e.designator)
              for e in rows.values()}
    # every DPD or DPT a row element references exists on the device, and every logged DDI
    # and the row's offsets and width have one
    objects = {d.object_id: d for d in device.process_data + device.properties}
    for element in rows.values():
        ddis = {objects[r.device_object_id].ddi.hex().upper()
                for r in element.device_object_references}
        assert {'008D', '0010', '0011', '01A5', '018D', '0052', '0086', '0087', '0088',
                '0043', '0046'} <= ddis
    # the time log, decoded from the bytes
    (log,) = task.time_logs
    assert log.filename == 'TLG00001' and log.filelength == len(files['TLG00001'])
    header, records = decode_time_log((out / 'TLG00001.XML').read_text(),
                                      (out / 'TLG00001.BIN').read_bytes())
    dlvs = [(d.get('A'), d.get('C')) for d in header.findall('DLV')]
    assert len(records) == len(result.plants)
    p = result.plants
    order = np.argsort(p.time, kind='stable')
    epoch = datetime(1980, 1, 1, tzinfo=timezone.utc).timestamp()
    worst = 0.0
    last_count = {}
    from planter_ros.export.isoxml import drp
    run = run_of_replay(result)
    machine = drp([run.records[i] for i in order], run.places)
    for (ms, days, ptn, values), i, (lat, lon) in zip(records, order, machine):
        assert (days * 86400 + ms / 1000.0) + epoch == pytest.approx(p.time[i], abs=5e-4)
        # the device reference point at the instant (test_isoxml_standard.py: the plant is at
        # its row's offsets from it), to the binary's 1e-7 degrees
        north, east = ptn['A'] * 1e-7, ptn['B'] * 1e-7
        assert abs(north - lat) <= 0.5e-7 + 1e-12
        assert abs(east - lon) <= 0.5e-7 + 1e-12
        worst = max(worst, geodesic_m(east, north, lon, lat))
        assert ptn['D'] == 6                                   # estimated (dead reckoning)
        by_ddi = {}
        for index, value in values.items():
            ddi, element = dlvs[index]
            assert row_of[element] == p.row[i]                 # the plant's own row
            by_ddi[ddi] = value
        assert by_ddi['008D'] == 1
        assert by_ddi['0010'] == round(result.summary['design_spacing'] * 1000)   # one design
        for ddi, value in (('0011', p.spacing[i]), ('01A5', abs(p.spacing_error[i])),
                           ('018D', p.ground_speed[i])):
            if math.isfinite(value):
                assert abs(by_ddi[ddi] - value * 1000) <= 0.5, ddi
            else:
                assert ddi not in by_ddi                       # undefined: not logged
        row = int(p.row[i])
        assert by_ddi['0052'] == last_count.get(row, 0) + 1    # plants so far in the row
        last_count[row] = by_ddi['0052']
    assert worst < 0.0075                                      # 1e-7 deg: < 6 mm N, 4 mm E
    # the task's totals: each row's plants and ISO 7256-1 indices (ppm)
    (time,) = task.times
    assert time.type.value == ('4',) or time.type.value == '4'
    totals = {(d.device_element_id_ref, d.process_data_ddi.hex().upper()): d.process_data_value
              for d in time.data_log_values}
    for element, row in row_of.items():
        summary = result.row_summaries[row]
        assert totals[(element, '0052')] == summary['plants'] == last_count[row]
        quality = summary['spacing_quality']
        assert totals[(element, '01A0')] == round(quality['quality_of_feed_index'] * 1e6)
        assert totals[(element, '01A2')] == round(quality['miss_index'] * 1e6)
        assert totals[(element, '01A4')] == round(quality['multiple_index'] * 1e6)
        assert totals[(element, '01A8')] == round(quality['precision'] * 1e6)
    assert time.start.to_datetime().timestamp() == pytest.approx(p.time.min(), abs=1e-3)
    assert time.stop.to_datetime().timestamp() == pytest.approx(p.time.max(), abs=1e-3)


def test_the_isoxml_zip_holds_a_taskdata_folder_the_library_reads(bag, result, tmp_path):
    """The zip holds TASKDATA/ as a terminal's USB stick does (and isoxml's own zip writer);
    the library's zip reader wants the files at the top, so it reads the folder."""
    import zipfile
    archive = tmp_path / 'taskdata.zip'
    assert run_cli(['replay', bag, '--isoxml', archive])[0] == 0
    assert list(tmp_path.iterdir()) == [archive]
    assert sorted(zipfile.ZipFile(archive).namelist()) == [
        'TASKDATA/TASKDATA.XML', 'TASKDATA/TLG00001.BIN', 'TASKDATA/TLG00001.XML']
    zipfile.ZipFile(archive).extractall(tmp_path / 'unzipped')
    task_data, files = read_taskdata(tmp_path / 'unzipped' / 'TASKDATA')
    assert len(task_data.tasks) == 1 and 'TLG00001' in files
    _, records = decode_time_log(
        (tmp_path / 'unzipped' / 'TASKDATA' / 'TLG00001.XML').read_text(), files['TLG00001'])
    assert len(records) == len(result.plants)


def test_plants_without_a_position_are_logged_as_not_available(tmp_path):
    out = tmp_path / 'TASKDATA'
    assert run_cli(['replay', NO_GNSS, '--isoxml', out])[0] == 0
    read_taskdata(out)
    _, records = decode_time_log((out / 'TLG00001.XML').read_text(),
                                 (out / 'TLG00001.BIN').read_bytes())
    assert len(records) == len(replay(str(NO_GNSS)).plants)
    assert {(r[2]['A'], r[2]['B'], r[2]['D']) for r in records} == {(0, 0, 15)}


def test_a_status_counts_plants_and_a_season_shares_one_device_per_machine(result):
    """Records with a seedling sensor's status: an empty cell adds no plant, a double two; two
    runs of one machine are two tasks of one device, a run of another machine adds one."""
    run = run_of_replay(result)
    statuses = ['planted'] * len(run.records)
    statuses[3], statuses[5] = 'empty', 'double'
    for record, status in zip(run.records, statuses):
        record['status'] = status
    other = ExportRun('other.mcap', [dict(r, row=0) for r in run.records[:5]], [(0, 'solo')],
                      run.design_spacing)
    root, files, tasks, logged, skipped = taskdata([run, run_of_replay(result), other])
    assert (tasks, logged, skipped) == (3, 2 * len(run.records) + 5, [])
    assert len(root.devices) == 2
    assert [t.device_allocations[0].device_id_ref for t in root.tasks] == ['DVC1', 'DVC1',
                                                                         'DVC2']
    count = {}
    for task in root.tasks[:2]:
        count[task.id] = sum(d.process_data_value for d in task.times[0].data_log_values
                             if d.process_data_ddi.hex() == '0052')
    assert count == {'TSK1': len(run.records), 'TSK2': len(run.records)}     # -1 + 1
    assert schema_problems(root) == []


def test_a_clock_that_is_not_utc_cannot_be_a_time_log(result, tmp_path):
    run = run_of_replay(result)
    for record in run.records:
        record['time'] -= 1.6e9                  # a simulation clock from 0: 1970
    with pytest.raises(ExportError, match='not a UTC time from 1980-01-01'):
        check_run(run)
    _, _, tasks, _, skipped = taskdata([run])
    assert tasks == 0 and skipped[0][0] == run.key
    wide = ExportRun('wide', run.records, [(k, f'r{k}') for k in range(43)])
    with pytest.raises(ExportError, match='at most 42 rows'):
        check_run(wide)


# ------------------------------------------------------------------------------ paths

def test_bad_export_paths_are_one_line_and_exit_2_before_the_replay(bag, tmp_path):
    (tmp_path / 'a_dir.shp').mkdir()
    (tmp_path / 'a_file').write_text('mine\n')
    (tmp_path / 'mine').mkdir()
    (tmp_path / 'mine' / 'notes.txt').write_text('mine\n')
    (tmp_path / 'old.dbf').mkdir()                 # a sidecar of old.shp that is a directory
    bad = [('--shapefile', tmp_path / 'missing' / 'x.shp', 'does not exist'),
           ('--shapefile', tmp_path / 'x.geojson', 'unsupported extension'),
           ('--shapefile', tmp_path / 'a_dir.shp', 'is a directory'),
           ('--shapefile', tmp_path / 'old.shp', 'is a directory'),
           ('--isoxml', tmp_path / 'missing' / 'TASKDATA', 'does not exist'),
           ('--isoxml', tmp_path / 'a_file', 'is not a directory'),
           ('--isoxml', tmp_path / 'mine', 'holds other files (notes.txt)'),
           ('--isoxml', tmp_path / 'missing' / 'x.zip', 'does not exist')]
    for option, path, words in bad:
        code, out, err = run_cli(['replay', bag, option, path])
        assert code == 2, (option, path, err)
        assert out == '' and err.count('\n') == 1 and words in err and option in err, err
    assert (tmp_path / 'mine' / 'notes.txt').read_text() == 'mine\n'
    assert not (tmp_path / 'missing').exists()


def test_a_failed_write_leaves_the_old_files_and_no_temporaries(result, tmp_path, monkeypatch):
    run = run_of_replay(result)
    shp, taskdir = tmp_path / 'map.shp', tmp_path / 'TASKDATA'
    write_shapefile(shp, [run])
    write_isoxml(taskdir, [run])
    (tmp_path / 'map.qix').write_bytes(b'an index of the old points')
    before = {f.name: f.read_bytes() for f in tmp_path.rglob('*') if f.is_file()}

    import shapefile

    def broken(self, *args, **kwargs):
        raise OSError('disk full')
    monkeypatch.setattr(shapefile.Writer, 'point', broken)
    with pytest.raises(OSError):
        write_shapefile(shp, [run])
    monkeypatch.undo()
    monkeypatch.setattr('planter_ros.export.isoxml.isoxml_to_text', broken, raising=False)
    import isoxml.util.isoxml_io
    monkeypatch.setattr(isoxml.util.isoxml_io, 'isoxml_to_text', broken)
    with pytest.raises(OSError):
        write_isoxml(taskdir, [run])
    after = {f.name: f.read_bytes() for f in tmp_path.rglob('*') if f.is_file()}
    assert after == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        'TASKDATA', 'map.cpg', 'map.dbf', 'map.prj', 'map.qix', 'map.shp', 'map.shx']
    monkeypatch.undo()
    write_shapefile(shp, [run])                      # replaced: the stale index goes
    assert not (tmp_path / 'map.qix').exists()
    write_isoxml(taskdir, [run])
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        'TASKDATA', 'map.cpg', 'map.dbf', 'map.prj', 'map.shp', 'map.shx']


# ------------------------------------------------------------------------------ a season

@pytest.mark.slow
def test_analyze_writes_the_seasons_shapefile_and_task_data_next_to_its_tables(bag, tmp_path):
    """Two machines' recordings in a season: the Shapefile holds every plant with its
    recording's name, where replay puts it; the task data one task per recording, one device
    per machine, each task's time log its recording's plants."""
    import shutil
    import zipfile
    season = tmp_path / 'season'
    (season / 'day1').mkdir(parents=True)
    (season / 'day2').mkdir()
    shutil.copy(bag, season / 'day1' / 'a.mcap')
    shutil.copy(NO_GNSS, season / 'day2' / 'b.mcap')
    out = tmp_path / 'tables'
    # (in this process: the exports are the question, not the command's process)
    code, printed, err = run_cli(['analyze', season, '--out', out, '--workers', 1])
    assert code == 0, err[-2000:]
    assert f'exports: {out / "as_planted.zip"} (Shapefile' in printed
    results = {'day1/a.mcap': replay(str(season / 'day1' / 'a.mcap')),
               'day2/b.mcap': replay(str(season / 'day2' / 'b.mcap'))}
    meta, points, columns = read_gdal(out / 'as_planted.zip')
    assert meta['crs'] == 'EPSG:4326'
    bags = np.array(columns['bag'])
    assert set(bags) == set(results)
    for key, result in results.items():
        mine = np.flatnonzero(bags == key)
        assert len(mine) == len(result.plants)
        if np.isfinite(result.plants.latitude).all():
            check_against_replay(result, [points[i] for i in mine],
                                 {k: np.asarray(v)[mine] for k, v in columns.items()},
                                 bag_name=key)
        else:
            assert all(points[i] is None for i in mine)
    zipfile.ZipFile(out / 'TASKDATA.zip').extractall(tmp_path / 'unzipped')
    task_data, files = read_taskdata(tmp_path / 'unzipped' / 'TASKDATA')
    assert len(task_data.devices) == 2
    assert sorted(t.designator for t in task_data.tasks) == sorted(results)
    for task in task_data.tasks:
        name = task.time_logs[0].filename
        _, records = decode_time_log(
            (tmp_path / 'unzipped' / 'TASKDATA' / f'{name}.XML').read_text(), files[name])
        assert len(records) == len(results[task.designator].plants)
    # a re-run that analyses nothing leaves them; one that finds them gone writes them again
    (out / 'TASKDATA.zip').unlink()
    code, printed, err = run_cli(['analyze', season, '--out', out, '--workers', 1, '--json'])
    assert code == 0, err[-2000:]
    import json
    report = json.loads(printed)
    assert report['skipped'] == 2 and report['exports']['tasks'] == 2
    assert (out / 'TASKDATA.zip').is_file()
