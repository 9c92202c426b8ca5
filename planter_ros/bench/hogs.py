"""CPU hogs: the load beside the bench's runs under load (`python -c "while True: pass"`
processes that die with the bench, also when it is killed: planter_ros.host.processes)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
import os
import subprocess
import sys

from planter_ros.host.processes import preexec_die_with_parent

__all__ = ['HOGS', 'QUICK_HOGS', 'QUICK_HOG_NICENESS', 'cpu_hogs']

HOGS = 2            # beside each run under load: as many as the 2-core reference machine has cores
QUICK_HOGS = 1      # --quick (the smoke run): the path with a hog, the figures from a full run
# --quick: the hog at the lowest priority: the path with a hog is run (started beside the run,
# killed after it), its load is a full run's figure; on a busy host (the test suite) it takes
# only the CPU nobody else wants instead of a core from the other tests
QUICK_HOG_NICENESS = 19


@contextmanager
def cpu_hogs(count: int, niceness: int = 0) -> Iterator[list[subprocess.Popen[bytes]]]:
    """`count` CPU-bound processes for the length of the block, `niceness` added to this
    process's; they die with this process, also when it is killed with SIGKILL."""
    tie = preexec_die_with_parent()

    def preexec() -> None:
        tie()
        if niceness:
            os.nice(niceness)
    hogs = [subprocess.Popen([sys.executable, '-c', 'while True: pass'],
                             preexec_fn=preexec) for _ in range(count)]
    try:
        yield hogs
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
