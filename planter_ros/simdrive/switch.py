"""The simulated bottom proximity switch, as the drive's digital input (60FDh bit 2) sees it.

Ideal by default: active while the mechanism is within half the switch's `width` of its bottom,
read at once. A real inductive switch and the input behind it are not: the switch turns on
`hysteresis / 2` inside its nominal edge and off `hysteresis / 2` outside it (so an edge lies at
a different angle crossed forwards and backwards), and the input shows a change `delay` s after
the switch made it, plus a `jitter` drawn uniformly from [0, jitter) s per change from a seeded
stream (the input's polling and filtering). The nominal edges stay at +-width/2, symmetric about
the bottom: the middle of the four edges (each crossed both ways) is the bottom whatever the
delay and hysteresis, which is what commissioning relies on (commission.procedure).
Plain state on mechanism angles (rad) and the motor's clock (s); the drive's lock is held by
the caller."""
from __future__ import annotations

from collections import deque
import math
import random

__all__ = ['HomeSwitch']

TWO_PI = 2.0 * math.pi


def _from_bottom(angle: float) -> float:
    """|angle| wrapped to [0, pi]: the distance from the bottom, either way."""
    return abs((angle + math.pi) % TWO_PI - math.pi)


class HomeSwitch:
    """The bottom switch and its input (module doc)."""

    def __init__(self, width: float, hysteresis: float = 0.0, delay: float = 0.0,
                 jitter: float = 0.0, seed: int | str = 0) -> None:
        if not width > 0:
            raise ValueError(f'home_switch_width = {width!r} is out of range: allowed > 0 rad')
        if not 0.0 <= hysteresis < width:
            raise ValueError(f'home_switch_hysteresis = {hysteresis!r} is out of range: allowed '
                             f'0 <= hysteresis < home_switch_width ({width!r} rad)')
        for name, value in (('home_switch_delay', delay), ('home_switch_jitter', jitter)):
            if not 0.0 <= value < math.inf:
                raise ValueError(f'{name} = {value!r} is out of range: allowed >= 0 s')
        self.width, self.hysteresis = float(width), float(hysteresis)
        self.delay, self.jitter = float(delay), float(jitter)
        self.ideal = self.hysteresis == 0.0 and self.delay == 0.0 and self.jitter == 0.0
        self._on_at = 0.5 * (self.width - self.hysteresis)      # turns on within this
        self._off_at = 0.5 * (self.width + self.hysteresis)     # turns off beyond this
        self._random = random.Random(f'home switch:{seed}')
        self.active: bool | None = None         # the switch itself (None: not seen yet)
        self.input = False                      # what the drive reads
        self._changes: deque[tuple[float, bool]] = deque()    # (instant shown, state)
        self._last = (0.0, 0.0)                 # (angle, instant) last sensed
        #: (instant, angle, state) of every change the switch itself made (for tests/plots)
        self.edges: list[tuple[float, float, bool]] = []

    def ideal_active(self, angle: float) -> bool:
        """The ideal switch: active within half its width of the bottom."""
        return _from_bottom(angle) <= 0.5 * self.width

    def sense(self, angle: float, now: float) -> None:
        """The mechanism at `angle` at motor time `now`: the switch's change, if any, found
        between the last angle sensed and this one (its instant interpolated) and queued for
        the input `delay` + jitter later."""
        if self.active is None:
            self.active = self.input = _from_bottom(angle) <= 0.5 * self.width
            self._last = (angle, now)
            return
        d = _from_bottom(angle)
        turn = d > self._off_at if self.active else d <= self._on_at
        if turn:
            threshold = self._off_at if self.active else self._on_at
            before, then = self._last
            d0 = _from_bottom(before)
            share = (threshold - d0) / (d - d0) if d != d0 else 1.0
            share = min(1.0, max(0.0, share))
            # interpolated within a servo sub-step; else (the first motion) at `now`
            at = then + share * (now - then) if 0.0 <= now - then <= 0.01 else now
            self.active = not self.active
            self.edges.append((at, before + share * (angle - before), self.active))
            shown = at + self.delay + (self._random.uniform(0.0, self.jitter)
                                       if self.jitter else 0.0)
            if self._changes:
                shown = max(shown, self._changes[-1][0])     # an input keeps its order
            self._changes.append((shown, self.active))
        self._last = (angle, now)

    def read(self, now: float) -> bool:
        """The input at motor time `now`."""
        while self._changes and self._changes[0][0] <= now:
            self.input = self._changes.popleft()[1]
        return self.input
