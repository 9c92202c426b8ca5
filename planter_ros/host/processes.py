"""Every helper process the product starts dies with the process that started it, also when that
one is killed with SIGKILL (a CI time limit, `timeout -s KILL`, the OOM killer).

Linux's `prctl(PR_SET_PDEATHSIG, signal)` asks the kernel to send `signal` to a process when
its parent goes away, however it goes. It is asked for in the child, so a parent that died
between the fork and the request would be missed: the child checks right after that its parent
is still the process that started it, and dies at once if not. The "parent" the kernel watches
is the *thread* that started the child: start helpers from a thread that lives as long as they
do (the main thread, a pool's own thread). Pure Python (ctypes), no ROS import. On a system
without prctl nothing is set and the callers' own pipes are the only link (the product runs on
Linux).

- `preexec_die_with_parent()`: `subprocess.Popen(..., preexec_fn=preexec_die_with_parent())`.
- `die_with_parent(parent_pid)`: first thing in a `multiprocessing` child or pool initializer
  (`multiprocessing.parent_process().pid` is the parent's pid there).
- `die_with_parent(parent_pid, grace=4)`: for a child with something to stop cleanly (drives
  to shut down) when it sees its parent gone on its own (a pipe's end-of-file): the kernel's
  signal starts a `grace` s alarm instead, whose default action ends the process however stuck
  it is (in the main thread, which installs the handler).
"""

from __future__ import annotations

from collections.abc import Callable
import ctypes
import math
import os
import signal
import sys
from types import FrameType

__all__ = ['GRACE_SIGNAL', 'PR_SET_PDEATHSIG', 'die_with_parent', 'parent_death_signal',
           'preexec_die_with_parent', 'supported']

PR_SET_PDEATHSIG = 1            # <linux/prctl.h>
PR_GET_PDEATHSIG = 2


def _prctl() -> Callable[..., int] | None:
    """libc's prctl, or None where there is none (not Linux)."""
    if not sys.platform.startswith('linux'):
        return None
    try:
        return ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None


def supported() -> bool:
    """True where the kernel can tie a child's life to its parent's."""
    return _prctl() is not None


def parent_death_signal() -> int | None:
    """The signal this process receives when its parent goes away (0: none; None: unknown
    here)."""
    prctl = _prctl()
    if prctl is None:
        return None
    value = ctypes.c_int(0)
    if prctl(PR_GET_PDEATHSIG, ctypes.byref(value), 0, 0, 0) != 0:
        return None
    return value.value


def _tie(prctl: Callable[..., int] | None, parent_pid: int, signum: int,
         exit_now: bool = True) -> None:
    if prctl is not None and prctl(PR_SET_PDEATHSIG, int(signum), 0, 0, 0) != 0:
        errno = ctypes.get_errno()
        raise OSError(errno, f'prctl(PR_SET_PDEATHSIG): {os.strerror(errno)}')
    if os.getppid() != parent_pid:        # the parent died before the request: go now
        os.kill(os.getpid(), signum)
        if exit_now:                      # a signal this process handles or ignores
            os._exit(128 + int(signum))


GRACE_SIGNAL = signal.SIGUSR1       # the parent-death signal of a child given a grace period


def die_with_parent(parent_pid: int, signum: int = signal.SIGKILL,
                    grace: float | None = None) -> None:
    """In a child process: receive `signum` when the parent goes away. `parent_pid` is the pid
    of the process that started this one; if it is already gone, this process ends now. With
    `grace` (whole seconds >= 1) the signal is GRACE_SIGNAL and only starts an alarm: the
    process ends `grace` s later unless it has stopped by itself by then."""
    if grace is not None:
        seconds = max(1, math.ceil(grace))

        def parent_gone(_signum: int, _frame: FrameType | None) -> None:
            if os.getppid() == parent_pid:          # not the kernel's: the parent is alive
                return
            signal.signal(signal.SIGALRM, signal.SIG_DFL)
            signal.alarm(seconds)
            signal.signal(GRACE_SIGNAL, signal.SIG_IGN)
        signal.signal(GRACE_SIGNAL, parent_gone)
        _tie(_prctl(), parent_pid, GRACE_SIGNAL, exit_now=False)
        return
    _tie(_prctl(), parent_pid, signum)


def preexec_die_with_parent(signum: int = signal.SIGKILL) -> Callable[[], None]:
    """A `preexec_fn` for subprocess.Popen: the child is tied to the calling process (libc is
    looked up here, in the parent, so the forked child only makes the call)."""
    prctl, parent_pid = _prctl(), os.getpid()

    def preexec() -> None:
        _tie(prctl, parent_pid, signum)
    return preexec
