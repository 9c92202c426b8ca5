"""The simulated drive's motor: a speed loop (first-order lag `time_constant` towards the speed
asked, within an acceleration limit), a coasting decay with the power stage off, and an encoder
integrating the speed into increments. It keeps its own time and integrates in `SERVO_STEP`
sub-steps up to each instant asked for, so a simulating thread that runs late (a loaded host)
changes nothing: a drive's servo loop never stalls. Plain state in motor counts; the drive's
lock is held by the caller."""
from __future__ import annotations

from collections.abc import Callable
import math

from .spec import SimSpec

__all__ = ['Motor', 'SERVO_STEP']

SERVO_STEP = 0.001      # s, the motor model's own step

# law(dt, now, velocity) -> (speed wanted, acceleration limit), counts/s and counts/s²
Law = Callable[[float, float, float], tuple[float, float]]
# after(position before, dt, now) after each sub-step
After = Callable[[float, float, float], None]


class Motor:
    """Speed, position and the motor's own clock (module doc)."""

    def __init__(self, spec: SimSpec) -> None:
        self.time_constant = float(spec.time_constant)
        self.coast_time_constant = float(spec.coast_time_constant)
        self.counts_per_rev = int(spec.counts_per_motor_rev)
        #: the motor's own acceleration limit, counts/s²
        self.limit = spec.max_acceleration * self.counts_per_rev / (2.0 * math.pi)
        self.velocity = 0.0       # counts/s
        self.position = 0.0       # counts
        self.time: float | None = None

    def lag(self, target: float, dt: float) -> float:
        """The speed loop's answer to `target` (counts/s) over `dt` s."""
        v = self.velocity
        return v + (target - v) * (1.0 - math.exp(-dt / self.time_constant))

    def coast(self, dt: float) -> float:
        return self.velocity * math.exp(-dt / self.coast_time_constant)

    def advance(self, now: float, law: Law, after: After) -> None:
        """Integrate up to `now` (monotonic s); the first call, or one after a pause of over
        a second (a paused simulation), only sets the clock."""
        last = self.time
        if last is None or now - last > 1.0:
            self.time = now
            return
        if now <= last:
            return
        steps = max(1, math.ceil((now - last) / SERVO_STEP - 1e-9))
        h = (now - last) / steps
        for k in range(1, steps + 1):
            t = last + k * h
            v = self.velocity
            wanted, limit = law(h, t, v)
            limit = min(limit, self.limit)
            self.velocity = v + max(-limit * h, min(limit * h, wanted - v))
            before = self.position
            self.position += 0.5 * (v + self.velocity) * h
            after(before, h, t)
        self.time = now

    @property
    def shaft_velocity(self) -> float:
        """rad/s of the motor shaft."""
        return self.velocity * 2.0 * math.pi / self.counts_per_rev

    @property
    def shaft_position(self) -> float:
        """rad of the motor shaft."""
        return self.position * 2.0 * math.pi / self.counts_per_rev
