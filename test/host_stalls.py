"""Did the host stop scheduling us? A watcher process, separate from the tests (no shared GIL,
no shared DDS participant), sleeps 5 ms at a time at the priority of the test process that
started it (it never asks for more) and reports every time it ran more than `REPORTED` s after
it last ran, less the 5 ms: the machine left a runnable process unscheduled that long (CPU
contention, a VM's stolen time). A stall inside the test process itself (a lock, the GIL, a
DDS send blocked) never shows here: it stays the test's finding.

A real-time test runs once more when it failed while the watcher saw the host stall for more
than `STARVED` s during it (conftest.py: the first failure and the stall are then shown in the
terminal summary and the JUnit file, and a session that needed more than one such re-run
fails). `PLANTER_TEST_STARVED` (s) sets another threshold: the harness's own tests
(test_harness.py) use it, and `pause_watcher` to stall the watcher on purpose.
"""
import os
import signal
import subprocess
import sys
import threading
import time

# half the drives' 0.2 s command deadline: a test loop unscheduled that long misses commands
STARVED = float(os.environ.get('PLANTER_TEST_STARVED', '0.1'))
REPORTED = 0.03

WATCHER = r'''
import ctypes, os, signal, sys, time
parent = int(sys.argv[1])
try:                                            # die with the test process, also on SIGKILL
    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)      # PR_SET_PDEATHSIG
except (OSError, AttributeError):
    pass
reported = float(sys.argv[2])
last = time.monotonic()                         # a stop from here on is measured
sys.stdout.write('watching\n')
sys.stdout.flush()
while os.getppid() == parent:
    time.sleep(0.005)
    now = time.monotonic()
    if now - last - 0.005 > reported:
        sys.stdout.write(f'{last!r} {now!r}\n')
        sys.stdout.flush()
    last = now
'''


class HostStalls:
    """The watcher process and the stalls it reported: (start, end) in CLOCK_MONOTONIC s, the
    clock every process of the host shares."""

    def __init__(self):
        self.stalls = []
        self._proc = subprocess.Popen(
            [sys.executable, '-c', WATCHER, str(os.getpid()), str(REPORTED)],
            stdout=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True)
        self._proc.stdout.readline()           # watching from here on
        threading.Thread(target=self._read, daemon=True, name='host-stalls').start()

    @property
    def pid(self):
        return self._proc.pid

    def _read(self):
        for line in self._proc.stdout:
            start, end = map(float, line.split())
            self.stalls.append((start, end))

    def longest(self, since, until):
        """The longest stall that overlapped [since, until] (s; 0 if none)."""
        return max((end - start for start, end in list(self.stalls)
                    if end >= since and start <= until), default=0.0)

    def close(self):
        self._proc.kill()
        self._proc.wait()


_watcher = None


def watcher():
    """This process's watcher, started on first use."""
    global _watcher
    if _watcher is None:
        _watcher = HostStalls()
    return _watcher


def close():
    if _watcher is not None:
        _watcher.close()


def wait_for_reports(seconds=0.05):
    """Give the watcher time to report a stall that just ended."""
    time.sleep(seconds)


def pause_watcher(seconds):
    """Stop the watcher for `seconds` (SIGSTOP, then SIGCONT): it reports a stall that long,
    as when the host leaves it unscheduled (the harness's own tests inject a host stall so)."""
    pid = watcher().pid
    os.kill(pid, signal.SIGSTOP)
    try:
        time.sleep(seconds)
    finally:
        os.kill(pid, signal.SIGCONT)
