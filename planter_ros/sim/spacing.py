"""Where the plants landed, from the mechanism angle and the true travelled distance, and how
far that is from the grid: the reference figures of the simulations and the demo."""

from collections.abc import Iterable
from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import ArrayLike

from planter_ros.kinematics.arrays import FloatArray


def plant_positions(angle: ArrayLike, distance: ArrayLike, pitch: float,
                    release: float = math.pi) -> FloatArray:
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
    positions: FloatArray = distance[idx - 1] + frac * (distance[idx] - distance[idx - 1])
    return positions


def error_figures(errors: ArrayLike) -> tuple[float | None, float | None, float | None,
                                              float | None]:
    """(mean, sigma, max |error|, RMS) of spacing errors (m; non-finite ones left out; None
    each when there is none). The definitions of replay's summary (signed mean, population
    standard deviation, largest magnitude), so the demo's figures and replay's differ only in
    where the plants are placed; RMS = (mean² + sigma²)^½ beside them (the demo's verdict)."""
    values = np.asarray(errors, dtype=float)
    values = values[np.isfinite(values)]
    if not values.size:
        return None, None, None, None
    return (float(values.mean()), float(values.std()), float(np.abs(values).max()),
            float(np.sqrt(np.mean(values ** 2))))


@dataclass(frozen=True)
class SpacingStats:
    plants: int
    mean_abs_spacing_error: float    # m, mean |gap − d| between consecutive plants
    max_abs_spacing_error: float     # m
    max_abs_drift: float             # m, max |position − (first + k·d)|: accumulated error
    final_drift: float               # m, drift of the last plant

    def as_dict(self) -> dict[str, float]:
        return dict(self.__dict__)


def spacing_stats(positions: ArrayLike, spacing: ArrayLike) -> SpacingStats:
    """Spacing error and drift of plants at `positions` (m) against `spacing` d (m): one
    number, or one per gap (the design in force when each gap's second plant was set; the
    grid then goes on at each gap's own d)."""
    at = np.asarray(positions, dtype=float)
    if at.size < 2:
        return SpacingStats(int(at.size), 0.0, 0.0, 0.0, 0.0)
    d = np.broadcast_to(np.asarray(spacing, dtype=float), (at.size - 1,))
    gaps = np.diff(at) - d
    drift = at - at[0] - np.concatenate(([0.0], np.cumsum(d)))
    return SpacingStats(int(at.size), float(np.mean(np.abs(gaps))),
                        float(np.max(np.abs(gaps))), float(np.max(np.abs(drift))),
                        float(drift[-1]))


def spacing_in_force(times: ArrayLike, spacing: float,
                     changes: Iterable[tuple[float, float]]) -> FloatArray:
    """d (m) of each gap between plants set at `times` (s, increasing): `spacing` at first;
    each change (t s, d) is in force from the first plant set after t (that plant's own gap
    is still the old d's), as the sync law and the monitor apply a new design."""
    instants = np.asarray(times, dtype=float)
    d = np.full(max(instants.size - 1, 0), float(spacing))
    for t, new in changes:
        after = np.nonzero(instants > t)[0]
        if after.size:
            d[after[0]:] = new          # gaps ending at plants after the change's first
    return d
