"""The demo's field run: what the simulated ground-speed sensor and GNSS receiver report.

A start, a cruise with noise, a left and a right turn of 10 m radius (sim.field.demo_curves),
a speed change, a stop; the sensor adds noise on speed and yaw rate and two glitches the sync
node must reject (a 25 m/s spike at 30 % of the run, a NaN at 60 %).
"""

import math

from planter_ros.sim.field import FieldProfile, demo_curves

__all__ = ['field_profile', 'glitches']


def field_profile(duration: float, cruise: float, top: float | None = None) -> FieldProfile:
    """The run's true ground speed and path: `duration` s at `cruise` m/s, a speed-up by
    half (never above `top` m/s, the scene's top ground speed), two turns."""
    change = 1.5 if not top else min(1.5, top / cruise)
    return FieldProfile(duration, cruise, change=change, curves=demo_curves(duration))


def glitches(duration: float) -> list[tuple[float, float]]:
    """(time s, value m/s) of the samples the sensor gets wrong: a spike and a NaN."""
    return [(0.3 * duration, 25.0), (0.6 * duration, math.nan)]
