"""SIGTERM is Ctrl-C: what systemd, `docker stop` and `timeout` send must stop a run cleanly.

`install()` handles SIGINT and SIGTERM alike. The first one asks for a clean stop: it is noted
(`received`), and whoever runs the process acts on it at a safe point — in a node's main,
rclpy's own handler (installed by rclpy.init() after ours, and calling ours afterwards) has
already shut its context down, so spin() returns and the node's clean-up runs (drives shut
down, bag finalised); the demo's loop polls `received`. Nothing is raised into whatever the
main thread is doing, so a stop never lands in the middle of writing a bag. The second signal
ends the process at once (`os._exit`, exit code 128 + the signal), for a stop that hangs.
`spin` runs a node's executor until the first signal (each wait bounded, so none is missed).
Pure Python: no ROS import.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from multiprocessing import resource_tracker
from multiprocessing.process import BaseProcess
import os
import signal
import threading
from types import FrameType
from typing import Any

__all__ = ['STOP_SIGNALS', 'SpinThread', 'StopSignals', 'held_for_child', 'ignore', 'install',
           'installed', 'spin', 'signal_number', 'start_held', 'unblock']

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopSignals:
    """The handler of both stop signals; `received` is the first one (None until then);
    `source`: '' when it reached this process, else who passed it on (`ask`)."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.received: int | None = None
        self.source = ''

    def ask(self, signum: int, source: str) -> None:
        """A stop that reached another process of ours (`source`: 'the command process'), as
        if `signum` had reached this one; the first stop counts."""
        if self.received is None:
            self.source = source
            self.received = signum

    def __call__(self, signum: int, _frame: FrameType | None) -> None:
        if self.received is None:
            self.received = signum
            return
        os.write(2, f'{self.name}: second {signal.Signals(signum).name}: forced exit, without '
                 'a clean stop\n'.encode())
        os._exit(128 + signum)

    @property
    def name_received(self) -> str:
        """'SIGTERM', 'SIGINT' or '' (no stop asked for)."""
        return signal.Signals(self.received).name if self.received is not None else ''

    @property
    def description(self) -> str:
        """'SIGTERM', 'SIGTERM to the command process', or '' (no stop asked for)."""
        name = self.name_received
        return f'{name} to {self.source}' if name and self.source else name


def installed() -> StopSignals | None:
    """The StopSignals handler this process installed (None: none)."""
    handler = signal.getsignal(signal.SIGTERM)
    return handler if isinstance(handler, StopSignals) else None


def install(name: str) -> StopSignals:
    """Handle SIGINT and SIGTERM in this process as described above (call from the main
    thread, before rclpy.init()); returns the handler. A stop signal held back while the
    process started (`held_for_child`) arrives now."""
    handler = StopSignals(name)
    for signum in STOP_SIGNALS:
        signal.signal(signum, handler)
    unblock()
    return handler


@contextmanager
def held_for_child() -> Iterator[None]:
    """Start a child process inside this: SIGINT and SIGTERM are blocked in the calling thread
    meanwhile, and the child inherits that mask (fork and exec keep it), so a stop signal that
    reaches the child before it has its own handlers (Python starting, its imports: a
    KeyboardInterrupt traceback, or death by SIGTERM) waits for them: `install`, `ignore` and
    `unblock` let it through. This process's own handler still gets a signal meanwhile (another
    thread takes it, or it waits until the block ends)."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def start_held(process: BaseProcess) -> None:
    """Start a multiprocessing `process` `held_for_child`. multiprocessing starts its resource
    tracker on first use, inside `start()`, and then unblocks SIGINT and SIGTERM in the calling
    thread (CPython's resource_tracker), so the first child would start with stop signals let
    through: a demo stopped within ~0.1 s of its start lost its sync process to SIGTERM's default
    action (exit code -15) before it had its handler, and with it the drives' own account. The
    tracker is started first, outside the block."""
    resource_tracker.ensure_running()
    with held_for_child():
        process.start()


def unblock() -> None:
    """Let SIGINT and SIGTERM through in this thread (a child started `held_for_child`, once
    its handlers are set)."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)


def spin(executor: Any, handler: StopSignals, period: float = 0.2) -> None:
    """Spin `executor` (an rclpy executor with the node added) until a stop signal arrives or
    its context ends. rclpy's own handler wakes a waiting executor, but a signal that lands
    while the wait is being set up can be missed (seen: about one SIGTERM in ten left a
    design node waiting forever on a loaded host), so each wait is bounded by `period` s and
    this handler's flag is checked after it. A signal landing between that check and the next
    wait shuts the context down under it: rclpy then refuses the wait (its RCLError "context is
    not valid"), which is this stop, not an error (seen on CI: a design node's SIGTERM ended in
    that traceback and exit code 1)."""
    def running() -> bool:
        return handler.received is None and bool(executor.context.ok())

    while running():
        try:
            executor.spin_once(timeout_sec=period)
        except Exception:                       # noqa: BLE001  (rclpy's RCLError: no ROS here)
            if running():
                raise
            return


class SpinThread:
    """`executor` (an rclpy executor with its nodes added) spun in a thread of its own until
    `stop()`. rclpy's `executor.shutdown()` called while another thread spins destroys the
    executor's guard condition under it: the spinning thread can still be making a handler
    with it, and dies in a traceback (rclpy 7.x, Jazzy: "'NoneType' object has no attribute
    'trigger'"; seen in a demo stopped by SIGTERM at start-up). So this thread spins in waits
    bounded by `period` s and checks its flag after each; `stop()` sets the flag, waits for the
    thread, and only then shuts the executor down. A context shut down under the wait is this
    stop too (as in `spin`)."""

    def __init__(self, executor: Any, name: str, period: float = 0.1) -> None:
        self.executor = executor
        self.period = float(period)
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True, name=name)

    def start(self) -> None:
        self.thread.start()

    def _running(self) -> bool:
        return not self._stop.is_set() and bool(self.executor.context.ok())

    def _spin(self) -> None:
        while self._running():
            try:
                self.executor.spin_once(timeout_sec=self.period)
            except Exception:                   # noqa: BLE001  (rclpy's RCLError: no ROS here)
                if self._running():
                    raise
                return

    def stop(self, timeout: float = 2.0) -> None:
        """Stop spinning (within `timeout` s: a callback still running after it is left to
        end on its own), then shut the executor down (also one never spun: `start` not
        called)."""
        self._stop.set()
        if self.thread.is_alive() and self.thread is not threading.current_thread():
            self.thread.join(timeout)
        self.executor.shutdown(timeout_sec=timeout)


def signal_number(name: str) -> int:
    """The number of a stop signal's name ('SIGTERM' -> 15); SIGTERM for another name."""
    return getattr(signal, name, signal.SIGTERM) if name in ('SIGTERM', 'SIGINT') else \
        signal.SIGTERM


def ignore() -> None:
    """A helper process its parent stops (over a pipe): the terminal's Ctrl-C, which reaches
    the whole process group, must not stop it on its own."""
    for signum in STOP_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)
    unblock()
