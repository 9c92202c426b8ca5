"""Homing (CiA 402 mode 6) in the simulated drive: methods 19 (the home switch: its edge below
the switch), 33 and 34 (the index pulse backwards, forwards), 35 and 37 (the current position);
the speeds 6099h:1/:2, the home offset 607Ch; statusword bit 12 attained, bit 13 error. Plain
state in motor counts: the drive's lock is held by the caller."""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ['HOMING_METHODS', 'Homing', 'HomingOrder']

HOMING_METHODS = (19, 33, 34, 35, 37)


@dataclass(frozen=True)
class HomingOrder:
    """What the dictionary holds for a homing when it starts: the method (6098h), the speeds
    (6099h:1 searching for the switch, :2 for zero; counts/s), the home offset (607Ch, counts)."""

    method: int
    fast: float
    slow: float
    offset: float


class Homing:
    """One drive's homing: its phase, and where the home is (module doc)."""

    def __init__(self, counts_per_rev: int, switch_active: Callable[[float], bool]) -> None:
        self.counts_per_rev = counts_per_rev
        self.switch_active = switch_active
        self.phase: tuple[str, int, float] | None = None    # (phase, direction, speed)
        self.attained = False
        self.error = False
        self.shift = 0.0          # counts: reported position - polarity sign * motor counts
        self.homed = 0            # homings attained since power-up
        self._offset, self._sign, self._slow = 0.0, 1.0, 0.0

    def reset(self) -> None:
        """Out of homing (a mode change)."""
        self.phase = None
        self.attained = self.error = False

    def start(self, order: HomingOrder, position: float, sign: float,
              velocity: float = 0.0) -> None:
        """Controlword bit 4 rising in homing mode: `order` from motor `position` (`sign`: the
        position polarity, `velocity` the motor's now)."""
        method, fast, slow, offset = order.method, order.fast, order.slow, order.offset
        self.attained = self.error = False
        self._offset, self._sign, self._slow = offset, sign, slow
        if method not in HOMING_METHODS or (method < 35 and (fast <= 0 or slow <= 0)):
            self.error = True
            self.phase = None
        elif method in (35, 37):                   # the current position is home
            self._set_home(position, offset, sign, velocity)
        elif method == 19:                         # home switch: its edge below the switch
            self.phase = ('leave', -1, slow) if self.switch_active(position) else (
                'search', 1, fast)
        else:                                      # 33 index pulse backwards, 34 forwards
            self.phase = ('index', 1 if method == 34 else -1, slow)

    def stop(self) -> None:
        """Bit 4 cleared while homing: stop, not attained."""
        if self.phase is not None:
            self.phase = ('stop', 1, 0.0)

    def velocity(self, sign: float) -> float:
        """The motor speed the phase asks for (counts/s); `sign` the velocity polarity."""
        if self.phase is None:
            return 0.0
        _, direction, speed = self.phase
        return sign * direction * speed

    def step(self, before: float, now: float, velocity: float) -> None:
        """After a motor sub-step from `before` to `now` counts: the switch and index edges."""
        if self.phase is None:
            return
        phase = self.phase[0]
        rev = self.counts_per_rev
        if phase == 'search' and self.switch_active(now):
            self.phase = ('leave', -1, self._slow)
        elif phase == 'leave' and not self.switch_active(now):
            self._set_home(now, self._offset, self._sign, velocity)
        elif phase == 'index' and math.floor(now / rev) != math.floor(before / rev):
            index = rev * max(math.floor(now / rev), math.floor(before / rev))
            self._set_home(index, self._offset, self._sign, velocity)
        elif phase == 'stop' and abs(velocity) < 0.5:
            self.phase = None

    def _set_home(self, counts: float, offset: float, sign: float, velocity: float) -> None:
        """Motor position `counts` becomes the home offset; stop, attained."""
        self.shift = offset - sign * counts
        self.phase = ('stop', 1, 0.0) if abs(velocity) >= 0.5 else None
        self.attained = True
        self.homed += 1
