"""Every helper process the product starts dies with the process that started it, also when that
one is killed with SIGKILL (a CI time limit, the OOM killer): the bench's CPU hogs, the local
Dask cluster's workers, the optimiser's pool, the demo's sync process. Each test starts the
command as a user's script would, waits until its helpers run, SIGKILLs the command alone (not
its process group) and finds none of its processes alive 5 s later."""
import os
import shutil
import signal
import subprocess
import sys
import time

import psutil
import pytest

from cli_helpers import REPO

from planter_ros.host.processes import supported

pytestmark = [pytest.mark.realtime(apart=True),         # (test/conftest.py)
              pytest.mark.skipif(not supported(), reason='needs Linux prctl(PR_SET_PDEATHSIG)')]

GRACE = 5.0          # s the helpers may take to go


def start(args, tmp_path, cwd=None):
    env = dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    out = open(tmp_path / 'stdout.txt', 'w')
    err = open(tmp_path / 'stderr.txt', 'w')
    proc = subprocess.Popen([sys.executable, *args], stdout=out, stderr=err, env=env,
                            cwd=cwd or tmp_path, start_new_session=True)
    out.close()
    err.close()
    return proc


def wait_for(proc, ready, tmp_path, timeout=120.0):
    """Poll until ready(descendant processes, stdout text) is true; returns the descendants."""
    parent = psutil.Process(proc.pid)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, (
            f'the command ended (exit {proc.returncode}) before its helpers were seen: '
            + (tmp_path / 'stderr.txt').read_text()[-1000:])
        try:
            children = parent.children(recursive=True)
        except psutil.NoSuchProcess:
            children = []
        if ready(children, (tmp_path / 'stdout.txt').read_text()):
            return children
        time.sleep(0.1)
    raise AssertionError(f'helpers not seen within {timeout:g} s')


def survivors_of_sigkill(proc, children):
    """SIGKILL `proc` alone; the `children` still running GRACE s later (then killed here)."""
    children = children + [c for c in _alive_descendants(proc) if c not in children]
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(10)
    alive = still_running(children, GRACE)
    left = [(c.pid, _cmdline(c)) for c in alive]
    for c in alive:                      # leave nothing behind, whatever the verdict
        try:
            c.kill()
        except psutil.NoSuchProcess:
            pass
    return left


def still_running(processes, timeout):
    """The `processes` still running after at most `timeout` s. One that has ended but is not
    yet reaped (a zombie: its parent killed, init has not collected it yet, which a loaded host
    was seen to take over 5 s to do) has ended."""
    deadline = time.monotonic() + timeout
    while True:
        alive = [p for p in processes if _running(p)]
        if not alive or time.monotonic() >= deadline:
            return alive
        time.sleep(0.05)


def _running(process):
    try:
        return process.is_running() and process.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def _alive_descendants(proc):
    try:
        return psutil.Process(proc.pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def _cmdline(process):
    try:
        return ' '.join(process.cmdline())[:120]
    except psutil.Error:
        return '?'


def named(children, text):
    found = []
    for c in children:
        try:
            if text in ' '.join(c.cmdline()):
                found.append(c)
        except psutil.Error:
            pass
    return found


@pytest.fixture
def reap():
    """Kills whatever a failed test left running (only the processes it started)."""
    started = []
    yield started.append
    for proc in started:
        for c in _alive_descendants(proc):
            try:
                c.kill()
            except psutil.NoSuchProcess:
                pass
        if proc.poll() is None:
            proc.kill()
            proc.wait()


GRANDCHILD = '''
import subprocess, sys, time
from planter_ros.host.processes import preexec_die_with_parent
tie = preexec_die_with_parent() if sys.argv[1] == 'tied' else None
child = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(120)'], preexec_fn=tie)
print(child.pid, flush=True)
time.sleep(120)
'''


@pytest.mark.parametrize('tied', [True, False])
def test_a_tied_child_dies_with_its_killed_parent_and_an_untied_one_does_not(tmp_path, reap,
                                                                             tied):
    proc = start(['-c', GRANDCHILD, 'tied' if tied else 'free'], tmp_path)
    reap(proc)
    children = wait_for(proc, lambda children, out: children and out.strip(), tmp_path)
    left = survivors_of_sigkill(proc, children)
    if tied:
        assert left == []
    else:               # the test can tell: without the tie, the child outlives its parent
        assert len(left) == 1


GRACE_CHILD = """
import os, subprocess, sys, time
code = ('import os, sys, time\\n'
        'from planter_ros.host.processes import die_with_parent\\n'
        'die_with_parent(int(sys.argv[1]), grace=2)\\n'
        'print("tied", flush=True)\\n'
        'time.sleep(120)\\n')
child = subprocess.Popen([sys.executable, '-c', code, str(os.getpid())])
print(child.pid, flush=True)
time.sleep(120)
"""


def test_a_child_given_grace_outlives_its_killed_parent_by_the_grace_only(tmp_path, reap):
    """The demo's sync process gets a few seconds to shut its drives down when the demo is
    killed; a child that does not stop by itself (this one sleeps) is ended after them."""
    proc = start(['-c', GRACE_CHILD], tmp_path)
    reap(proc)
    children = wait_for(proc, lambda children, out: children and 'tied' in out, tmp_path)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(10)
    killed = time.monotonic()
    assert still_running(children, 1.0)                   # the grace: still there after 1 s
    assert still_running(children, GRACE) == [], time.monotonic() - killed


def test_a_child_whose_parent_is_already_gone_ends_at_once():
    env = dict(os.environ, PYTHONPATH=str(REPO))
    # pid 1 is never this child's parent: as if the parent had died before the request
    code = ('from planter_ros.host.processes import die_with_parent\n'
            'die_with_parent(1)\nprint("ran")')
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, env=env,
                          timeout=60)
    assert proc.returncode == -signal.SIGKILL and 'ran' not in proc.stdout


