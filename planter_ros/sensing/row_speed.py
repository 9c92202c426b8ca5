"""Each row's own ground speed on a curve: v_i = v − ω_z·y_i, from samples worth believing.

The ground-speed message (geometry_msgs/TwistStamped) carries the machine's forward speed v in
`twist.linear.x` and its yaw rate ω_z in `twist.angular.z` (rad/s, + counter-clockwise, REP 103).
A row at lateral offset y_i (+ = left) travels at v_i = v − ω_z·y_i: on a left turn the left
rows are the inner ones and slower. One rule for the sync law, the monitor and replay:

* the speed passes `GroundSpeedFilter` (NaN/inf, too fast, spikes rejected and counted; a
  plausible negative sample is counted and used as it is: the machine reversing);
* the yaw rate passes `YawRateFilter`, the same rule with its own limits (no sign rule: both
  directions are turns). A rejected yaw rate keeps the last accepted one, for at most
  `yaw_rate_timeout`; after that the machine is taken to go straight (ω_z = 0);
* only a sample whose speed is accepted moves the rows (a yaw rate alone does not: it would
  hide a dead speed sensor from the stale rule);
* a machine not moving forward (v ≤ 0) moves no row: a transplanter does not turn on the spot,
  and gyro noise at standstill must not creep the rows;
* a row whose v_i ≤ 0 is not moving forward: its speed is 0 (it holds, it never turns
  backwards, and its travelled distance does not run backwards).

Pure Python and numpy, no ROS.
"""

from collections.abc import Sequence
from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planter_ros.config import check, setting

from .ground_speed_filter import (
    GroundSpeedFilter, GroundSpeedLimits, PlausibleRule, implausible, plausible_run)

YAW_REJECT_REASONS = ('non_finite', 'too_fast', 'spike')

FloatArray = NDArray[np.float64]
# (t s, v m/s, ω_z rad/s or None: no yaw rate recorded) of a recording's ground-speed messages
TwistSamples = tuple[ArrayLike, ArrayLike, ArrayLike | None]


@dataclass(frozen=True)
class YawRateLimits:
    """Plausibility limits of the yaw-rate reading (SI): parameters of the sync node; the
    monitor and replay use the defaults."""

    max_yaw_rate: float = setting(1.5, 'faster yaw rates are implausible and rejected (a 1 m '
                                  'radius at 1.5 m/s)', unit='rad/s', range=(0.01, 10.0))
    max_yaw_acceleration: float = setting(3.0, 'yaw-rate samples jumping more than this allows '
                                          'are spikes, rejected', unit='rad/s²',
                                          range=(0.01, 100.0))
    yaw_rate_tolerance: float = setting(0.05, 'sensor noise allowed on top of the spike limit',
                                        unit='rad/s', range=(0.0, 1.0))
    yaw_rate_timeout: float = setting(0.5, 'no accepted yaw rate for this long: the rows are '
                                      'driven as on a straight line (ω_z = 0)', unit='s',
                                      range=(0.05, 10.0))

    def __post_init__(self) -> None:
        check(self)

    @property
    def rule(self) -> PlausibleRule:
        return PlausibleRule(self.max_yaw_rate, self.max_yaw_acceleration,
                             self.yaw_rate_tolerance)


class YawRateFilter:
    """Stateful yaw-rate check; `rejected` counts by reason, `accepted` counts the rest."""

    def __init__(self, limits: YawRateLimits = YawRateLimits()) -> None:
        self.limits = limits
        self.rejected = {r: 0 for r in YAW_REJECT_REASONS}
        self.accepted = 0
        self._ref_w: float | None = None
        self._ref_t = 0.0

    def check(self, w: float, t: float) -> tuple[float | None, str | None]:
        """(yaw rate to use or None, rejection reason or None) for sample w (rad/s) at t (s)."""
        last = None if self._ref_w is None else (self._ref_w, self._ref_t)
        reason = implausible(w, t, last, self.limits.rule)
        if reason is not None:
            self.rejected[reason] += 1
            return None, reason
        self.accepted += 1
        self._ref_w, self._ref_t = float(w), t
        return float(w), None


class MotionFilter:
    """The machine's motion samples worth believing: speed and yaw rate (see the module doc)."""

    def __init__(self, limits: GroundSpeedLimits | None = None,
                 yaw_limits: YawRateLimits | None = None) -> None:
        self.speed = GroundSpeedFilter(limits or GroundSpeedLimits())
        self.yaw = YawRateFilter(yaw_limits or YawRateLimits())
        self._w = 0.0
        self._t_w: float | None = None    # time of the last accepted yaw rate

    def configure(self, limits: GroundSpeedLimits, yaw_limits: YawRateLimits) -> None:
        self.speed.limits = limits
        self.yaw.limits = yaw_limits

    def check(self, v: float, w: float, t: float,
              yaw: bool = True) -> tuple[float, float] | None:
        """(v, ω_z) to move the rows with, or None when the speed sample is rejected. v is the
        plausible speed as measured (negative when reversing), ω_z the accepted or held yaw
        rate (0 once it is older than yaw_rate_timeout). `yaw` False: the yaw rate is not
        looked at (every row at y = 0) and ω_z is 0."""
        if yaw:
            w_used, _ = self.yaw.check(w, t)
            if w_used is not None:
                self._w, self._t_w = w_used, t
        used, reason = self.speed.check(v, t)
        if used is None:
            return None
        return (float(v) if reason == 'negative' else used), (self.yaw_rate(t) if yaw else 0.0)

    def yaw_rate(self, t: float) -> float:
        """The yaw rate in use at time t (rad/s)."""
        return self._w if self.yaw_fresh(t) else 0.0

    def yaw_fresh(self, t: float) -> bool:
        return self._t_w is not None and t - self._t_w <= self.yaw.limits.yaw_rate_timeout


