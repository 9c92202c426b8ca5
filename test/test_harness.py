"""The test harness itself (conftest.py, host_stalls.py) cannot hide a failure.

Each test runs pytest on a small test file of its own in a subprocess, with this directory's
conftest.py as its plugin, as CI would run it, and reads its exit code, its terminal output and
its JUnit file:

* a real-time test that fails only on its first run fails the session;
* one that failed while the host stalled (injected: the stall watcher is stopped for 0.3 s, as
  a host that leaves it unscheduled would) runs once more, and its first failure and the stall
  are in the terminal summary and in the JUnit file; two such re-runs fail the session; one that
  fails again fails;
* a test that uses a live fixture or starts something live without the realtime marker fails,
  naming the marker; a test marked flaky fails, and --reruns is refused (pytest-rerunfailures
  comes with colcon);
* a session started 5 below this one's priority runs nothing, not even the stall watcher,
  above that, and the tests not marked realtime 10 below it (a loop of the product under test
  runs at the product's own SCHED_FIFO, as its command process does, and only while it runs:
  drive_helpers.as_the_command_process); the real-time tests live in
  processes of their own run first, on the first two processes, those live in the test process
  then, on the same two and the third, never beside one of the first kind; on the first two
  both before the others; the fourth process runs no real-time test.
"""
import os
from pathlib import Path
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

HERE = Path(__file__).resolve().parent
# the inner sessions load this directory's conftest and the plugins the suite names (pytest.ini)
INI = """[pytest]
addopts = -p conftest -p no:cacheprovider
    --disable-plugin-autoload -p xdist.plugin -p xdist.looponfail -p _hypothesis_pytestplugin
    -p pytest_rerunfailures
markers =
    slow: slow
    realtime: real-time
"""
FLAKY = """
import os
from pathlib import Path

import pytest

import host_stalls


def first_run(name):
    path = Path(os.environ['RUNS']) / name
    runs = int(path.read_text()) + 1 if path.exists() else 1
    path.write_text(str(runs))
    return runs == 1


def stall():
    if os.environ.get('STALL'):
        host_stalls.pause_watcher(0.3)
"""


def pytest_run(tmp_path, source, *args, env=None, nice=0, modules=None):
    """Run pytest on `source` (test_inner.py; `modules`: {file name: source} instead) in
    `tmp_path`: (the finished process, the JUnit file's root)."""
    tmp_path.mkdir(exist_ok=True)
    for name, text in (modules or {'test_inner.py': source}).items():
        (tmp_path / name).write_text(text)
    (tmp_path / 'pytest.ini').write_text(INI)
    (tmp_path / 'runs').mkdir()
    junit = tmp_path / 'junit.xml'
    environ = dict(os.environ, RUNS=str(tmp_path / 'runs'), **(env or {}))
    environ['PYTHONPATH'] = os.pathsep.join(filter(None, (str(HERE),
                                                          os.environ.get('PYTHONPATH'))))
    out = subprocess.run(
        [sys.executable, '-m', 'pytest', '-rA', f'--junitxml={junit}',
         f'--basetemp={tmp_path / "base"}', *args], cwd=tmp_path, env=environ,
        capture_output=True, text=True, timeout=180,
        preexec_fn=(lambda: os.nice(nice)) if nice else None)
    return out, (ET.parse(junit).getroot() if junit.exists() else None)


def cases(junit):
    """{test name: (its properties, its failure/error elements' messages)} of a JUnit file."""
    out = {}
    for case in junit.iter('testcase'):
        props = {p.get('name'): p.get('value') for p in case.iter('property')}
        failures = [e.get('message') or '' for e in case if e.tag in ('failure', 'error')]
        out[case.get('name')] = (props, failures)
    return out


def test_a_realtime_test_that_fails_only_on_its_first_run_fails_the_session(tmp_path):
    out, junit = pytest_run(tmp_path, FLAKY + """
@pytest.mark.realtime
def test_flaky():
    assert not first_run('flaky'), 'wrong on the first run only'
""", '-n', '0', env={'PLANTER_TEST_STARVED': '1000'})     # no host stall can count
    assert out.returncode == 1, out.stdout[-3000:]
    assert 'wrong on the first run only' in out.stdout
    assert cases(junit)['test_flaky'][1]
    assert (tmp_path / 'runs' / 'flaky').read_text() == '1'       # run once


