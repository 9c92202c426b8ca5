"""A season analysed the way an agronomist adds days: one day's folder, then two days, then the
season from its parent folder, then the season moved, reached through a symbolic link and with a
copy of a bag beside it. After every run each bag is in the tables once and each plant once, in
the Parquet tables (pyarrow, DuckDB), the Shapefile (GDAL) and the ISOXML task data: a bag is
its content, not the path it was found at (analysis.season). The tables hold nulls where replay
has no value (DuckDB) and every number of every table names its unit, nested ones too.

The season has empty cups, doubles, unknown tilts and input gaps, and a cam-schedule run."""
import json
import os
from pathlib import Path
import shutil
import zipfile

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from cli_helpers import REPO, planter_here
from planter_ros.analysis.tables import units
from planter_ros.recording.replay import replay


@pytest.fixture(scope='module')
def season(tmp_path_factory):
    """season/day1: a 4-row and a 1-row run; season/day2: a cam-schedule run (tomato cam
    scene, 0.15 m then 0.25 m); all with a tray of 10 % empty and 5 % double cells."""
    from planter_ros.analysis.simulate import SeasonRequest, simulate_scene_bag
    from planter_ros.sim.season import simulate_bag
    from planter_ros.sim.tray import TrayShares
    root = tmp_path_factory.mktemp('agronomist') / 'season'
    (root / 'day1').mkdir(parents=True)
    (root / 'day2').mkdir()
    simulate_bag(root / 'day1' / 'a.mcap', 0, 0, 20.0, 4, TrayShares(0.1, 0.05))
    simulate_bag(root / 'day1' / 'b.mcap', 0, 1, 16.0, 1, TrayShares(0.1, 0.05))
    simulate_scene_bag(str(root / 'day2' / 'c.mcap'), 0, SeasonRequest(
        3, 30.0, None, str(REPO / 'config' / 'tomato_cam.yaml'), TrayShares(0.1, 0.05)))
    # another recording, not in the season: what a bag's file is rewritten with
    simulate_bag(root.parent / 'other.mcap', 0, 2, 16.0, 2, TrayShares(0.1, 0.05))
    return root


@pytest.fixture(scope='module')
def plants(season):
    """{bag file name: its replay's plants}."""
    return {path.name: replay(str(path)).plants
            for path in sorted(season.parent.rglob('*.mcap'))}


def analyze(*paths, out):
    """`planter analyze PATHS --out OUT --workers 1 --json`, called in this process (how the
    season is found is the question here, not the process: the code and the model version are
    loaded once for all the runs): its report."""
    done = planter_here('analyze', *paths, '--out', out, '--workers', 1, '--json')
    assert done.returncode == 0, done.stderr[-3000:]
    assert 'Traceback' not in done.stderr
    return json.loads(done.stdout)


def check_once(out, plants, names):
    """Each bag of `names` ({name: bag file name}) once in every table and export, each of its
    plants once."""
    bags = pq.read_table(out / 'bags').to_pylist()
    assert sorted(row['bag'] for row in bags) == sorted(names)
    assert len({row['bag_id'] for row in bags}) == len(bags)
    table = pq.read_table(out / 'plants')
    counts = {}
    for bag in table.column('bag').to_pylist():
        counts[bag] = counts.get(bag, 0) + 1
    assert counts == {name: len(plants[file]) for name, file in names.items()}
    assert len(table.column('bag_id').unique()) == len(bags)
    # the Shapefile, through GDAL
    from pyogrio import raw
    _, shp = raw.read_arrow(str(out / 'as_planted.zip'))
    shape_counts = {}
    for bag in shp.column('bag').to_pylist():
        shape_counts[bag] = shape_counts.get(bag, 0) + 1
    assert shape_counts == counts
    # the ISOXML task data: one task per bag, its time log one record per plant
    import xml.etree.ElementTree as ET
    with zipfile.ZipFile(out / 'TASKDATA.zip') as archive:
        root = ET.fromstring(archive.read('TASKDATA/TASKDATA.XML'))
        tasks = {t.get('B'): t.find('TLG').get('A') for t in root.findall('TSK')}
        assert sorted(tasks) == sorted(names)
        for name, log in tasks.items():
            header = ET.fromstring(archive.read(f'TASKDATA/{log}.XML'))
            data = archive.read(f'TASKDATA/{log}.BIN')
            assert _records(header, data) == counts[name], name


