"""The mechanism behind a simulated drive: a gear (`gear_ratio` motor turns per mechanism turn),
a motor possibly wired the other way round (`motor_reversed`), a bottom (the planting tip
lowest) at an unknown `mechanical_offset` from the encoder's zero, and a proximity switch at
the bottom wired as the drive's home switch (60FDh bit 2; ideal, or with the delay, hysteresis
and jitter of a real one: `switch`). Optionally the instants the
mechanism truly passes its bottom forwards (`bottom_times`: the truth a test measures the
machine's own account of its plants against). Pure arithmetic on motor counts."""
from __future__ import annotations

import math

from .spec import SimSpec
from .switch import HomeSwitch

__all__ = ['Mechanism', 'simulated_mechanism', 'wrap_angle']

TWO_PI = 2.0 * math.pi


def wrap_angle(angle: float) -> float:
    """`angle` wrapped to [-pi, pi)."""
    return (angle + math.pi) % TWO_PI - math.pi


class Mechanism:
    """The mechanism of one simulated drive (module doc)."""

    def __init__(self, spec: SimSpec) -> None:
        self.counts_per_rev = spec.counts_per_motor_rev
        self.gear_ratio = float(spec.gear_ratio)
        self.motor_reversed = bool(spec.motor_reversed)
        self.offset = float(spec.mechanical_offset)
        self.switch_width = float(spec.home_switch_width)
        self.switch = HomeSwitch(spec.home_switch_width, spec.home_switch_hysteresis,
                                 spec.home_switch_delay, spec.home_switch_jitter, spec.seed)
        self._now = 0.0           # the motor time last moved to (s)
        self.record_bottom = bool(spec.record_bottom)
        #: monotonic s at which the mechanism passed its bottom forwards (record_bottom)
        self.bottom_times: list[float] = []

    def angle(self, counts: float) -> float:
        """rad, the mechanism's angle from its bottom (forward +) at motor `counts`."""
        turns = counts / (self.counts_per_rev * self.gear_ratio)
        wiring = -1.0 if self.motor_reversed else 1.0
        return wiring * TWO_PI * turns - self.offset

    def switch_active(self, counts: float) -> bool:
        """The home switch input as the drive reads it with the motor at `counts` (now)."""
        if self.switch.ideal:
            return self.switch.ideal_active(self.angle(counts))
        self.switch.sense(self.angle(counts), self._now)
        return self.switch.read(self._now)

    def note_motion(self, after: float, now: float) -> None:
        """The motor moved to `after` counts at motor time `now` (each sub-step): the switch
        senses it (a real switch's changes are timed on the motor's clock)."""
        self._now = now
        if not self.switch.ideal:
            self.switch.sense(self.angle(after), now)

    def note_bottom(self, before: float, after: float, dt: float, now: float) -> None:
        """The bottom passed forwards in a sub-step from `before` to `after` counts that ended
        at `now`: its instant, interpolated."""
        if not self.record_bottom:
            return
        a0, a1 = self.angle(before) / TWO_PI, self.angle(after) / TWO_PI
        if a1 > a0 and math.floor(a1) > math.floor(a0):
            share = (a1 - math.floor(a1)) / (a1 - a0)
            self.bottom_times.append(now - share * dt)


def simulated_mechanism(seed: int, node_id: int, power_up: int = 0) -> tuple[float, bool]:
    """(mechanical offset rad, motor reversed) of a simulated row: the wiring fixed by `seed`
    and the node id (the machine's), the offset between the encoder's zero and the bottom by
    the power-up too (an incremental encoder counts from wherever the motor was at power-up):
    commissioning runs power-up 0, a later start another, and the homing must find the same
    bottom."""
    # lazy: numpy costs 150 ms (python -X importtime) and the drives' own process
    # (simdrive.process) never draws a mechanism: only the machine's side does
    import numpy as np
    wiring = np.random.default_rng([seed, node_id])
    offset = np.random.default_rng([seed, node_id, power_up])
    return float(offset.uniform(0.0, TWO_PI)), bool(wiring.random() < 0.5)