def test_a_rerun_after_a_host_stall_is_shown_in_the_summary_and_the_junit_file(tmp_path):
    """Under xdist (the suite's way): the re-run's record crosses from the worker."""
    out, junit = pytest_run(tmp_path, FLAKY + """
@pytest.mark.realtime
def test_flaky():
    if first_run('flaky'):
        stall()
        assert False, 'wrong on the first run only'
""", '-n', '2', env={'STALL': '1'})
    assert out.returncode == 0, out.stdout[-3000:]
    summary = out.stdout[out.stdout.index('real-time tests run twice after a host stall'):]
    line = next(line for line in summary.splitlines() if 'test_inner.py::test_flaky' in line)
    assert 'unscheduled for' in line and 'wrong on the first run only' in line
    assert line.endswith('the second run passed')
    props, failures = cases(junit)['test_flaky']
    assert failures == []
    assert 'unscheduled for' in props['host_stall_rerun']
    assert 'wrong on the first run only' in props['first_failure']


def test_more_than_one_rerun_fails_the_session_and_a_second_failure_stands(tmp_path):
    out, junit = pytest_run(tmp_path, FLAKY + """
@pytest.mark.realtime
def test_flaky_a():
    if first_run('a'):
        stall()
        assert False, 'a: wrong on the first run only'


@pytest.mark.realtime
def test_flaky_b():
    if first_run('b'):
        stall()
        assert False, 'b: wrong on the first run only'


@pytest.mark.realtime
def test_wrong_twice():
    first_run('c')
    stall()
    assert False, 'wrong every time'
""", '-n', '0', env={'STALL': '1'})
    assert out.returncode == 1, out.stdout[-3000:]
    assert '3 tests needed a second run (at most one may): the session fails' in out.stdout
    found = cases(junit)
    assert found['test_flaky_a'][1] == [] and found['test_flaky_b'][1] == []
    props, failures = found['test_wrong_twice']
    assert failures and 'wrong every time' in props['first_failure']
    assert (tmp_path / 'runs' / 'c').read_text() == '2'


def test_a_live_test_without_the_marker_fails_naming_it(tmp_path):
    out, junit = pytest_run(tmp_path, """
import pytest


def test_on_a_bus(channel):
    pass


@pytest.fixture
def machine():
    from planter_ros.simdrive.bus import SimulatedBus
    return SimulatedBus


def test_through_a_fixture(machine):
    pass


def test_a_demo():                      # (stopped at its set-up: no demo runs)
    from cli_helpers import run_planter
    run_planter('demo', '--duration', '8')


@pytest.mark.realtime
def test_marked(channel):
    pass


@pytest.mark.flaky(reruns=3)
def test_retried():
    pass


def test_pure():
    pass
""", '-n', '0')
    assert out.returncode == 1, out.stdout[-3000:]
    found = cases(junit)
    assert "must be marked realtime (it uses the live fixture 'channel')" in \
        found['test_on_a_bus'][1][0]
    assert 'must be marked realtime (it uses SimulatedBus)' in \
        found['test_through_a_fixture'][1][0]
    assert 'must be marked realtime (it runs `planter demo' in found['test_a_demo'][1][0]
    assert 'flaky: a re-run that hides its first failure' in found['test_retried'][1][0]
    assert found['test_marked'][1] == [] and found['test_pure'][1] == []
    out, junit = pytest_run(tmp_path / 'again', 'def test_pure():\n    pass\n', '-n', '0',
                            '--reruns', '2')
    assert out.returncode == 4 and '--reruns re-runs a failed test' in out.stderr


PRIORITY = """
import os
import time

import pytest

import host_stalls

def note(kind):
    with open(os.path.join(os.environ['RUNS'], 'nice'), 'a') as f:
        f.write(f"{kind} {os.environ.get('PYTEST_XDIST_WORKER')} "
                f"{os.getpriority(os.PRIO_PROCESS, 0)} {time.monotonic()}\\n")
"""


