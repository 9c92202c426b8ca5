"""SIGTERM is Ctrl-C in every node main and the demo: the first stop signal asks for a clean
stop, a second one forces the exit (a clean-up that hangs must not keep the process alive)."""
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

import pytest

from planter_ros.host import stop_signals

pytestmark = pytest.mark.realtime(apart=True)   # processes of its own (test/conftest.py)

REPO = Path(__file__).resolve().parents[1]

HUNG_CLEANUP = r'''
import time
from planter_ros.host import stop_signals
stop = stop_signals.install('test')
print('running', flush=True)
while stop.received is None:
    time.sleep(0.01)
print('stopping on', stop.name_received, flush=True)
time.sleep(60)                     # a clean-up that hangs
print('clean-up done', flush=True)
'''


def child_env():
    return dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')


@pytest.mark.parametrize('sig', [signal.SIGTERM, signal.SIGINT])
def test_the_first_signal_asks_for_a_clean_stop_the_second_forces_the_exit(sig):
    proc = subprocess.Popen([sys.executable, '-c', HUNG_CLEANUP], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=child_env())
    try:
        assert proc.stdout.readline().strip() == 'running'
        proc.send_signal(sig)
        assert proc.stdout.readline().strip() == f'stopping on {signal.Signals(sig).name}'
        t0 = time.monotonic()
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert time.monotonic() - t0 < 5
    assert proc.returncode == 128 + sig
    assert 'clean-up done' not in out
    assert err == f'test: second {signal.Signals(sig).name}: forced exit, without a clean stop\n'


@pytest.mark.parametrize('main', ['design_node', 'sync_node'])
def test_sigterm_stops_a_node_like_ctrl_c_with_exit_0(main, tmp_path):
    """design_node and sync_node (on a simulated drive) stop cleanly on SIGTERM; the monitor's
    bag is tested in test_recorder_signals.py."""
    code = {'design_node': 'from planter_ros.nodes.design_node import main; '
                           'raise SystemExit(main())',
            'sync_node': SYNC_ON_A_SIMULATED_DRIVE}[main]
    args = ['--ros-args', '--params-file', str(REPO / 'config' / 'tomato_five_bar.yaml')] \
        if main == 'design_node' else []
    env = child_env()
    env.pop('ROS_AUTOMATIC_DISCOVERY_RANGE')      # unset: the node keeps discovery on the host
    proc = subprocess.Popen([sys.executable, '-c', code] + args, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env=env)
    lines = []
    try:
        # with a deadline: a node whose DDS participant never comes up (seen once: every new
        # participant on the host blocked on a stale shared-memory port) fails here, not the
        # whole run at CI's time limit
        reader = threading.Thread(target=lambda: _read_until_up(proc, lines), daemon=True)
        reader.start()
        reader.join(STARTED_WITHIN)
        assert not reader.is_alive(), (f'{main} not up within {STARTED_WITHIN:g} s:\n'
                                       + ''.join(lines))
        time.sleep(0.5)
        proc.send_signal(signal.SIGTERM)
        rest, _ = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    out = ''.join(lines) + rest
    assert proc.returncode == 0, out
    assert 'Traceback' not in out
    if main == 'sync_node':
        assert 'drive shut down (target 0, disabled, pre-operational)' in out
        assert 'discovery range LOCALHOST' in out


STARTED_WITHIN = 60.0      # s a node may take to say it is up (a loaded host: a few seconds)


def _read_until_up(proc, lines):
    for line in proc.stdout:
        lines.append(line)
        if 'published' in line or 'enabled (profile velocity)' in line:
            return


# sync_node's main on a virtual bus with a simulated drive in the same process
SYNC_ON_A_SIMULATED_DRIVE = r'''
import os, sys
from planter_ros.simdrive.drive import SimulatedDrive
from planter_ros.nodes.sync_node import main
channel = f'sigterm{os.getpid()}'
sim = SimulatedDrive(channel)
sim.start()
code = main(['--ros-args', '-p', 'can_interface:=virtual', '-p', f'can_channel:={channel}'])
print('discovery range', os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE'), flush=True)
sim.stop()
raise SystemExit(code)
'''


class _Context:
    def __init__(self):
        self.valid = True

    def ok(self):
        return self.valid


