"""`planter analyze`: a season of bags into Parquet tables on Dask.

Every Parquet row equals `planter replay --json` of its bag, field by field; a damaged bag is
a row with its reason and the rest are analysed; a real `dask scheduler` and `dask worker`,
started as separate processes on 127.0.0.1, give the same tables as the local cluster; a re-run
skips what is done (and redoes a changed bag without duplicating it); --out into a bad place
is refused before any work."""
import contextlib
import io
import json
import os
from pathlib import Path
import shutil
import signal
import socket
import subprocess
import sys
import time

import pyarrow.parquet as pq
import pytest

from cli_helpers import REPO, planter_here, run_planter
from planter_ros.analysis.tables import plant_dicts, unflatten, units
from planter_ros.cli.main import main
from planter_ros.sim.season import draw_plan, simulate_bag, simulate_plan, write_monitor_bag

# columns of the bags table that are the analysis's own, not replay's JSON
OWN = ('bag_id', 'status', 'reason', 'file_size', 'file_mtime_ns', 'model_version', 'options',
       'analysed_at', 'analysis_seconds', 'analysis_cpu_seconds', 'plants_file')
# what differs between two runs of the same analysis
WHEN = ('analysed_at', 'analysis_seconds', 'analysis_cpu_seconds', 'plants_file')


