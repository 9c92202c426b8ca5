"""Time on the simulated drives' side of the cable: a frame's time on the bus, the pace of the
drives' thread, gaps between events as a drive sees them, and reading every waiting frame."""
from __future__ import annotations

from collections.abc import Callable, Iterator
import logging
import math
import threading
import time

import can
import canopen

__all__ = ['Gaps', 'paced', 'receive', 'wire_time']

log = logging.getLogger(__name__)


def paced(stop_event: threading.Event, tick: float,
          work: Callable[[], object]) -> Iterator[tuple[float, float]]:
    """Every `tick` s until `stop_event`: run `work()` (read the bus), then yield (seconds since
    the last step, now). A loop that fell behind (a loaded machine) takes up its pace from now
    instead of catching up in a burst."""
    last = time.monotonic()
    next_tick = last
    while not stop_event.is_set():
        next_tick += tick
        delay = next_tick - time.monotonic()
        if delay > 0:
            stop_event.wait(delay)
        else:
            next_tick = time.monotonic()
        work()
        now = time.monotonic()
        dt, last = now - last, now
        yield dt, now


class Gaps:
    """Gaps between events on the receiver's clock: count, largest, and how many exceeded each
    of `limits` (s). Constant memory, one comparison per limit per event."""

    def __init__(self, limits: tuple[float, ...] = (0.05, 0.15, 0.2)) -> None:
        self.limits = tuple(limits)
        self.over = [0] * len(self.limits)
        self.count = 0
        self.max_gap = 0.0
        self._last: float | None = None

    def event(self, now: float) -> None:
        last, self._last = self._last, now
        if last is None:
            return
        gap = now - last
        self.count += 1
        self.max_gap = max(self.max_gap, gap)
        for i, limit in enumerate(self.limits):
            if gap > limit:
                self.over[i] += 1

    def restart(self) -> None:
        """The next event starts a new series (the sender stopped on purpose)."""
        self._last = None

    def summary(self) -> dict:
        return {'gaps': self.count, 'max': self.max_gap,
                'over': {f'{limit * 1e3:g} ms': n for limit, n in zip(self.limits, self.over)}}


def wire_time(timestamp: float | None) -> float:
    """A received frame's time on the bus, on the monotonic clock: python-can stamps a frame
    with the wall clock (the virtual bus when it is sent, SocketCAN when the kernel receives
    it), so its age is subtracted from now; now for a frame without a stamp."""
    now = time.monotonic()
    if timestamp is None or not math.isfinite(timestamp) or timestamp <= 0.0:
        return now
    return now - max(time.time() - timestamp, 0.0)


def receive(bus: can.BusABC, network: canopen.Network) -> None:
    """Decode every frame waiting on `bus` (canopen's own listener does the same from a thread
    of its own): the simulated drives' thread calls this before each step, so a watchdog is
    never judged with frames still waiting in the queue."""
    while True:
        msg = bus.recv(timeout=0.0)
        if msg is None:
            return
        if msg.is_error_frame or msg.is_remote_frame:
            continue
        try:
            network.notify(msg.arbitration_id, msg.data, msg.timestamp)
        except Exception as exc:     # a callback's error must not stop the drive, as canopen
            log.error('simulated drive: %s', exc)