def _records(header, data):
    """Records in a binary time log (its header: TIM with PTN A, B, D), per ISO 11783-10."""
    import struct
    assert [k for k in 'ABCDEFGHI' if header.find('PTN').get(k) == ''] == ['A', 'B', 'D']
    at = count = 0
    while at < len(data):
        at += struct.calcsize('<IHiiB')
        values = data[at]
        at += 1 + 5 * values
        count += 1
    assert at == len(data)
    return count


@pytest.mark.slow
def test_each_bag_and_plant_once_however_the_season_is_found(season, plants, tmp_path):
    out = tmp_path / 'tables'
    first = analyze(season / 'day1', out=out)                 # one day
    assert (first['bags_found'], first['analysed'], first['skipped']) == (2, 2, 0)
    check_once(out, plants, {'a.mcap': 'a.mcap', 'b.mcap': 'b.mcap'})

    second = analyze(season / 'day1', season / 'day2', out=out)    # then two
    assert (second['bags_found'], second['analysed'], second['skipped']) == (3, 1, 2)
    names = {'day1/a.mcap': 'a.mcap', 'day1/b.mcap': 'b.mcap', 'day2/c.mcap': 'c.mcap'}
    check_once(out, plants, names)                            # day1's bags named by their day

    third = analyze(season, out=out)                          # the season from its parent
    assert (third['bags_found'], third['analysed'], third['skipped']) == (3, 0, 3)
    check_once(out, plants, names)

    again = analyze(season / 'day1', out=out)                 # a folder below: names kept
    assert again['skipped'] == 2 and again['analysed'] == 0
    check_once(out, plants, names)

    moved = season.parent / 'season moved'                    # the folder moved
    shutil.move(season, moved)
    try:
        (moved.parent / 'link').symlink_to(moved / 'day2')
        shutil.copy2(moved / 'day1' / 'a.mcap', moved / 'a copy.mcap')
        fourth = analyze(moved, moved.parent / 'link', out=out)
        assert fourth['analysed'] == 0 and fourth['skipped'] == 3
        assert fourth['bags_found'] == 3
        assert fourth['copies'] == [{'path': str(moved / 'a copy.mcap'),
                                     'same_as': str(moved / 'day1' / 'a.mcap')}]
        check_once(out, plants, names)
        rows = {row['bag']: row for row in pq.read_table(out / 'bags').to_pylist()}
        assert rows['day1/a.mcap']['path'] == str(moved / 'day1' / 'a.mcap')
        # a bag's file rewritten with another recording: that one takes its place
        original = (moved / 'day1' / 'b.mcap').read_bytes()
        shutil.copyfile(season.parent / 'other.mcap', moved / 'day1' / 'b.mcap')
        fifth = analyze(moved, out=out)
        assert fifth['analysed'] == 1 and fifth['skipped'] == 2
        check_once(out, plants, {'day1/a.mcap': 'a.mcap', 'day1/b.mcap': 'other.mcap',
                                 'day2/c.mcap': 'c.mcap'})
        (moved / 'day1' / 'b.mcap').write_bytes(original)
    finally:
        if moved.exists():
            shutil.move(moved, season)
        if (season.parent / 'link').is_symlink():
            (season.parent / 'link').unlink()
        (season / 'a copy.mcap').unlink(missing_ok=True)


