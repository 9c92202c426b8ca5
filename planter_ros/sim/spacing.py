"""Where the plants landed, from the mechanism angle and the true travelled distance, and how
far that is from the grid: the reference figures of the simulations and the demo."""

from dataclasses import dataclass
import math

import numpy as np


def plant_positions(angle, distance, pitch, release=math.pi):
    """Travelled distance (m) at each instant the mechanism angle passes release + k·pitch.

    `angle` and `distance` are samples at the same instants; crossings are interpolated
    linearly. Only forward crossings count (the command is never negative).
    """
    angle = np.asarray(angle, dtype=float)
    distance = np.asarray(distance, dtype=float)
    k = np.floor((angle - release) / pitch)
    idx = np.flatnonzero(np.diff(k) > 0) + 1
    if idx.size == 0:
        return np.empty(0)
    crossing = (k[idx]) * pitch + release
    a0, a1 = angle[idx - 1], angle[idx]
    frac = np.where(a1 > a0, (crossing - a0) / np.where(a1 > a0, a1 - a0, 1.0), 1.0)
    return distance[idx - 1] + frac * (distance[idx] - distance[idx - 1])


@dataclass(frozen=True)
class SpacingStats:
    plants: int
    mean_abs_spacing_error: float    # m, mean |gap − d| between consecutive plants
    max_abs_spacing_error: float     # m
    max_abs_drift: float             # m, max |position − (first + k·d)|: accumulated error
    final_drift: float               # m, drift of the last plant

    def as_dict(self):
        return dict(self.__dict__)


def spacing_stats(positions, spacing):
    positions = np.asarray(positions, dtype=float)
    if positions.size < 2:
        return SpacingStats(int(positions.size), 0.0, 0.0, 0.0, 0.0)
    gaps = np.diff(positions) - spacing
    drift = positions - positions[0] - spacing * np.arange(positions.size)
    return SpacingStats(int(positions.size), float(np.mean(np.abs(gaps))),
                        float(np.max(np.abs(gaps))), float(np.max(np.abs(drift))),
                        float(drift[-1]))
