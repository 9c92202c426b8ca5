"""The simulated field: true ground-speed profiles of a transplanter run (callable t -> m/s,
with their exact travelled distance), used by the closed-loop simulation, the sample streams
and the demo's ground-speed sensor. A run may include curves: then the profile also has a yaw
rate, each row's own travelled distance, and the machine's pose (x, y, heading) along the way.

Frames follow REP 103: x forward, y left, the heading and yaw rate + counter-clockwise (a left
turn); a row at lateral offset y travels at v·(1 − κ·y), κ the path's signed curvature.
"""

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from planter_ros.kinematics.arrays import FloatArray, Floats

# (t, s, heading, x, y) on the profile's fine grid
_Path = tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]


@dataclass(frozen=True)
class Curve:
    """A steady turn from `start` to `end` (s) of signed `radius` (m, + = left turn), its
    curvature eased in and out over `ease` s at either end (no step in the yaw rate)."""

    start: float
    end: float
    radius: float
    ease: float = 0.5

    def breakpoints(self) -> tuple[list[float], list[float]]:
        """(times, curvatures) of the piecewise-linear curvature, 0 outside the curve."""
        ease = min(self.ease, 0.5 * (self.end - self.start))
        k = 1.0 / self.radius
        return ([self.start, self.start + ease, self.end - ease, self.end], [0.0, k, k, 0.0])


@dataclass(frozen=True)
class Stop:
    """A halt in the middle of a run: the speed ramps down to 0 over `ramp` s from `start` (s),
    stays 0 for `hold` s, then ramps back over `ramp` s (a headland, a refill of seedlings)."""

    start: float
    hold: float
    ramp: float = 1.0

    def factor(self, t: float) -> float:
        """The fraction of the run's speed left at time t (0..1)."""
        down = self.start + self.ramp
        up = down + self.hold
        if t <= self.start or t >= up + self.ramp:
            return 1.0
        if t < down:
            return (down - t) / self.ramp
        if t <= up:
            return 0.0
        return (t - up) / self.ramp


@dataclass(frozen=True)
class Ramps:
    """How a run starts and ends: the speed ramps up from 0 over `start` s and down to a stop
    over `stop` s."""

    start: float = 2.0
    stop: float = 2.0


def demo_curves(duration: float, radius: float = 10.0,
                length: float = 8.0) -> tuple[Curve, Curve]:
    """A left and a right turn of `radius` (m), each `length` s (a quarter of the run in a run
    under 32 s), in the two cruise phases of a `FieldProfile` of `duration` s: from 15 % and
    60 % of the run."""
    length = min(length, 0.25 * duration)
    return (Curve(0.15 * duration, 0.15 * duration + length, radius),
            Curve(0.6 * duration, 0.6 * duration + length, -radius))