def test_bench_killed_during_the_control_loop_case_leaves_no_cpu_hog(tmp_path, reap):
    # a full run (two hogs beside each demo run), killed in its first run
    proc = start(['-m', 'planter_ros.cli', 'bench', '--only', 'control loop'], tmp_path)
    reap(proc)
    children = wait_for(proc, lambda children, out: len(named(children, 'while True')) == 2,
                        tmp_path)
    assert survivors_of_sigkill(proc, children) == []


def test_analyze_killed_during_a_local_cluster_run_leaves_no_worker(tmp_path, reap):
    bags = tmp_path / 'bags'
    bags.mkdir()
    for k in range(60):                 # work enough to be killed in the middle of it
        shutil.copy(REPO / 'bags' / 'sample_tomato.mcap', bags / f'b{k:02d}.mcap')
    proc = start(['-m', 'planter_ros.cli', 'analyze', str(bags), '--out', str(tmp_path / 'out'),
                  '--workers', '2'], tmp_path)
    reap(proc)
    children = wait_for(proc, lambda children, out: len(named(children, 'spawn_main')) >= 2,
                        tmp_path)
    time.sleep(1.0)                     # the workers are up and taking tasks
    assert survivors_of_sigkill(proc, children) == []


def test_optimize_killed_during_the_search_leaves_no_pool_worker(tmp_path, reap):
    proc = start(['-m', 'planter_ros.cli', 'optimize', 'three-arm', '--workers', '2',
                  '--max-time', '120', '--out', str(tmp_path / 'o.yaml')], tmp_path)
    reap(proc)
    children = wait_for(proc, lambda children, out: len(children) >= 2, tmp_path)
    assert survivors_of_sigkill(proc, children) == []
    assert not (tmp_path / 'o.yaml').exists()


def test_demo_killed_while_running_leaves_no_sync_process(tmp_path, reap):
    proc = start(['-m', 'planter_ros.cli', 'demo', '--duration', '60', '--bag',
                  str(tmp_path / 'd.mcap')], tmp_path)
    reap(proc)
    children = wait_for(proc, lambda children, out: 'field run starts' in out
                        and named(children, 'spawn_main'), tmp_path)
    assert survivors_of_sigkill(proc, children) == []


def test_the_local_clusters_workers_and_the_optimisers_pool_are_tied_by_the_kernel():
    """Dask's and multiprocessing's own pipes end idle helpers too (the SIGKILL tests above
    pass for them without the tie): the kernel's signal also ends a busy one, so it must be
    set in each worker."""
    from planter_ros.analysis.engine import cluster
    from planter_ros.optimize.three_arm import PopulationScorer
    from planter_ros.host.processes import parent_death_signal
    from planter_ros.scene import default_scene_path
    from planter_ros.cli.commands.design_three_arm import load_params
    with cluster(workers=2) as client:
        assert set(client.run(parent_death_signal).values()) == {signal.SIGKILL}
    base = load_params(default_scene_path('rice_three_arm.yaml'), '--base')
    with PopulationScorer(base, workers=2) as scorer:
        assert scorer._pool.map(_signal_of_worker, range(2)) == [signal.SIGKILL] * 2


def _signal_of_worker(_):
    from planter_ros.host.processes import parent_death_signal
    return parent_death_signal()
