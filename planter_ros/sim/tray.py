"""The simulated seedling tray and the row's cup sensor: one place for `planter simulate`'s runs
and `planter demo`'s live machine.

A tray's cells reach the row's cup one per planting cycle: a cell is empty with `empty_rate`,
holds two seedlings with `double_rate`, else one (`Tray`, a seeded draw). The cup sensor (an
optical cup or drop-tube sensor: prediction.seedlings) reads each cup half a planting cycle
before the planting angle (`sense_angle`), one reading per cycle; `SensedCycles` finds, in a
row's measured shaft angle as it comes, the cycles whose cup has just passed the sensor. Pure
numpy, no ROS.
"""

import math

import numpy as np

TWO_PI = 2.0 * math.pi


class Tray:
    """What each cycle's cup holds: 0 (an empty cell) with `empty_rate`, 2 (a double) with
    `double_rate` (of what the empty cells leave), else 1; from the generator `rng` (the same
    seed, the same tray)."""

    def __init__(self, empty_rate, double_rate, rng):
        self.empty_rate, self.double_rate, self.rng = float(empty_rate), float(double_rate), rng

    def cells(self, n):
        """The next `n` cells' seedling counts (int array)."""
        draw = self.rng.random(int(n))
        return np.where(draw < self.empty_rate, 0,
                        np.where(draw < self.empty_rate + self.double_rate, 2, 1))


def sense_angle(model, k):
    """The shaft angle (rad) at which cycle k's cup passes the sensor: half a planting cycle
    before planting angle k of the planting model (prediction.planting_model_from_design)."""
    return model.planting_phase + (np.asarray(k, dtype=float) - 0.5) * TWO_PI \
        / model.plants_per_revolution


def cycles_between(model, theta0, theta1):
    """The cycles k whose sense angle lies in (theta0, theta1] (int array)."""
    n = model.plants_per_revolution
    # a candidate either side (the floor of a rounded product may land one off a boundary):
    # the angles themselves decide
    first = math.floor((theta0 - model.planting_phase) * n / TWO_PI + 0.5)
    last = math.floor((theta1 - model.planting_phase) * n / TWO_PI + 0.5) + 1
    ks = np.arange(first, last + 1)
    angles = sense_angle(model, ks)
    return ks[(angles > theta0) & (angles <= theta1)]


class SensedCycles:
    """A row's cup sensor fed the measured shaft angle sample by sample (the live demo): `add`
    returns the cycles whose cup passed the sensor since the previous sample, with each cup's
    count from the row's tray; the first sample reads a cup whose sense angle it is. The running
    maximum of the angle is used (a shaft that turns back does not read a cup twice)."""

    def __init__(self, model, tray):
        self.model, self.tray = model, tray
        self._theta = None

    def add(self, theta):
        """[(cycle k, count)] of the cups read between the previous angle and `theta` (rad)."""
        theta = float(theta)
        if not math.isfinite(theta) or (self._theta is not None and theta <= self._theta):
            return []
        # the first sample: a cup right at the starting angle is read too (as simulate reads
        # the cycle whose sense angle is the run's first angle)
        start = math.nextafter(theta, -math.inf) if self._theta is None else self._theta
        ks = cycles_between(self.model, start, theta)
        self._theta = theta
        return list(zip(ks.tolist(), self.tray.cells(ks.size).tolist()))


def add_tray_arguments(parser, options, defaults, spec_option):
    """The command line's --empty-rate and --double-rate, checked as the `options` dataclass's
    settings `empty_rate` and `double_rate` (`spec_option`: the command line's checker);
    `defaults`: (empty, double)."""
    for name, default in zip(('empty', 'double'), defaults):
        parser.add_argument(f'--{name}-rate', metavar='R', default=default, help=f"share of "
                            f"the tray's {name} cells, 0..1 (default {default:g})",
                            type=spec_option(options, f'{name}_rate', f'--{name}-rate'))