class FieldProfile:
    """A transplanter run, callable t -> v (m/s): ramp up over `start` s, cruise, a speed change
    to `change`·cruise at 45 % of the run (over 1 s), and a ramp to a stop (over `stop` s)
    ending 1 s before `duration` (`ramps`: Ramps, the start and stop ramps' lengths). The phase
    boundaries are attributes (s). `curves`: `Curve`s (not overlapping) the path makes
    meanwhile; none = a straight run. `stops`: `Stop`s on the way (the yaw rate is v·κ, so the
    machine does not turn while it stands)."""

    def __init__(self, duration: float, cruise: float, change: float = 1.5,
                 curves: Iterable[Curve] = (), stops: Iterable[Stop] = (),
                 ramps: Ramps = Ramps()) -> None:
        self.duration, self.cruise, self.change = duration, cruise, change
        self.stops = tuple(stops)
        self.start, self.stop = ramps.start, ramps.stop
        self.t_change = 0.45 * duration
        self.t_stop_end = duration - 1.0
        self.t_stop = self.t_stop_end - ramps.stop
        self.curves = tuple(sorted(curves, key=lambda c: c.start))
        times, kappas = [0.0], [0.0]
        for curve in self.curves:
            t, k = curve.breakpoints()
            times += t
            kappas += k
        self._kappa = (np.asarray(times), np.asarray(kappas))
        self._path: _Path | None = None              # integrated on first use

    def __call__(self, t: float) -> float:
        if t <= 0.0 or t >= self.t_stop_end:
            return 0.0
        if t < self.start:
            base = self.cruise * t / self.start
        elif t < self.t_change:
            base = self.cruise
        elif t < self.t_change + 1.0:
            base = self.cruise * (1.0 + (self.change - 1.0) * (t - self.t_change))
        else:
            base = self.cruise * self.change
        if t > self.t_stop:
            base *= (self.t_stop_end - t) / self.stop
        for halt in self.stops:
            base *= halt.factor(t)
        return base

    def distance(self, t: Floats, dt: float = 1e-3) -> Floats:
        """True travelled distance (m) at times t (array), by the trapezoid rule on a fine grid."""
        grid = np.arange(0.0, max(float(np.max(t)), 0.0) + 2 * dt, dt)
        v = np.array([self(x) for x in grid])
        s = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)))
        distance: Floats = np.interp(t, grid, s)
        return distance

    def curvature(self, t: Floats) -> Floats:
        """Signed path curvature κ (1/m, + = turning left) at time(s) t."""
        kappa: Floats = np.interp(t, *self._kappa)
        return kappa

    def yaw_rate(self, t: float) -> float:
        """True yaw rate ω_z = v·κ (rad/s, + counter-clockwise) at time t (s)."""
        return self(t) * float(self.curvature(t))

    def _integrated(self) -> _Path:
        """(t, s, heading, x, y) on a fine grid over the run, integrated once (trapezoid)."""
        if self._path is None:
            dt = max(1e-3, self.duration / 100_000)
            t = np.arange(0.0, self.duration + 2 * dt, dt)
            v = np.array([self(x) for x in t])

            def integral(f: FloatArray) -> FloatArray:
                return np.concatenate(([0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * dt)))
            s = integral(v)
            heading = integral(v * self.curvature(t))
            self._path = (t, s, heading, integral(v * np.cos(heading)),
                          integral(v * np.sin(heading)))
        return self._path

    def pose(self, t: Floats) -> tuple[Floats, Floats, Floats]:
        """The machine's reference point at time(s) t: (x, y, heading) in m, m, rad, in the
        field frame of the start (x forward at t = 0, y left)."""
        grid, _, heading, x, y = self._integrated()
        return np.interp(t, grid, x), np.interp(t, grid, y), np.interp(t, grid, heading)

    def row_distance(self, t: Floats, lateral_offset: float) -> Floats:
        """True distance (m) a row at `lateral_offset` (m, + left) has travelled at time(s) t:
        ∫v·(1 − κ·y) dt = s − y·heading."""
        grid, s, heading, _, _ = self._integrated()
        distance: Floats = np.interp(t, grid, s) - lateral_offset * np.interp(t, grid, heading)
        return distance


def field_profile(duration: float, cruise: float, change: float = 1.5,
                  curves: Iterable[Curve] = (), stops: Iterable[Stop] = (),
                  ramps: Ramps = Ramps()) -> FieldProfile:
    return FieldProfile(duration, cruise, change, curves, stops, ramps)


def speed_profile(t: Floats, cruise: float, duration: float, step_at: float | None = None,
                  step: float = 1.25, ramp: float = 2.0) -> Floats:
    """True ground speed (m/s): ramp up, cruise, a step to step·cruise, ramp down to a stop."""
    step_at = 0.5 * duration if step_at is None else step_at
    up = np.clip(t / ramp, 0.0, 1.0)
    down = np.clip((duration - t) / ramp, 0.0, 1.0)
    level = np.where(t < step_at, cruise, step * cruise)
    speed: Floats = level * np.minimum(up, down)
    return speed
