"""Faults injected into a simulated drive beyond its own: power off and on (`power_cycle`),
slow SDO answers (one at a time, in order, from a seeded random stream), and EMCY storms. Plain
state; the drive decides what they do."""
from __future__ import annotations

import random

from .spec import SimSpec

__all__ = ['InjectedFaults']


class InjectedFaults:
    """Power, SDO slowness and EMCY storms of one drive (module doc)."""

    def __init__(self, spec: SimSpec, node_id: int) -> None:
        self.sdo_delay = spec.sdo_delay
        self.sdo_slow_share = float(spec.sdo_slow_share)
        self._random = random.Random(f'{spec.seed}:{node_id}')
        self.powered = True
        self.power_on_at = 0.0
        self.power_cycles = 0
        self._sdo_queue: list[tuple[float, int, bytes, float]] = []   # (answer at, frame)
        self._sdo_free_at = 0.0
        self.sdo_requests = 0
        self.sdo_slow = 0                 # requests answered late
        self._storm: tuple[float, float, float, int] | None = None    # start, end, rate, code
        self._storm_sent = 0

    def power_off(self, now: float, off_time: float) -> None:
        self.powered = False
        self.power_on_at = now + float(off_time)
        self._storm = None
        self._sdo_queue.clear()
        self.power_cycles += 1

    def sdo_request(self, now: float, can_id: int, data: bytes | bytearray,
                    stamp: float) -> bool:
        """An SDO request: True to answer it at once, else it is queued (a slow drive)."""
        self.sdo_requests += 1
        delay = self.sdo_delay
        slow = delay is not None and self._random.random() < self.sdo_slow_share
        if not slow and now >= self._sdo_free_at:
            return True
        at = max(now, self._sdo_free_at) + (self._random.uniform(*delay)
                                            if slow and delay is not None else 0.0)
        self.sdo_slow += slow
        self._sdo_free_at = at
        self._sdo_queue.append((at, can_id, bytes(data), stamp))
        return False

    def due_sdo(self, now: float) -> list[tuple[float, int, bytes, float]]:
        due = [item for item in self._sdo_queue if item[0] <= now]
        self._sdo_queue = [item for item in self._sdo_queue if item[0] > now]
        return due

    def storm(self, now: float, rate: float, seconds: float, code: int) -> None:
        self._storm = (now, now + float(seconds), float(rate), int(code))
        self._storm_sent = 0

    def storm_burst(self, now: float) -> tuple[int, int]:
        """(EMCYs due now, their code)."""
        storm = self._storm
        if storm is None:
            return 0, 0
        start, end, rate, code = storm
        burst = int((min(now, end) - start) * rate) - self._storm_sent
        self._storm_sent += max(burst, 0)
        if now >= end:
            self._storm = None
        return max(burst, 0), code
