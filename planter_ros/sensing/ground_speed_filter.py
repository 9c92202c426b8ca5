"""Which measured ground-speed samples to believe: one rule for the sync law and the monitor.

A sample is rejected (and counted) when it is NaN/inf, faster than `max_ground_speed`, or
further from the last sample taken than `max_ground_acceleration` allows over the time between
them, plus a noise `tolerance` (a spike). A genuine lasting step is taken once the allowance,
growing with the time since the last sample taken, covers it. A plausible negative sample
(reversing, or noise around standstill) is counted and read as 0: the machine is not moving
forward, and nothing integrates distance backwards. Pure Python, no ROS.
"""

from collections.abc import Sequence
from dataclasses import dataclass
import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planter_ros.config import check, setting

REJECT_REASONS = ('non_finite', 'too_fast', 'spike', 'negative')


class PlausibleRule(NamedTuple):
    """The rule of one sensor's samples: at most `max_abs` in size, changing at most
    `max_rate` per second from the last sample taken plus a noise `tolerance`."""

    max_abs: float
    max_rate: float
    tolerance: float


@dataclass(frozen=True)
class GroundSpeedLimits:
    """Plausibility limits of a ground-speed sensor (SI): parameters of the sync node; the
    monitor and replay use the defaults."""

    max_ground_speed: float = setting(
        3.0, 'faster samples are implausible and rejected', unit='m/s', range=(0.1, 10.0))
    max_ground_acceleration: float = setting(
        3.0, 'samples jumping more than this allows are spikes, rejected', unit='m/s²',
        range=(0.1, 50.0))
    ground_speed_tolerance: float = setting(
        0.05, 'sensor noise allowed on top of the spike limit', unit='m/s', range=(0.0, 1.0))

    def __post_init__(self) -> None:
        check(self)

    @property
    def rule(self) -> PlausibleRule:
        return PlausibleRule(self.max_ground_speed, self.max_ground_acceleration,
                             self.ground_speed_tolerance)


def implausible(x: object, t: float, last: tuple[float, float] | None,
                rule: PlausibleRule) -> str | None:
    """Why sample x at time t is not believable under `rule` (PlausibleRule), or None:
    'non_finite', 'too_fast' (|x| above max_abs) or 'spike' (further from the last sample
    taken, `last` = (value, time) or None, than max_rate allows over the time between them,
    plus the noise tolerance). The rule of every sensor."""
    if not isinstance(x, (int, float)) or not math.isfinite(x):
        return 'non_finite'
    if abs(x) > rule.max_abs:
        return 'too_fast'
    if last is not None and abs(x - last[0]) > rule.tolerance + rule.max_rate * (t - last[1]):
        return 'spike'
    return None


class GroundSpeedFilter:
    """Stateful sample check; `rejected` counts by reason, `accepted` counts the rest."""

    def __init__(self, limits: GroundSpeedLimits = GroundSpeedLimits()) -> None:
        self.limits = limits
        self.rejected = {r: 0 for r in REJECT_REASONS}
        self.accepted = 0
        self._ref_v: float | None = None
        self._ref_t = 0.0

    def check(self, v: float, t: float) -> tuple[float | None, str | None]:
        """(speed to use or None, rejection reason or None) for sample v (m/s) at time t (s)."""
        last = None if self._ref_v is None else (self._ref_v, self._ref_t)
        reason = implausible(v, t, last, self.limits.rule)
        if reason is None and v < 0.0:
            reason = 'negative'
        if reason is not None:
            self.rejected[reason] += 1
            if reason != 'negative':
                return None, reason
        else:
            self.accepted += 1
        self._ref_v, self._ref_t = float(v), t
        return max(float(v), 0.0), reason


def filter_ground_speed(t: Sequence[float] | NDArray[np.float64],
                        v: Sequence[float] | NDArray[np.float64],
                        limits: GroundSpeedLimits = GroundSpeedLimits()
                        ) -> tuple[list[float], list[float]]:
    """The samples of a whole recording the filter keeps, in order: (times, speeds) lists."""
    check = GroundSpeedFilter(limits).check
    kept_t: list[float] = []
    kept_v: list[float] = []
    for ti, vi in zip(t, v):
        used, _ = check(float(vi), float(ti))
        if used is not None:
            kept_t.append(ti)
            kept_v.append(used)
    return kept_t, kept_v


_WINDOW = 256        # samples checked at once against their predecessor (plausible_run)


def plausible_run(x: ArrayLike, t: ArrayLike, rule: PlausibleRule) -> NDArray[np.bool_]:
    """Which samples x (at increasing times t, arrays) a filter applying `implausible` with
    `rule` (PlausibleRule) one by one would take: a boolean array. Each sample is judged
    against the last one taken, as the stateful filters do, with the same arithmetic; a run
    of samples that are all taken is judged at once (each against its predecessor), only the
    samples after a rejection one by one until the next one is taken."""
    max_abs, max_rate, tolerance = rule
    x = np.asarray(x, dtype=float)
    t = np.asarray(t, dtype=float)
    taken = np.zeros(x.size, dtype=bool)
    with np.errstate(invalid='ignore'):
        candidates = np.flatnonzero(np.isfinite(x) & (np.abs(x) <= max_abs))
    if not candidates.size:
        return taken
    ref = int(candidates[0])                 # nothing taken before it: no spike rule
    taken[ref] = True
    k, n = 1, candidates.size
    while k < n:
        # a window of candidates, each against the one before it (valid while all are taken)
        block = candidates[k:k + _WINDOW]
        before = np.concatenate(([ref], block[:-1]))
        spike = np.abs(x[block] - x[before]) > tolerance + max_rate * (t[block] - t[before])
        bad = np.flatnonzero(spike)
        upto = bad[0] if bad.size else block.size
        taken[block[:upto]] = True
        if upto:
            ref = int(block[upto - 1])
        k += int(upto)
        if not bad.size:
            continue
        # a rejection: the next candidates against the last one taken, until one is taken
        while k < n:
            i = int(candidates[k])
            k += 1
            if not abs(x[i] - x[ref]) > tolerance + max_rate * (t[i] - t[ref]):
                taken[i] = True
                ref = i
                break
    return taken
