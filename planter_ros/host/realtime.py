"""What the command process asks of the kernel: a real-time scheduling class, locked memory,
and to die with its parent. Each request says in one line what it did not get; the process runs
on either way (a desk or a container may refuse; the machine's set-up is in doc/command.md).
Linux only (sched_setscheduler, mlockall and prctl through libc); elsewhere each says so."""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal

from planter_ros.host import processes

__all__ = ['MCL_CURRENT', 'MCL_FUTURE', 'request_fifo', 'request_nice', 'lock_memory',
           'die_with_parent']

MCL_CURRENT, MCL_FUTURE = 1, 2


def _libc() -> ctypes.CDLL | None:
    name = ctypes.util.find_library('c')
    return ctypes.CDLL(name, use_errno=True) if name else None


def request_fifo(priority: int) -> str:
    """SCHED_FIFO at `priority` (1..99) for this process; '' when granted, else why not.
    `priority` 0 asks for nothing (and says so)."""
    if priority <= 0:
        return 'SCHED_FIFO not asked for (realtime_priority = 0)'
    if not hasattr(os, 'sched_setscheduler'):
        return 'SCHED_FIFO is not available on this system'
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, ValueError) as exc:
        return (f'SCHED_FIFO priority {priority} refused ({exc}); raise the rtprio limit '
                '(limits.conf / systemd LimitRTPRIO) or run with CAP_SYS_NICE')
    return ''


def request_nice(nice: int) -> str:
    """Every thread of this process, and those it starts later, at `nice` (-20..-1): a larger
    share of a busy CPU than ordinary processes, without a real-time class (the sync node's
    shell: the DDS threads and the callback that forward a ground-speed sample to the command
    process); '' when granted. `nice` 0 asks for nothing (and says nothing)."""
    if nice >= 0:
        return ''
    if not hasattr(os, 'setpriority'):
        return 'setpriority is not available on this system'
    try:
        threads = [int(tid) for tid in os.listdir('/proc/self/task')]
    except OSError:
        threads = [0]                      # no /proc: this thread (and those it starts)
    for tid in threads:
        try:
            os.setpriority(os.PRIO_PROCESS, tid, nice)
        except ProcessLookupError:         # the thread has ended meanwhile
            continue
        except OSError as exc:
            return (f'nice {nice} refused ({exc.strerror}); raise the nice limit (limits.conf '
                    '/ systemd Nice=) or run with CAP_SYS_NICE')
    return ''


def lock_memory() -> str:
    """mlockall(MCL_CURRENT | MCL_FUTURE): no page fault stalls the loop; '' when granted."""
    libc = _libc()
    if libc is None or not hasattr(libc, 'mlockall'):
        return 'mlockall is not available on this system'
    if libc.mlockall(MCL_CURRENT | MCL_FUTURE) != 0:
        err = ctypes.get_errno()
        return (f'mlockall refused ({os.strerror(err)}); raise the memlock limit '
                '(limits.conf / systemd LimitMEMLOCK) or run with CAP_IPC_LOCK')
    return ''


def die_with_parent(parent: int, sig: int = signal.SIGTERM) -> str:
    """Ask the kernel for `sig` when the parent (pid `parent`) dies (planter_ros.host.processes);
    '' when set, else why not (for the log line and diagnostics). A parent already gone:
    `sig` at once."""
    if not processes.supported():
        return 'PR_SET_PDEATHSIG is not available on this system'
    try:
        processes.die_with_parent(parent, sig)
    except OSError as exc:
        return f'PR_SET_PDEATHSIG refused ({exc.strerror})'
    return ''