def row_speed(v: float, yaw_rate: float, lateral_offset: float) -> float:
    """A row's forward speed (m/s, ≥ 0): v − ω_z·y, 0 when that is not forward or the machine
    is not moving forward."""
    return max(v - yaw_rate * lateral_offset, 0.0) if v > 0.0 else 0.0


class RowSpeedStream:
    """Samples in, each row's speed out, one sample at a time (the monitor; replay runs the
    same through `row_speed_samples`). Samples with a non-finite time or speed, or a time not
    after the last such sample, are dropped before the filter (the prediction model's rule)."""

    def __init__(self, offsets: Sequence[float] | FloatArray,
                 limits: GroundSpeedLimits | None = None,
                 yaw_limits: YawRateLimits | None = None, yaw: bool | None = None) -> None:
        """`yaw`: look at the yaw rate; default only if a row is off the centre line (rows at
        y = 0 do not turn with it); the as-planted map needs it always."""
        self.offsets = np.asarray(offsets, dtype=float)
        self.filter = MotionFilter(limits, yaw_limits)
        self._yaw = bool(np.any(self.offsets)) if yaw is None else bool(yaw)
        self._seen = -math.inf

    def motion(self, t: float, v: float, w: float) -> tuple[float, float, float] | None:
        """(t, v, ω_z) the rows move with, or None for a sample they do not use."""
        t, v = float(t), float(v)
        if not (math.isfinite(t) and math.isfinite(v)) or not t > self._seen:
            return None
        self._seen = t
        motion = self.filter.check(v, float(w), t, self._yaw)
        return None if motion is None else (t, *motion)

    def add(self, t: float, v: float, w: float) -> tuple[float, FloatArray] | None:
        """(t, speeds per row as an array) or None for a sample the rows do not use."""
        sample = self.motion(t, v, w)
        if sample is None:
            return None
        return sample[0], self.speeds(sample[1], sample[2])

    def speeds(self, v: float, yaw_rate: float) -> FloatArray:
        """Each row's speed (array) for the machine's motion (v, ω_z) from `motion`."""
        return _row_speeds(np.float64(v), np.float64(yaw_rate), self.offsets)


def _row_speeds(v: float | FloatArray, yaw_rate: float | FloatArray,
                offsets: FloatArray) -> FloatArray:
    """v − ω_z·y for every row (offsets as a column against arrays of samples), 0 where that
    is not forward or the machine is not moving forward."""
    return np.where(v > 0.0, np.maximum(v - yaw_rate * offsets, 0.0), 0.0)


def motion_samples(samples: TwistSamples, offsets: Sequence[float] | FloatArray,
                   limits: GroundSpeedLimits | None = None,
                   yaw_limits: YawRateLimits | None = None,
                   yaw: bool | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The machine's motion over a whole recording as the rows use it: (times, v, ω_z), each
    (n,), of the `samples` (t, v, ω_z) `RowSpeedStream.motion` keeps, in order, with its
    arithmetic (vectorised: ground_speed_filter.plausible_run). ω_z may be None (no yaw rate
    recorded: straight); `yaw` as for RowSpeedStream."""
    t, v, w = samples
    t = np.asarray(t, dtype=float)
    v = np.asarray(v, dtype=float)
    w = np.zeros_like(v) if w is None else np.asarray(w, dtype=float)
    limits = limits or GroundSpeedLimits()
    yaw_limits = yaw_limits or YawRateLimits()
    use_yaw = bool(np.any(np.asarray(offsets, dtype=float))) if yaw is None else bool(yaw)
    # the stream's gate: a finite time and speed, the time after every such one before it
    finite = np.isfinite(t) & np.isfinite(v)
    seen = np.maximum.accumulate(np.where(finite, t, -np.inf))
    gate = finite & (t > np.concatenate(([-np.inf], seen[:-1])))
    t, v, w = t[gate], v[gate], w[gate]
    kept = plausible_run(v, t, limits.rule)
    if not kept.any():
        return np.zeros(0), np.zeros(0), np.zeros(0)
    if use_yaw:
        # the yaw rate in use: the last accepted one (this sample's own included), while fresh
        taken = plausible_run(w, t, yaw_limits.rule)
        last = np.maximum.accumulate(np.where(taken, np.arange(t.size), -1))
        at = np.maximum(last, 0)
        fresh = (last >= 0) & (t - t[at] <= yaw_limits.yaw_rate_timeout)
        used = np.where(fresh, w[at], 0.0)
    else:
        used = np.zeros(t.size)
    return t[kept], v[kept], used[kept]


def row_speed_samples(samples: TwistSamples, offsets: Sequence[float] | FloatArray,
                      limits: GroundSpeedLimits | None = None,
                      yaw_limits: YawRateLimits | None = None,
                      motion: tuple[FloatArray, FloatArray, FloatArray] | None = None
                      ) -> tuple[FloatArray, FloatArray]:
    """Each row's speed over a whole recording: (times (n,), speeds (rows, n)) of the
    `samples` (t, v, ω_z) the rows use, in order. ω_z may be None (no yaw rate recorded:
    straight); `motion`: the samples' `motion_samples`, if already known."""
    kept_t, kept_v, kept_w = motion or motion_samples(samples, offsets, limits, yaw_limits)
    offsets = np.asarray(offsets, dtype=float)
    if not kept_t.size:
        return np.zeros(0), np.zeros((len(offsets), 0))
    return kept_t, _row_speeds(kept_v, kept_w, offsets[:, None])
