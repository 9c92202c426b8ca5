"""The simulated field: true ground-speed profiles of a transplanter run (callable t -> m/s,
with their exact travelled distance), used by the closed-loop simulation, the sample streams
and the demo's ground-speed sensor."""

import numpy as np


class FieldProfile:
    """A transplanter run, callable t -> v (m/s): ramp up over `start` s, cruise, a speed change
    to `change`·cruise at 45 % of the run (over 1 s), and a ramp to a stop (over `stop` s)
    ending 1 s before `duration`. The phase boundaries are attributes (s)."""

    def __init__(self, duration, cruise, change=1.5, start=2.0, stop=2.0):
        self.duration, self.cruise, self.change = duration, cruise, change
        self.start, self.stop = start, stop
        self.t_change = 0.45 * duration
        self.t_stop_end = duration - 1.0
        self.t_stop = self.t_stop_end - stop

    def __call__(self, t):
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
        return base

    def distance(self, t, dt=1e-3):
        """True travelled distance (m) at times t (array), by the trapezoid rule on a fine grid."""
        grid = np.arange(0.0, max(float(np.max(t)), 0.0) + 2 * dt, dt)
        v = np.array([self(x) for x in grid])
        s = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)))
        return np.interp(t, grid, s)


def field_profile(duration, cruise, change=1.5, start=2.0, stop=2.0):
    return FieldProfile(duration, cruise, change, start, stop)


def speed_profile(t, cruise, duration, step_at=None, step=1.25, ramp=2.0):
    """True ground speed (m/s): ramp up, cruise, a step to step·cruise, ramp down to a stop."""
    step_at = 0.5 * duration if step_at is None else step_at
    up = np.clip(t / ramp, 0.0, 1.0)
    down = np.clip((duration - t) / ramp, 0.0, 1.0)
    level = np.where(t < step_at, cruise, step * cruise)
    return level * np.minimum(up, down)
