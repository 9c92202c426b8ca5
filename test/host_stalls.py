"""Did the host stop scheduling us? A watcher process, separate from the tests (no shared GIL,
no shared DDS participant), sleeps 5 ms at a time at the tests' own priority and reports every
sleep that overran by more than `REPORTED` s: the machine left a runnable process unscheduled
that long (CPU contention, a VM's stolen time). A stall inside the test process itself (a lock,
the GIL, a DDS send blocked) never shows here: it stays the test's finding.

The real-time tests run once more when they failed while the watcher saw the host stall for
more than `STARVED` s during them (conftest.py); CI's log names each such re-run.
"""
import os
import subprocess
import sys
import threading
import time

# half the drives' 0.2 s command deadline: a test loop unscheduled that long misses commands
STARVED = 0.1
REPORTED = 0.03

WATCHER = r'''
import ctypes, os, signal, sys, time
parent = int(sys.argv[1])
try:                                            # die with the test process, also on SIGKILL
    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)      # PR_SET_PDEATHSIG
except (OSError, AttributeError):
    pass
reported = float(sys.argv[2])
try:                                            # the tests' own priority, however it was started
    os.setpriority(os.PRIO_PROCESS, 0, 0)
except OSError:
    pass
while os.getppid() == parent:
    before = time.monotonic()
    time.sleep(0.005)
    after = time.monotonic()
    if after - before - 0.005 > reported:
        sys.stdout.write(f'{before!r} {after!r}\n')
        sys.stdout.flush()
'''


class HostStalls:
    """The watcher process and the stalls it reported: (start, end) in CLOCK_MONOTONIC s, the
    clock every process of the host shares."""

    def __init__(self):
        self.stalls = []
        self._proc = subprocess.Popen(
            [sys.executable, '-c', WATCHER, str(os.getpid()), str(REPORTED)],
            stdout=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True)
        threading.Thread(target=self._read, daemon=True, name='host-stalls').start()

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