class _Executor:
    """An executor whose wait is refused once its context was shut down under it (rclpy's
    RCLError 'the given context is not valid'), the way a signal landing between spin()'s check
    and the next wait leaves it."""

    def __init__(self, shut_down_after):
        self.context = _Context()
        self.waits = 0
        self.shut_down_after = shut_down_after

    def spin_once(self, timeout_sec):
        self.waits += 1
        if self.waits > self.shut_down_after:
            self.context.valid = False
            raise RuntimeError('failed to initialize wait set: the given context is not valid')


def test_a_context_shut_down_under_the_wait_ends_the_spin_without_an_error():
    handler = stop_signals.StopSignals('test')
    executor = _Executor(shut_down_after=3)
    stop_signals.spin(executor, handler, period=0.0)
    assert executor.waits == 4


def test_a_wait_that_fails_on_a_live_context_is_still_an_error():
    class Broken(_Executor):
        def spin_once(self, timeout_sec):
            raise RuntimeError('a callback failed')
    with pytest.raises(RuntimeError, match='a callback failed'):
        stop_signals.spin(Broken(shut_down_after=0), stop_signals.StopSignals('test'), 0.0)


def test_a_spin_thread_is_shut_down_only_after_its_last_wait():
    """rclpy's executor.shutdown() destroys the guard condition a spinning thread may still be
    making a handler with (a demo stopped at start-up printed that thread's traceback): a
    SpinThread's executor is shut down only once no wait runs or can start."""
    import threading
    import time

    class Recording(_Executor):
        def __init__(self):
            super().__init__(shut_down_after=10**9)
            self.inside = threading.Event()
            self.after_shutdown = []
            self.down = False

        def spin_once(self, timeout_sec):
            self.inside.set()
            if self.down:
                self.after_shutdown.append('wait started')
            time.sleep(0.002)                   # a callback running
            if self.down:
                self.after_shutdown.append('wait ended')
            super().spin_once(timeout_sec)

        def shutdown(self, timeout_sec):
            self.down = True
            return True
    for _ in range(20):
        executor = Recording()
        spinner = stop_signals.SpinThread(executor, 'test-executor', period=0.001)
        spinner.start()
        assert executor.inside.wait(2.0)
        spinner.stop()
        assert executor.down and not spinner.thread.is_alive()
        assert executor.after_shutdown == []


def test_a_spin_thread_never_started_still_shuts_its_executor_down():
    class Recording(_Executor):
        down = False

        def shutdown(self, timeout_sec):
            self.down = True
            return True
    executor = Recording(shut_down_after=0)
    stop_signals.SpinThread(executor, 'never-started').stop()   # a start cut short before it
    assert executor.down and executor.waits == 0


MASK_CHILD = '''
import signal


def report(conn):
    conn.send(sorted(int(s) for s in signal.pthread_sigmask(signal.SIG_BLOCK, [])))
'''

FIRST_SPAWN = '''
import json, multiprocessing, sys
sys.path.insert(0, sys.argv[1])
import mask_child
from planter_ros.host import stop_signals
context = multiprocessing.get_context('spawn')
ours, theirs = context.Pipe()
process = context.Process(target=mask_child.report, args=(theirs,))
stop_signals.start_held(process)
print(json.dumps(ours.recv()))
process.join()
'''


def test_the_first_spawned_child_starts_with_stop_signals_held(tmp_path):
    """The demo's sync process is the first multiprocessing child of its process: started
    `start_held`, it starts with SIGINT and SIGTERM blocked (until its own handler is in
    place). With `held_for_child` alone the resource tracker multiprocessing starts on first use
    unblocked them before the child was spawned: a stop 0-0.1 s into a demo's start killed the
    sync process (exit code -15) and the demo had no drive's account of how it ended."""
    (tmp_path / 'mask_child.py').write_text(MASK_CHILD)
    out = subprocess.run([sys.executable, '-c', FIRST_SPAWN, str(tmp_path)], capture_output=True,
                         text=True, env=child_env(), timeout=60)
    assert out.returncode == 0, out.stderr
    blocked = set(json.loads(out.stdout))
    assert {int(signal.SIGINT), int(signal.SIGTERM)} <= blocked, blocked