@pytest.mark.slow
def test_nothing_runs_above_the_sessions_priority_and_realtime_tests_run_on_their_lanes_first(
        tmp_path):
    here = PRIORITY + """
pytestmark = pytest.mark.realtime


def test_here_1(channel):           # a live fixture: live in the test process
    note('here')
    w = host_stalls.watcher().pid
    with open(os.path.join(os.environ['RUNS'], 'watcher'), 'w') as f:
        f.write(str(os.getpriority(os.PRIO_PROCESS, w)))
    time.sleep(1.0)
    note('end')


def test_here_2(channel):
    note('here')
    time.sleep(1.0)
    note('end')
"""
    apart = PRIORITY + """
pytestmark = pytest.mark.realtime


def start_demo():                   # (the name of a demo run: live in processes of its own)
    time.sleep(1.0)


def test_apart_1():
    note('apart')
    start_demo()
    note('end')


def test_apart_2():
    note('apart')
    start_demo()
    note('end')
"""
    other = PRIORITY + """
@pytest.mark.realtime
def test_here_3(channel):
    note('here')
    time.sleep(1.0)
    note('end')


def test_other_1():
    note('other')


def test_other_2():
    note('other')
"""
    # 5 below this process's priority (which may already be lowered: the suite runs this
    # test beside the real-time ones)
    start = min(os.getpriority(os.PRIO_PROCESS, 0) + 5, 19)
    out, junit = pytest_run(tmp_path, None, '-n', '4', nice=5,
                            modules={'test_a.py': here, 'test_b.py': other,
                                     'test_c.py': apart, 'test_d.py': apart})
    assert out.returncode == 0, out.stdout[-3000:]
    runs = [line.split() for line in (tmp_path / 'runs' / 'nice').read_text().splitlines()]
    assert len(runs) == 7 * 2 + 2, runs              # 7 real-time (start, end), 2 others
    nice = {'here': start, 'apart': start, 'other': min(start + 10, 19)}
    assert all(int(n) == nice[kind] for kind, _, n, _ in runs if kind != 'end'), runs
    assert int((tmp_path / 'runs' / 'watcher').read_text()) >= start
    # the first two processes run the demo-like tests, two at once; the third may take the
    # tests live in the test process too, once those are done; the fourth none
    assert {worker for kind, worker, _, _ in runs if kind == 'here'} <= {'gw0', 'gw1', 'gw2'}
    assert {worker for kind, worker, _, _ in runs if kind == 'apart'} == {'gw0', 'gw1'}
    spans = {}
    for kind, worker, _, at in sorted(runs, key=lambda r: float(r[3])):
        if kind in ('here', 'apart'):
            spans[worker] = (kind, float(at))
        elif kind == 'end':
            spans.setdefault('done', []).append((*spans.pop(worker), float(at)))
    done = spans['done']
    edges = sorted([(s0, +1) for _, s0, _ in done] + [(s1, -1) for _, _, s1 in done])
    assert max(sum(step for _, step in edges[:k + 1]) for k in range(len(edges))) <= 3, done
    for kind, start_at, end_at in done:          # a HERE test never beside an APART one
        beside = [k for k, s0, s1 in done if s0 < end_at and s1 > start_at]
        assert kind == 'apart' or 'apart' not in beside, done
    assert max(s0 for k, s0, _ in done if k == 'apart') < min(s0 for k, s0, _ in done
                                                            if k == 'here'), done
    # on a process that runs both, the real-time tests first
    for lane in ('gw0', 'gw1'):
        there = [kind for kind, worker, _, _ in sorted(runs, key=lambda r: float(r[3]))
                 if worker == lane and kind != 'end']
        assert there == sorted(there, key=lambda kind: kind == 'other'), runs


def test_a_loop_under_test_runs_at_the_command_process_priority_only_while_it_runs():
    from drive_helpers import SWITCH_INTERVAL, SyncLoopConfig, as_the_command_process

    def policies():
        tids = os.listdir('/proc/self/task')
        return {os.sched_getscheduler(int(tid)) for tid in tids}
    interval = sys.getswitchinterval()
    with as_the_command_process():
        inside = policies(), sys.getswitchinterval()
        fifo = os.sched_getparam(0).sched_priority
    if os.SCHED_FIFO in inside[0]:            # granted (root or CAP_SYS_NICE)
        assert inside[0] == {os.SCHED_FIFO} and fifo == SyncLoopConfig().realtime_priority
    assert inside[1] == SWITCH_INTERVAL
    assert policies() == {os.SCHED_OTHER} and sys.getswitchinterval() == interval
