"""Outside services and odd files in `planter analyze`, `planter simulate` and `planter
replay` (issue 32's held-out cases): each is refused in one line with exit 2, or handled, and
none hangs, ends in a traceback or replaces a file the command did not write.

* `--scheduler` at a port that accepts and never answers, at an HTTP server, at a server that
  answers garbage: one line within the connect timeout (set to 1 s here), nothing left behind;
* a FIFO named `.mcap`, a symbolic link to nothing: refused as PATH/BAG, named and skipped
  inside a folder;
* `--out` over a folder holding a user's own `bags.parquet` or `report.html`, or a file of an
  earlier output the user replaced: refused, the user's file untouched;
* `simulate` with empty and double shares over 100 % of the cells, or an empty PATH: refused;
* a run that planted nothing: acceptance FAIL (it was PASS), every output still written.

Network: servers on 127.0.0.1 only, each bounded in time and closed by the test."""
import contextlib
from dataclasses import replace
import http.server
import io
import json
import os
import socket
import threading
import time

import pytest

from cli_helpers import run_planter
from planter_ros.cli.main import main


def run_cli(argv):
    out, err = io.StringIO(), io.StringIO()
    started = time.monotonic()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue(), time.monotonic() - started


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    from planter_ros.sim.season import simulate_bag
    path = tmp_path_factory.mktemp('services') / 'run.mcap'
    simulate_bag(path, 1, 0, 12.0, 2)
    return path


# ------------------------------------------------------------------- servers on 127.0.0.1

class Server:
    """A TCP server on 127.0.0.1 in a thread: `answer(connection)` for each connection
    (None: accept and never answer); closed by `close()` (at most `life` s)."""

    def __init__(self, answer=None, life=60.0):
        self.sock = socket.socket()
        self.sock.bind(('127.0.0.1', 0))
        self.sock.listen(16)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.answer, self.end = answer, time.monotonic() + life
        self.connections, self.stopped = [], threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self):
        while not self.stopped.is_set() and time.monotonic() < self.end:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                continue
            self.connections.append(conn)
            if self.answer is not None:
                self.answer(conn)

    def close(self):
        self.stopped.set()
        self.thread.join(5)
        for conn in self.connections:
            conn.close()
        self.sock.close()


@pytest.fixture
def quick_connect(monkeypatch):
    from planter_ros.analysis import engine
    # loaded before a command is timed (the commands load it lazily): on a loaded host its
    # first import in this process took seconds, which are not the connect timeout timed here
    import distributed  # noqa: F401
    monkeypatch.setattr(engine, 'CONNECT_TIMEOUT', 1.0)
    monkeypatch.setattr(engine, 'HANDSHAKE_GRACE', 1.0)


def _refused(code, out, err, seconds, *words):
    assert code == 2, err
    assert err.count('\n') == 1 and err.startswith('planter: error: --scheduler'), err
    assert 'Traceback' not in err and out == ''
    for word in words:
        assert word in err, err
    assert seconds < 8.0, seconds            # the 1 s connect timeout, not Dask's minutes


@pytest.mark.parametrize('command', ['analyze', 'simulate'])
def test_a_scheduler_port_that_accepts_and_never_answers(command, bag, tmp_path,
                                                         quick_connect):
    server = Server()
    try:
        address = f'tcp://127.0.0.1:{server.port}'
        args = (['analyze', bag, '--out', tmp_path / 'out'] if command == 'analyze' else
                ['simulate', tmp_path / 'sim', '--bags', 1, '--duration', 10])
        _refused(*run_cli(args + ['--scheduler', address]), 'no Dask scheduler answered')
        assert server.connections                       # it did connect, and gave up
    finally:
        server.close()
    assert not (tmp_path / 'out').exists() and not (tmp_path / 'sim').exists()


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):          # (the server's log is not the command's stderr)
        pass


def test_an_http_server_as_the_scheduler(bag, tmp_path, quick_connect):
    httpd = http.server.ThreadingHTTPServer(('127.0.0.1', 0), QuietHandler)
    thread = threading.Thread(target=httpd.serve_forever, kwargs={'poll_interval': 0.1},
                              daemon=True)
    thread.start()
    try:
        address = f'tcp://127.0.0.1:{httpd.server_address[1]}'
        _refused(*run_cli(['analyze', bag, '--out', tmp_path / 'out', '--scheduler', address]))
    finally:
        httpd.shutdown()
        httpd.server_close()
    assert not (tmp_path / 'out').exists()


