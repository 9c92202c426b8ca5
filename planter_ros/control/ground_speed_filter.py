"""Which measured ground-speed samples to believe: one rule for the sync law and the monitor.

A sample is rejected (and counted) when it is NaN/inf, faster than `max_ground_speed`, or
further from the last sample taken than `max_ground_acceleration` allows over the time between
them, plus a noise `tolerance` (a spike). A genuine lasting step is taken once the allowance,
growing with the time since the last sample taken, covers it. A plausible negative sample
(reversing, or noise around standstill) is counted and read as 0: the machine is not moving
forward, and nothing integrates distance backwards. Pure Python, no ROS.
"""

from dataclasses import dataclass
import math

REJECT_REASONS = ('non_finite', 'too_fast', 'spike', 'negative')


@dataclass(frozen=True)
class GroundSpeedLimits:
    """Plausibility limits of a ground-speed sensor (SI); the sync node validates the values
    its parameters set (PhaseLockConfig), the monitor uses these defaults."""

    max_ground_speed: float = 3.0           # m/s, faster samples are implausible
    max_ground_acceleration: float = 3.0    # m/s², larger jumps are spikes
    ground_speed_tolerance: float = 0.05    # m/s, sensor noise allowed on top of that


class GroundSpeedFilter:
    """Stateful sample check; `rejected` counts by reason, `accepted` counts the rest."""

    def __init__(self, limits=GroundSpeedLimits()):
        self.limits = limits
        self.rejected = {r: 0 for r in REJECT_REASONS}
        self.accepted = 0
        self._ref_v = None
        self._ref_t = None

    def check(self, v, t):
        """(speed to use or None, rejection reason or None) for sample v (m/s) at time t (s)."""
        lim = self.limits
        reason = None
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            reason = 'non_finite'
        elif abs(v) > lim.max_ground_speed:
            reason = 'too_fast'
        elif self._ref_v is not None and abs(v - self._ref_v) > (
                lim.ground_speed_tolerance + lim.max_ground_acceleration * (t - self._ref_t)):
            reason = 'spike'
        elif v < 0.0:
            reason = 'negative'
        if reason is not None:
            self.rejected[reason] += 1
            if reason != 'negative':
                return None, reason
        else:
            self.accepted += 1
        self._ref_v, self._ref_t = float(v), t
        return max(float(v), 0.0), reason


def filter_ground_speed(t, v, limits=GroundSpeedLimits()):
    """The samples of a whole recording the filter keeps, in order: (times, speeds) lists."""
    check = GroundSpeedFilter(limits).check
    kept_t, kept_v = [], []
    for ti, vi in zip(t, v):
        used, _ = check(float(vi), float(ti))
        if used is not None:
            kept_t.append(ti)
            kept_v.append(used)
    return kept_t, kept_v