@pytest.mark.slow
def test_nulls_and_units_of_the_seasons_tables(season, plants, tmp_path):
    """DuckDB finds null exactly where replay has no value (unknown tilt and uprightness of an
    input gap's instant, a sequence's first spacing); every number of both tables, nested ones
    too, has its unit in the schema."""
    import duckdb
    out = tmp_path / 'tables'
    analyze(season, out=out)
    counted = duckdb.sql(
        f"SELECT bag, count(*) FILTER (WHERE upright IS NULL) AS upright, "
        f"count(*) FILTER (WHERE tilt_rad IS NULL) AS tilt, "
        f"count(*) FILTER (WHERE spacing_m IS NULL) AS spacing, "
        f"count(*) FILTER (WHERE input_gap) AS gaps "
        f"FROM read_parquet('{out}/plants/*.parquet') GROUP BY bag").fetchall()
    for bag, upright, tilt, spacing, gaps in counted:
        p = plants[Path(bag).name]
        assert (upright, tilt, spacing, gaps) == (
            np.isnan(p.upright).sum(), np.isnan(p.tilt).sum(), np.isnan(p.spacing).sum(),
            (p.input_gap == 1).sum())
    assert sum(row[1] for row in counted) > 0 and sum(row[4] for row in counted) > 0
    for table in (pq.read_table(out / 'plants'), pq.read_table(out / 'bags')):
        known = units(table.schema)
        missing = [name for name in _numbers(table.schema) if name not in known]
        assert missing == []
    bags = units(pq.read_schema(out / 'bags' / 'bags.parquet'))
    assert bags['design.dyad_ratios'] == '1'
    assert bags['rows.summary.spacing_error_mean'] == 'm'
    assert bags['rows.lateral_offset'] == 'm'


def _numbers(schema, prefix=''):
    """Dotted names of every numeric field (numbers, times, lists of them) of a schema, into
    structs and lists of structs."""
    out = []
    for field in schema:
        name, kind = f'{prefix}{field.name}', field.type
        while pa.types.is_list(kind) and pa.types.is_struct(kind.value_type):
            kind = kind.value_type
        if pa.types.is_struct(kind):
            out += _numbers([kind.field(i) for i in range(kind.num_fields)], f'{name}.')
            continue
        base = kind.value_type if pa.types.is_list(kind) else kind
        if pa.types.is_integer(base) or pa.types.is_floating(base) or \
                pa.types.is_timestamp(base):
            out.append(name)
    return out


@pytest.mark.slow
def test_a_bag_found_twice_in_one_run_is_counted_once(season, tmp_path):
    """A symbolic link to a bag and a copy of it in the same run: one bag (the link is the
    file itself; the copy is named as one)."""
    folder = tmp_path / 'one'
    folder.mkdir()
    shutil.copy2(season / 'day1' / 'b.mcap', folder / 'b.mcap')
    shutil.copy2(season / 'day1' / 'b.mcap', folder / 'b again.mcap')
    os.symlink(folder / 'b.mcap', folder / 'b link.mcap')
    report = analyze(folder, out=tmp_path / 'out')
    assert report['bags_found'] == 1 and report['analysed'] == 1
    ((copy, same),) = [(c['path'], c['same_as']) for c in report['copies']]
    assert {copy, same} == {str(folder / 'b.mcap'), str(folder / 'b again.mcap')}
    assert pq.read_table(tmp_path / 'out' / 'bags').num_rows == 1


@pytest.mark.slow
def test_a_season_output_that_fails_does_not_keep_the_others(season, tmp_path, monkeypatch):
    """The Shapefile fails (a disk full, say): the ISOXML is still written, the failure named
    with its file (planter analyze prints it on stderr, exit 1)."""
    from planter_ros.export import season as season_exports
    import planter_ros.export.shapefile as shapefile
    out = tmp_path / 'tables'
    analyze(season / 'day1', out=out)
    (out / 'TASKDATA.zip').unlink()

    def full(path, runs):
        raise OSError(28, 'No space left on device')
    monkeypatch.setattr(shapefile, 'write_shapefile', full)
    result = season_exports.write_season_exports(out, force=True)
    assert result['shapefile'] is None and result['isoxml'] == str(out / 'TASKDATA.zip')
    assert result['failed'] == [{'file': str(out / 'as_planted.zip'),
                                 'reason': 'OSError: [Errno 28] No space left on device'}]
    assert (out / 'TASKDATA.zip').is_file() and result['tasks'] == 2
    result['seconds'] = 0.0
    assert season_exports.format_exports(result) == \
        f'exports: {out / "TASKDATA.zip"} (ISOXML, 2 tasks) in 0.0 s'