def test_a_server_that_answers_something_else(bag, tmp_path, quick_connect):
    """An HTTP error page at once, then the connection closed: what answers is not Dask."""
    def page(conn):
        conn.sendall(b'HTTP/1.0 400 Bad Request\r\nContent-Type: text/html\r\n\r\n'
                     b'<html>bad request</html>\n' * 4)
        conn.close()
    server = Server(page)
    try:
        address = f'tcp://127.0.0.1:{server.port}'
        code, out, err, seconds = run_cli(['analyze', bag, '--out', tmp_path / 'out',
                                           '--scheduler', address])
        _refused(code, out, err, seconds)
        assert 'not a Dask scheduler' in err or 'cannot connect' in err
    finally:
        server.close()


# ---------------------------------------------------------------------------- odd files

@pytest.mark.slow
def test_a_fifo_named_mcap_is_refused_and_skipped(bag, tmp_path):
    fifo = tmp_path / 'stream.mcap'
    os.mkfifo(fifo)
    # as BAG or PATH: refused at once (in a child process: a hang fails on the timeout)
    r = run_planter('replay', fifo, timeout=60)
    assert r.returncode == 2 and r.stderr == f'planter: error: BAG = {fifo} is a FIFO, not a ' \
        'bag: allowed a .mcap file or a rosbag2 bag directory\n'
    r = run_planter('analyze', fifo, '--out', tmp_path / 'out', timeout=60)
    assert r.returncode == 2 and 'is a FIFO, not a bag' in r.stderr
    assert r.stderr.count('\n') == 1 and not (tmp_path / 'out').exists()
    # in a folder with a bag and a link to nothing: both named, the bag analysed
    folder = tmp_path / 'field'
    folder.mkdir()
    os.mkfifo(folder / 'pipe.mcap')
    os.symlink(tmp_path / 'gone.mcap', folder / 'gone.mcap')
    os.link(bag, folder / 'run.mcap')
    r = run_planter('analyze', folder, '--out', tmp_path / 'out', '--workers', 1, '--json',
                    timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert 'Traceback' not in r.stderr
    assert f'planter: warning: {folder / "gone.mcap"} is a symbolic link to nothing, not a ' \
        'bag: skipped' in r.stderr
    assert f'planter: warning: {folder / "pipe.mcap"} is a FIFO, not a bag: skipped' in r.stderr
    report = json.loads(r.stdout)
    assert report['bags_found'] == 1 and report['analysed'] == 1


def test_a_symbolic_link_to_nothing_given_is_one_line(tmp_path):
    link = tmp_path / 'gone.mcap'
    os.symlink(tmp_path / 'nowhere.mcap', link)
    code, out, err, _ = run_cli(['analyze', link, '--out', tmp_path / 'out'])
    assert code == 2 and err.count('\n') == 1 and 'a symbolic link to nothing' in err
    code, out, err, _ = run_cli(['replay', link])
    assert code == 2 and err.count('\n') == 1 and 'does not exist' in err


# ------------------------------------------------------------------------ users' files

@pytest.mark.slow
def test_out_over_a_users_own_files_is_refused_and_they_are_kept(bag, tmp_path):
    mine = {'bags.parquet': b'PAR1 my own table PAR1', 'report.html': b'<html>my report</html>'}
    for name, content in mine.items():
        folder = tmp_path / name.split('.')[0]
        folder.mkdir()
        (folder / name).write_bytes(content)
        code, out, err, _ = run_cli(['analyze', bag, '--out', folder])
        assert code == 2 and err.count('\n') == 1 and f'holds other files ({name})' in err
        assert [p.name for p in folder.iterdir()] == [name]
        assert (folder / name).read_bytes() == content
    # an earlier output whose report.html the user replaced with their own: kept
    out = tmp_path / 'season'
    r = run_planter('analyze', bag, '--out', out, '--workers', 1, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    (out / 'report.html').write_bytes(mine['report.html'])
    (out / 'notes.txt').write_text('the field was wet\n')          # theirs, beside ours
    code, _, err, _ = run_cli(['analyze', bag, '--out', out])
    assert code == 2 and err.count('\n') == 1
    assert 'holds report.html, which planter analyze did not write' in err
    assert (out / 'report.html').read_bytes() == mine['report.html']
    # moved away: the output is the command's again, the user's notes untouched
    (out / 'report.html').unlink()
    r = run_planter('analyze', bag, '--out', out, '--workers', 1, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (out / 'report.html').is_file()
    assert (out / 'notes.txt').read_text() == 'the field was wet\n'


# ----------------------------------------------------------------------------- simulate

@pytest.mark.parametrize('args, words', [
    (['--empty-rate', '0.8', '--double-rate', '0.8'], '= 160 % of the cells'),
    (['--empty-rate', '0.6', '--double-rate', '0.41'], '= 101 % of the cells'),
])
def test_simulate_refuses_a_tray_of_more_than_all_its_cells(args, words, tmp_path):
    code, out, err, _ = run_cli(['simulate', tmp_path / 'sim', '--bags', 1, *args])
    assert code == 2 and err.count('\n') == 1 and words in err, err
    assert not (tmp_path / 'sim').exists()


def test_simulate_and_analyze_refuse_an_empty_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)                   # '' would be the working directory
    code, _, err, _ = run_cli(['simulate', '', '--bags', 1, '--duration', 10])
    assert code == 2 and err.startswith('planter: error: PATH is empty')
    code, _, err, _ = run_cli(['analyze', '', '--out', tmp_path / 'out'])
    assert code == 2 and err.startswith('planter: error: PATH is empty')
    code, _, err, _ = run_cli(['replay', ''])
    assert code == 2 and err.startswith('planter: error: BAG is empty')
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------- nothing planted

@pytest.fixture(scope='module')
def nothing_planted(tmp_path_factory):
    """Two 2-row runs that put no seedling in the ground: one standing still all along (no
    planting instant), one whose tray is all empty cells."""
    from planter_ros.sim.field import Stop
    from planter_ros.sim.season import draw_plan, simulate_plan, write_monitor_bag
    folder = tmp_path_factory.mktemp('nothing')
    still = replace(draw_plan(0, 0, 12.0, 2), stops=(Stop(0.0, 30.0),), curves=(),
                    glitches=(), stall=None)
    write_monitor_bag(simulate_plan(still), folder / 'still.mcap')
    write_monitor_bag(simulate_plan(replace(draw_plan(0, 1, 12.0, 2), empty_rate=1.0)),
                      folder / 'empty.mcap')
    return folder


@pytest.mark.parametrize('name', ['still', 'empty'])
def test_a_run_that_planted_nothing_does_not_pass(nothing_planted, name, tmp_path):
    bag = nothing_planted / f'{name}.mcap'
    code, out, err, _ = run_cli(['replay', bag, '--json'])
    assert code == 0, err
    acceptance = json.loads(out)['acceptance']
    assert acceptance['passed'] is False
    assert [f['index'] for f in acceptance['failed']] == ['planted', 'planted']
    files = {'plot': tmp_path / 'r.png', 'csv': tmp_path / 'p.csv',
             'geojson': tmp_path / 'p.geojson', 'shapefile': tmp_path / 'p.zip',
             'isoxml': tmp_path / 'td'}
    code, out, err, _ = run_cli(['replay', bag] + [x for k, p in files.items()
                                                   for x in (f'--{k}', p)])
    assert code == 0, err
    line = next(t for t in out.splitlines() if t.startswith('acceptance'))
    assert ': FAIL: row row_1: planted nothing' in line and 'PASS' not in line
    assert all(p.exists() for p in files.values())


@pytest.mark.slow
def test_a_busy_port_8787_makes_no_noise(tmp_path):
    """The local cluster's scheduler serves its HTTP routes on a free loopback port: with
    Dask's default 8787 taken (another cluster, another tool), no 'Port 8787 is already in use'
    on stderr."""
    holder = socket.socket()
    try:
        holder.bind(('127.0.0.1', 8787))
        holder.listen(1)
    except OSError:
        pass                                     # someone else holds it: busy all the same
    try:
        r = run_planter('simulate', tmp_path / 'sim', '--bags', 1, '--duration', 10,
                        '--workers', 1, timeout=300)
    finally:
        holder.close()
    assert r.returncode == 0, r.stderr[-2000:]
    assert 'already in use' not in r.stderr and 'Warning' not in r.stderr, r.stderr