@pytest.fixture(scope='module')
def season(tmp_path_factory):
    """A small season in nested directories: simulated runs of 4, 1 and 2 rows (.mcap files),
    one as a rosbag2 bag directory split in three files, a copy cut off before its end (replays
    with a warning) and a file of garbage named .mcap (replay refuses it)."""
    root = tmp_path_factory.mktemp('season')
    (root / 'day1').mkdir()
    (root / 'day2' / 'machine').mkdir(parents=True)
    simulate_bag(root / 'day1' / 'a.mcap', 5, 0, 16.0, 4)
    simulate_bag(root / 'day1' / 'b.mcap', 5, 1, 16.0, 1)
    simulate_bag(root / 'day2' / 'machine' / 'c.mcap', 5, 2, 16.0, 2)
    write_monitor_bag(simulate_plan(draw_plan(5, 3, 16.0, 4)), root / 'day2' / 'split',
                      split_duration=6.0)
    data = (root / 'day1' / 'a.mcap').read_bytes()
    (root / 'day2' / 'cut.mcap').write_bytes(data[:len(data) * 2 // 3])
    (root / 'day2' / 'garbage.mcap').write_bytes(b'these are field notes, not a bag\n' * 10)
    return root


def analyze(*args, timeout=300):
    r = run_planter('analyze', *args, '--json', timeout=timeout)
    assert r.returncode in (0, 1), r.stderr[-3000:]
    return r, json.loads(r.stdout)


def analyze_here(*args):
    """`planter analyze ARGS --json` called in this process (where the process boundary is not
    what a test is about: no interpreter to start, the code and the model version loaded once):
    (exit code, printed, the report)."""
    done = planter_here('analyze', *args, '--json')
    assert done.returncode in (0, 1), done.stderr[-3000:]
    return done.returncode, done.stderr, json.loads(done.stdout)


@pytest.fixture(scope='module')
def local(season):
    """The season analysed on the default local cluster (2 workers), tables inside the season
    (so the search must skip them)."""
    out = season / 'tables'
    r, report = analyze(season, '--out', out, '--workers', 2)
    return out, r, report


def rows_of(out):
    """The bags table by bag key (its path from the analysed root)."""
    return {row['bag']: row for row in pq.read_table(out / 'bags').to_pylist()}


def plants_of(out):
    """The plants table as replay's JSON plant dicts, by bag key."""
    table = pq.read_table(out / 'plants')
    per_bag = {}
    for bag, plant in zip(table.column('bag').to_pylist(), plant_dicts(table)):
        per_bag.setdefault(bag, []).append(plant)
    return per_bag, table


def same_plants(got, expected):
    """Plant dicts equal but the time, which the table holds as a UTC timestamp (ns)."""
    assert len(got) == len(expected)
    for a, b in zip(got, expected):
        assert a.keys() == b.keys()
        assert abs(a['time'] - b['time']) < 1e-6
        assert {k: v for k, v in a.items() if k != 'time'} == \
            {k: v for k, v in b.items() if k != 'time'}


def test_every_bag_is_found_once_and_the_tables_are_not(season, local):
    out, r, report = local
    expected = {season / 'day1' / 'a.mcap', season / 'day1' / 'b.mcap',
                season / 'day2' / 'machine' / 'c.mcap', season / 'day2' / 'split',
                season / 'day2' / 'cut.mcap', season / 'day2' / 'garbage.mcap'}
    # named by the path from the analysed root, keyed by content (a moved season still joins)
    assert set(rows_of(out)) == {p.relative_to(season).as_posix() for p in expected}
    assert all(row['path'] == str(season / bag) for bag, row in rows_of(out).items())
    assert all(row['bag_id'].startswith('sha256:') for row in rows_of(out).values())
    assert report['bags_found'] == 6 and report['workers'] == 2
    assert report['analysed'] == 5 and report['failed'] == 1 and report['with_warnings'] == 1
    assert r.returncode == 0
    # progress on stderr: bags done / total, rate, × real time; the last line says it is done
    lines = [line for line in r.stderr.splitlines() if line.startswith('planter analyze:')]
    assert lines and lines[-1].startswith('planter analyze: 6/6 bags, ')
    assert 'bags/s' in lines[-1] and '× real time' in lines[-1] and '1 failed' in lines[-1]


def test_the_tables_equal_planter_replay_json_of_every_bag(season, local, capsys):
    out, _, _ = local
    bags = rows_of(out)
    plants, table = plants_of(out)
    for bag, row in bags.items():
        code = main(['replay', str(season / bag), '--json'])
        captured = capsys.readouterr()
        if row['status'] == 'failed':
            assert code == 2 and bag not in plants
            assert captured.err == f'planter: error: {row["reason"]}\n'
            continue
        assert code == 0
        expected = json.loads(captured.out)
        same_plants(plants.get(bag, []), expected.pop('plants'))
        expected['path'] = expected.pop('bag')
        got = unflatten({k: v for k, v in row.items() if k not in OWN + ('bag',)})
        assert got == expected, bag
        assert row['status'] == ('warnings' if expected['warnings'] else 'ok')
    assert sum(len(p) for p in plants.values()) == table.num_rows > 100
    # SI units in the schemas
    assert units(table.schema)['spacing_error_m'] == 'm'
    assert table.schema.field('tilt_rad').metadata[b'unit'] == b'rad'
    bags_units = units(pq.read_schema(out / 'bags' / 'bags.parquet'))
    assert bags_units['summary.spacing_error_mean'] == 'm'
    assert bags_units['settings.upright_threshold'] == 'rad' and bags_units['duration'] == 's'


def test_a_damaged_bag_is_reported_and_the_rest_analysed(season, local):
    out, r, report = local
    bags = rows_of(out)
    garbage = bags['day2/garbage.mcap']
    assert garbage['status'] == 'failed' and 'is not an MCAP file' in garbage['reason']
    assert garbage['plants_file'] is None and '\n' not in garbage['reason']
    cut = bags['day2/cut.mcap']
    assert cut['status'] == 'warnings' and any('not finalised' in w for w in cut['warnings'])
    whole = bags['day1/a.mcap']
    assert 0 < cut['summary.plants'] < whole['summary.plants']
    assert report['failures'] == [{'bag': garbage['bag'], 'status': 'failed',
                                   'reason': garbage['reason']}]
    for row in bags.values():
        if row is not garbage:
            assert row['status'] in ('ok', 'warnings') and row['reason'] is None


def _free_port():
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def _scheduler_address(info, proc, deadline):
    """The address in the scheduler file `info` once it is there in full: dask writes it in
    place (a reader can see it created and still empty, as a loaded host showed)."""
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            return json.loads(info.read_text())['address']
        except (FileNotFoundError, ValueError, KeyError):
            time.sleep(0.1)
    pytest.fail(f'dask scheduler wrote no address to {info} (exit code {proc.poll()})')


@pytest.fixture
def dask_cluster(tmp_path):
    """`dask scheduler` and `dask worker` as separate processes on 127.0.0.1; yields the
    scheduler's address."""
    dask = Path(sys.executable).with_name('dask')
    env = dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    info = tmp_path / 'scheduler.json'
    procs = [subprocess.Popen(
        [str(dask), 'scheduler', '--host', '127.0.0.1', '--port', str(_free_port()),
         '--no-dashboard', '--scheduler-file', str(info)],
        env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        address = _scheduler_address(info, procs[0], deadline=time.monotonic() + 60)
        procs.append(subprocess.Popen(
            [str(dask), 'worker', '--scheduler-file', str(info), '--host', '127.0.0.1',
             '--nworkers', '1', '--nthreads', '1', '--no-dashboard'],
            env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        yield address
    finally:
        for proc in reversed(procs):
            proc.send_signal(signal.SIGTERM)
        for proc in reversed(procs):
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def test_a_real_dask_scheduler_and_worker_give_the_same_tables(season, local, dask_cluster,
                                                               tmp_path):
    from distributed import Client
    assert dask_cluster.startswith('tcp://127.0.0.1:')
    with Client(dask_cluster, timeout=30, set_as_default=False) as client:
        client.wait_for_workers(1, timeout=60)
        workers = client.scheduler_info()['workers']
        assert workers and all(w.startswith('tcp://127.0.0.1:') for w in workers)
    out = tmp_path / 'remote'
    # (the command in this process: the scheduler and the worker are processes of their own)
    _, _, report = analyze_here(season, '--out', out, '--scheduler', dask_cluster)
    assert report['workers'] == 1 and report['analysed'] == 5 and report['failed'] == 1
    here, there = rows_of(local[0]), rows_of(out)
    assert here.keys() == there.keys()
    for bag in here:
        assert {k: v for k, v in here[bag].items() if k not in WHEN} == \
            {k: v for k, v in there[bag].items() if k not in WHEN}
    assert plants_of(local[0])[0] == plants_of(out)[0]


@pytest.mark.slow
def test_a_rerun_skips_what_is_done_and_redoes_a_changed_bag(season, local, tmp_path):
    season = _copy(season, tmp_path / 'season')        # its bags are changed here
    out = tmp_path / 'tables'
    _, _, first = analyze_here(season, '--out', out, '--workers', 1)
    assert first['analysed'] + first['failed'] == 6 and first['skipped'] == 0
    before = (out / 'bags' / 'bags.parquet').read_bytes()
    plants, table = plants_of(out)
    # one worker in the command's process: the plants of two worker processes
    assert plants == plants_of(local[0])[0]

    report = out / 'report.html'
    outputs = [report, out / 'as_planted.zip', out / 'TASKDATA.zip']
    made = [path.stat().st_mtime_ns for path in outputs]
    drawn = made[0]
    _, _, again = analyze_here(season, '--out', out)
    assert again['skipped'] == 6 and again['analysed'] == again['failed'] == 0
    assert again['workers'] == 0                       # no cluster started for nothing
    assert (out / 'bags' / 'bags.parquet').read_bytes() == before
    # the same tables: the report and the exports kept
    assert [path.stat().st_mtime_ns for path in outputs] == made
    # outputs older than the tables (a run stopped between them): written again
    older = (out / 'bags' / 'bags.parquet').stat().st_mtime_ns - 1_000_000_000
    for path in (report, out / 'TASKDATA.zip'):
        os.utime(path, ns=(older, older))
    analyze_here(season, '--out', out)
    assert report.stat().st_mtime_ns > drawn
    assert (out / 'TASKDATA.zip').stat().st_mtime_ns > made[2]
    drawn = report.stat().st_mtime_ns

    # touched, the same content: the same bag (its new time recorded, nothing redone)
    changed = season / 'day1' / 'b.mcap'
    stat = changed.stat()
    os.utime(changed, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))
    _, _, touched = analyze_here(season, '--out', out, '--workers', 1)
    assert touched['skipped'] == 6 and touched['analysed'] == 0
    assert rows_of(out)['day1/b.mcap']['file_mtime_ns'] == stat.st_mtime_ns + 1_000_000_000
    # rewritten with another recording: analysed again, in place of the old one
    simulate_bag(tmp_path / 'other.mcap', 5, 7, 16.0, 1)
    shutil.copyfile(tmp_path / 'other.mcap', changed)
    _, _, third = analyze_here(season, '--out', out, '--workers', 1)
    assert third['skipped'] == 5 and third['analysed'] == 1
    assert report.stat().st_mtime_ns > drawn           # new tables: a new report
    rows = rows_of(out)
    assert len(rows) == 6 and rows['day1/b.mcap']['path'] == str(changed)
    now, _ = plants_of(out)
    assert {bag: p for bag, p in now.items() if bag != 'day1/b.mcap'} == {
        bag: p for bag, p in plants.items() if bag != 'day1/b.mcap'}
    assert now['day1/b.mcap'] != plants['day1/b.mcap']      # the new recording's, once
    plants = now

    _, _, forced = analyze_here(season, '--out', out, '--workers', 1, '--force')
    assert forced['skipped'] == 0 and forced['analysed'] + forced['failed'] == 6
    assert plants_of(out)[0] == plants
    # every part file is claimed by a bag of the table
    claimed = {row['plants_file'] for row in rows_of(out).values()} - {None}
    assert {p.name for p in (out / 'plants').iterdir()} == claimed

    _, _, window = analyze_here(season, '--out', out, '--workers', 1, '--window', 5)
    assert window['analysed'] + window['failed'] == 6        # other settings: done again
    assert all(row['settings.window'] == 5 for row in rows_of(out).values()
               if row['status'] != 'failed')


def _copy(season, to):
    """A copy of the season (times kept), without the tables of other tests."""
    shutil.copytree(season, to, ignore=shutil.ignore_patterns('tables'))
    return to


def test_out_into_a_bad_place_is_refused_before_any_work(season, tmp_path, capsys):
    (tmp_path / 'notes.txt').write_text('mine\n')
    (tmp_path / 'foreign').mkdir()
    (tmp_path / 'foreign' / 'photo.jpg').write_bytes(b'\xff\xd8')
    (tmp_path / 'broken' / 'bags').mkdir(parents=True)
    (tmp_path / 'broken' / 'bags' / 'bags.parquet').write_bytes(b'not parquet')
    cases = {tmp_path / 'notes.txt': 'exists and is not a directory',
             tmp_path / 'missing' / 'out': 'does not exist',
             tmp_path / 'foreign': 'holds other files',
             tmp_path / 'broken': 'is not a readable bags table'}
    for out, words in cases.items():
        # a PATH that does not exist: refused for --out first, so nothing else was looked at
        assert main(['analyze', str(tmp_path / 'no-such-bags'), '--out', str(out)]) == 2
        err = capsys.readouterr().err
        assert err.startswith('planter: error: --out') and words in err, err
        assert err.count('\n') == 1
    assert not (tmp_path / 'missing').exists()
    assert sorted(p.name for p in (tmp_path / 'foreign').iterdir()) == ['photo.jpg']
    r = run_planter('analyze', season, '--out', tmp_path / 'notes.txt')
    assert r.returncode == 2 and r.stderr.count('\n') == 1 and 'Traceback' not in r.stderr


@pytest.mark.parametrize('args, words', [
    (['--workers', '0'], '--workers = 0 is out of range'),
    (['--scheduler', 'somewhere'], 'is not a scheduler address'),
    (['--workers', '2', '--scheduler', 'tcp://127.0.0.1:1'], 'not allowed with argument'),
    (['--window', '0'], '--window = 0 is out of range'),
])
def test_bad_options_are_one_line(args, words, season, tmp_path, capsys):
    assert main(['analyze', str(season), '--out', str(tmp_path / 'out'), *args]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count('\n') == 1
    assert not (tmp_path / 'out').exists()


def test_no_bags_and_no_scheduler_are_refused(tmp_path, capsys, monkeypatch):
    from planter_ros.analysis import engine
    (tmp_path / 'empty').mkdir()
    assert main(['analyze', str(tmp_path / 'empty'), '--out', str(tmp_path / 'out')]) == 2
    assert 'holds no bag' in capsys.readouterr().err
    (tmp_path / 'empty' / 'run.mcap').write_bytes(b'x')
    monkeypatch.setattr(engine, 'CONNECT_TIMEOUT', 1.0)
    assert main(['analyze', str(tmp_path / 'empty'), '--out', str(tmp_path / 'out'),
                 '--scheduler', f'tcp://127.0.0.1:{_free_port()}']) == 2
    err = capsys.readouterr().err
    assert 'cannot connect' in err and err.count('\n') == 1
    assert not (tmp_path / 'out').exists()            # made for nothing: removed again
    shutil.rmtree(tmp_path / 'empty')


@pytest.mark.slow
def test_tables_people_read_with_pandas_dask_and_duckdb(season, local, tmp_path):
    """Row names, UTC times, integer and boolean types, units; each table in its own folder;
    the reads doc/analysis.md shows; a season moved elsewhere still joins (nothing redone)."""
    import dask.dataframe as dd
    import duckdb
    import pandas as pd
    out, _, _ = local
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == ['bags', 'plants']
    schema = pq.read_schema(next((out / 'plants').glob('*.parquet')))
    assert str(schema.field('upright').type) == 'bool'
    assert str(schema.field('input_gap').type) == 'bool'
    assert str(schema.field('status').type) == 'string'
    plants = pd.read_parquet(out / 'plants')
    assert str(plants['index'].dtype) == 'int64' and str(plants['row'].dtype) == 'int64'
    # upright is null for an instant in an input gap: pandas' nullable boolean
    nullable = pd.read_parquet(out / 'plants', dtype_backend='numpy_nullable')
    assert str(nullable['upright'].dtype) == 'boolean'
    assert nullable['upright'].isna().sum() == plants['input_gap'].sum() > 0
    assert str(plants['time_utc'].dtype).startswith('datetime64[ns, UTC]')
    assert plants['time_utc'].min() > pd.Timestamp('2000-01-01', tz='UTC')
    four = plants[plants['bag'] == 'day1/a.mcap']
    assert sorted(four['row_name'].unique()) == sorted(
        r['name'] for r in rows_of(out)['day1/a.mcap']['rows'])
    assert set(plants[plants['bag'] == 'day1/b.mcap']['row_name']) <= {'row', 'center'} or \
        plants[plants['bag'] == 'day1/b.mcap']['row_name'].str.len().min() > 0
    bags = pd.read_parquet(out / 'bags')
    assert str(bags['analysed_at'].dtype).startswith('datetime64[ns, UTC]')
    lazy = dd.read_parquet(str(out / 'plants'))
    assert len(lazy) == len(plants)
    per_row = duckdb.sql(
        f"SELECT bag, row_name, count(*) AS plants, avg(hole_width_m) AS hole_m "
        f"FROM read_parquet('{out}/plants/*.parquet') GROUP BY ALL").df()
    assert per_row['plants'].sum() == len(plants)
    # units: every number of either table has one (schema metadata), the ambiguous in the name
    for table in (pq.read_table(out / 'plants'), pq.read_table(out / 'bags')):
        known = units(table.schema)
        numbers = [f.name for f in table.schema if str(f.type) in ('double', 'int64')]
        assert [n for n in numbers if n not in known] == []
    # moved: the same keys, nothing analysed again
    shutil.copytree(out, tmp_path / 'tables')
    analyze_here(season, '--out', tmp_path / 'tables', '--workers', 1)  # up to date (other
    moved = tmp_path / 'moved'                                          # tests touch the season)
    shutil.copytree(season, moved, ignore=shutil.ignore_patterns('tables'))
    _, _, again = analyze_here(moved, '--out', tmp_path / 'tables', '--workers', 1)
    assert again['skipped'] == 6 and again['analysed'] == 0


def test_the_season_report_per_field_day_and_row_and_its_html(season, local, tmp_path):
    """`planter analyze` prints one line per field, day and row (instants, ISO indices,
    uprightness, hole width, verdict naming what failed) and writes one self-contained HTML
    report next to the tables: its figures embedded, nothing fetched from elsewhere."""
    import re

    import pandas as pd
    out, _, report = local
    html_path = Path(report['report'])
    assert html_path == out / 'report.html' and html_path.is_file()
    printed = io.StringIO()                                   # nothing to do: printed
    with contextlib.redirect_stdout(printed):
        assert main(['analyze', str(season), '--out', str(out)]) == 0
    lines = printed.getvalue().splitlines()
    head = next(i for i, line in enumerate(lines) if line.split()[:2] == ['field', 'day'])
    end = lines.index(f'season report: {html_path}')
    table = lines[head + 1:end]
    plants = pd.read_parquet(out / 'plants')
    plants['field'] = [str(Path(b).parent) for b in plants['bag']]
    plants['day'] = plants['time_utc'].dt.strftime('%Y-%m-%d')
    groups = plants.groupby(['field', 'day', 'row_name']).size()
    assert len(table) == len(groups)
    for line in table:
        field, day, row, instants = line.split()[:4]
        assert groups[(field, day, row)] == int(instants)
        assert ' PASS' in line or re.search(r' FAIL  \((max|min)_\w+', line), line
    text = html_path.read_text()
    assert text.count('<img alt="figure" src="data:image/png;base64,') >= 3
    assert not re.search(r'(src|href)="(?!data:)', text)              # self-contained
    assert text.count('<tr class=') == len(groups)


# A worker's close cuts its comms while a heartbeat to the scheduler may be on its way: the
# heartbeat fails with "Stream is closed" and distributed logs it with its traceback (a race in
# distributed's Worker.close). The script makes that race happen every time, at the moment it
# does: the failing heartbeat's log record, written as the worker's comms are closed.
CLOSE_RACE = '''
import logging
from distributed.comm.core import CommClosedError
from planter_ros.analysis.engine import cluster


def heartbeat_in_flight(dask_worker):
    close = dask_worker.rpc.close

    async def cut():
        try:
            raise CommClosedError('in <TCP (closed) ConnectionPool.heartbeat_worker>: '
                                  'Stream is closed')
        except CommClosedError:
            logging.getLogger('distributed.worker').exception(
                'Failed to communicate with scheduler during heartbeat.')
        await close()
    dask_worker.rpc.close = cut
    return True


if __name__ == '__main__':
    with cluster(2) as client:
        assert all(client.run(heartbeat_in_flight).values())
    print('closed')
'''


def test_a_heartbeat_cut_by_the_local_clusters_close_leaves_no_traceback(tmp_path):
    """What the user of `planter analyze` or `planter simulate` sees when the local cluster
    closes while a worker's heartbeat is in flight: nothing (the workers share the command's
    stderr)."""
    script = tmp_path / 'close_race.py'
    script.write_text(CLOSE_RACE)
    env = {**os.environ, 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                       timeout=120, env=env, cwd=tmp_path)
    assert r.returncode == 0 and r.stdout.strip() == 'closed', r.stderr[-3000:]
    assert 'Traceback' not in r.stderr and 'Stream is closed' not in r.stderr, r.stderr[-3000:]


def test_one_worker_runs_in_the_commands_process_more_run_in_processes_of_their_own():
    """`--workers 1` starts no worker process (the analysis in the command's own process); two
    workers are processes of their own. (The same plants either way: the re-run test.)"""
    from planter_ros.analysis.engine import cluster
    with cluster(workers=1, in_process=True) as client:
        assert list(client.run(os.getpid).values()) == [os.getpid()]
    with cluster(workers=2) as client:
        pids = set(client.run(os.getpid).values())
    assert len(pids) == 2 and os.getpid() not in pids
    with pytest.raises(ValueError):
        with cluster(workers=2, in_process=True):
            pass
