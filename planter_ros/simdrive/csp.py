"""Cyclic synchronous position in the simulated drive: the target taken at each SYNC, the set
point interpolated linearly to it over one interpolation period (60C2h:1 × 10^60C2h:2 s, as
the master wrote it; 1006h where the drive has no 60C2h), extrapolated at the last segment's
speed for at most `EXTRAPOLATE_PERIODS` when a SYNC brings no new target, then held; and the
following-error watch (6065h window, 6066h time-out). Plain state in motor counts: the drive's
lock is held by the caller."""
from __future__ import annotations

import math

__all__ = ['CspSetpoint', 'wrap_i32']


def wrap_i32(value: int) -> int:
    return (value + 2**31) % 2**32 - 2**31


class CspSetpoint:
    """The CSP set point of one drive (module doc)."""

    #: a SYNC without a new target (lost on the bus, or late), or a SYNC lost: the set point
    #: goes on at the last segment's speed for at most this many periods, then holds
    EXTRAPOLATE_PERIODS = 1

    def __init__(self) -> None:
        self.pending: int | None = None   # the target taken at the last SYNC (motor counts)
        self.start_from = 0.0
        self.to = 0.0
        self.start = -math.inf
        self.extrapolated = 0             # segments in a row without a new target
        self.period = 0.0                 # s, the interpolation period (0: not told)
        self.window = math.inf            # counts, 6065h
        self.timeout = 0.0                # s, 6066h
        self.since: float | None = None   # the following error beyond the window since
        self.error = 0.0                  # counts, set point - actual
        self.targets_missing = 0          # SYNCs that found no new target
        self.last_fault = ''

    @property
    def interpolation_period(self) -> float:
        return self.period or 0.01

    def unwrap(self, raw: int) -> float:
        """A 32-bit target position near the current set point (counts, unwrapped)."""
        return self.to + wrap_i32(int(raw) - round(self.to))

    def hold(self, position: float) -> None:
        """The set point = `position`, standing (at enable, entering CSP, after homing)."""
        self.start_from = self.to = float(position)
        self.start = -math.inf
        self.pending = None
        self.since = None
        self.error = 0.0

    def next_segment(self, now: float) -> None:
        """At a SYNC: interpolate from the set point to the target taken; without one, go on
        at the last segment's speed (at most EXTRAPOLATE_PERIODS in a row), then hold."""
        if self.pending is not None:
            self.start_from = self.setpoint(now)
            self.to = self.unwrap(self.pending)
            self.pending = None
            self.extrapolated = 0
        else:
            self.targets_missing += 1
            step = self.to - self.start_from
            self.start_from = self.setpoint(now)
            self.extrapolated += 1
            if self.extrapolated > self.EXTRAPOLATE_PERIODS or not math.isfinite(self.start):
                step = 0.0
            self.to = self.start_from + step
        self.start = now

    def reach(self) -> float:
        """How many periods the current segment's speed lasts: one, plus the extrapolation
        left when no SYNC comes (a lost SYNC)."""
        return 1.0 + max(self.EXTRAPOLATE_PERIODS - self.extrapolated, 0)

    def setpoint(self, now: float) -> float:
        """The interpolated position set point (counts) at `now`."""
        share = min(max((now - self.start) / self.interpolation_period, 0.0), self.reach())
        return self.start_from + (self.to - self.start_from) * share

    def feed_forward(self, now: float) -> float:
        """The set point's speed at `now` (counts/s)."""
        period = self.interpolation_period
        moving = now - self.start < period * self.reach()
        return (self.to - self.start_from) / period if moving else 0.0

    def guide(self, now: float) -> tuple[float, float]:
        """(`setpoint(now)`, `feed_forward(now)`) in one pass: the servo asks both at every
        sub-step."""
        period = self.period or 0.01
        reach = 1.0 + max(self.EXTRAPOLATE_PERIODS - self.extrapolated, 0)
        start_from, to, elapsed = self.start_from, self.to, now - self.start
        share = min(max(elapsed / period, 0.0), reach)
        return (start_from + (to - start_from) * share,
                (to - start_from) / period if elapsed < period * reach else 0.0)

    def follow(self, now: float, position: float, velocity: float, dt: float,
               setpoint: float | None = None) -> bool:
        """The following error at `now` with the motor at `position` (`setpoint`: the set point
        at `now`, when the caller has it); True when it stayed beyond the window for the
        time-out (a fault: `last_fault` says what)."""
        if setpoint is None:
            setpoint = self.setpoint(now)
        self.error = setpoint - position
        if abs(self.error) <= self.window:
            self.since = None
            return False
        self.since = now if self.since is None else self.since
        if now - self.since < self.timeout:
            return False
        self.last_fault = (
            f'following error {self.error:.0f} counts > window {self.window:.0f} for '
            f'{now - self.since:.3f} s (set point {setpoint:.0f}, segment '
            f'{self.start_from:.0f} -> {self.to:.0f} started {now - self.start:.3f} s ago, '
            f'speed {velocity:.0f} counts/s, dt {dt:.4f} s)')
        return True
