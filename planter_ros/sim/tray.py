"""The simulated seedling tray and the row's cup sensor: one place for `planter simulate`'s runs
and `planter demo`'s live machine.

A tray's cells reach the row's cup one per planting cycle: a cell is empty with `empty_rate`,
holds two seedlings with `double_rate`, else one (`Tray`, a seeded draw). The cup sensor (an
optical cup or drop-tube sensor: prediction.seedlings) reads each cup half a planting cycle
before the planting angle (`sense_angle`), one reading per cycle; `SensedCycles` finds, in a
row's measured shaft angle as it comes, the cycles whose cup has just passed the sensor. Pure
numpy, no ROS.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from dataclasses import dataclass
import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from planter_ros.kinematics.planting import Planting

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class TrayShares:
    """A simulated tray: the share of its cells that are empty (the cup sensor reads 0) and of
    those holding two seedlings (it reads 2)."""

    empty_rate: float = 0.0
    double_rate: float = 0.0


FULL_TRAY = TrayShares()        # every cell holds one seedling


class Tray:
    """What each cycle's cup holds: 0 (an empty cell) with `empty_rate`, 2 (a double) with
    `double_rate` (of what the empty cells leave), else 1; from the generator `rng` (the same
    seed, the same tray)."""

    def __init__(self, empty_rate: float, double_rate: float, rng: np.random.Generator) -> None:
        self.empty_rate, self.double_rate, self.rng = float(empty_rate), float(double_rate), rng

    def cells(self, n: int) -> NDArray[np.int_]:
        """The next `n` cells' seedling counts (int array)."""
        draw = self.rng.random(int(n))
        counts: NDArray[np.int_] = np.where(draw < self.empty_rate, 0,
                        np.where(draw < self.empty_rate + self.double_rate, 2, 1))
        return counts


def sense_angle(model: Planting, k: ArrayLike) -> NDArray[np.float64]:
    """The shaft angle (rad) at which cycle k's cup passes the sensor: half a planting cycle
    before planting angle k of the planting model (prediction.planting_model_from_design)."""
    angle: NDArray[np.float64] = model.planting_phase + (np.asarray(k, dtype=float) - 0.5) \
        * TWO_PI / model.plants_per_revolution
    return angle


def cycles_between(model: Planting, theta0: float, theta1: float) -> NDArray[np.int_]:
    """The cycles k whose sense angle lies in (theta0, theta1] (int array)."""
    n = model.plants_per_revolution
    # a candidate either side (the floor of a rounded product may land one off a boundary):
    # the angles themselves decide
    first = math.floor((theta0 - model.planting_phase) * n / TWO_PI + 0.5)
    last = math.floor((theta1 - model.planting_phase) * n / TWO_PI + 0.5) + 1
    ks = np.arange(first, last + 1)
    angles = sense_angle(model, ks)
    cycles: NDArray[np.int_] = ks[(angles > theta0) & (angles <= theta1)]
    return cycles


class SensedCycles:
    """A row's cup sensor fed the measured shaft angle sample by sample (the live demo): `add`
    returns the cycles whose cup passed the sensor since the previous sample, with each cup's
    count from the row's tray; the first sample reads a cup whose sense angle it is. The running
    maximum of the angle is used (a shaft that turns back does not read a cup twice)."""

    def __init__(self, model: Planting, tray: Tray) -> None:
        self.model, self.tray = model, tray
        self._theta: float | None = None         # the running maximum (None: no sample yet)

    def add(self, theta: float) -> list[tuple[int, int]]:
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


def add_tray_arguments(parser: argparse.ArgumentParser, options: type,
                       defaults: Sequence[float],
                       spec_option: Callable[[type, str, str], Callable[[str], Any]]) -> None:
    """The command line's --empty-rate and --double-rate, checked as the `options` dataclass's
    settings `empty_rate` and `double_rate` (`spec_option`: the command line's checker);
    `defaults`: (empty, double)."""
    for name, default in zip(('empty', 'double'), defaults):
        parser.add_argument(f'--{name}-rate', metavar='R', default=default, help=f"share of "
                            f"the tray's {name} cells, 0..1 (default {default:g})",
                            type=spec_option(options, f'{name}_rate', f'--{name}-rate'))
