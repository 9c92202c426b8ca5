"""Where and how a planting mechanism plants: the nozzle tip's path through the soil around each
planting instant, as the plant prediction (planter_ros.prediction), the sync law's section stops
(where the mechanism plants on its shaft) and the electronic cam (planter_ros.cam) use it.

A mechanism plants n times per revolution, at the shaft angles θ_k = planting_phase + 2πk/n.
For an advance v/ω (m of ground per rad of shaft) it gives:

* the tip sweep: the nozzle tip's swept horizontal extent below the soil line at depth D
  (five-bar: closed form `five_bar.hole_geometry`; any other path: sampled);
* the tilt: the seedling's root ball is released at the bottom of the path; while the nozzle
  climbs back to the surface (shaft angle ψ_exit) it moves along the row relative to the soil
  by (v/ω - A_r)·ψ_exit more than the synchronous path does (A_r, `release_advance`: the
  advance with zero horizontal nozzle speed at release; five-bar A_r = l2 - l1). The stem,
  held at the surface, is dragged by that slip Δx while the root ball stays put: tilt =
  atan2(Δx, D) from vertical, positive = top leaning forward (direction of travel). Zero at
  perfect sync; dragging (λ < 1) leans the plant forward, overspeed (λ > 1) backward. The
  assumptions are listed in doc/monitor_recording.md.

`sync_advance` A0 is the advance at which the mechanism plants at its spacing (λ = A0·ω/v = 1).
Pure numpy/scipy, no ROS.
"""

from abc import ABC, abstractmethod
from collections.abc import Sequence
import math

import numpy as np
from numpy.typing import ArrayLike

from planter_ros.config import ConfigError, coerce, spec_of

from .arrays import FloatArray, Floats
from .design_inputs import DesignInputs
from .errors import DesignError
from .five_bar import depth_angle, hole_geometry, static_trajectory, static_x

__all__ = ['Planting', 'FiveBarPlanting', 'PathPlanting']

TWO_PI = 2.0 * math.pi


class Planting(ABC):
    """What every planting geometry has: `plants_per_revolution`, `planting_phase` (rad),
    `depth` and `spacing` (m), `nozzle_width` (m, along the row), `entry_angle` and
    `exit_angle` (rad of shaft from the surface to the planting instant and back),
    `sync_advance` and `release_advance` (m/rad); `tip_sweep(advance)` and `tip_path(phi)`."""

    plants_per_revolution: int
    planting_phase: float
    depth: float
    spacing: float
    nozzle_width: float
    entry_angle: float
    exit_angle: float
    sync_advance: float
    release_advance: float

    @abstractmethod
    def tip_sweep(self, advance: ArrayLike) -> Floats:
        """The tip's swept extent (m) below the soil for advance v/ω (m/rad, array)."""

    @abstractmethod
    def tip_path(self, phi: ArrayLike) -> tuple[Floats, Floats]:
        """The tip in the mechanism frame relative to its planting point (x forward, y up; m)
        at shaft angles `phi` (rad) from the planting instant."""

    @abstractmethod
    def tip_x(self, phi: ArrayLike) -> Floats:
        """`tip_path(phi)`'s x alone (m): what the measured arcs need."""

    def tilt(self, advance: ArrayLike) -> Floats:
        """The stem's tilt from vertical (rad, + = top leaning forward) for advance v/ω (m/rad,
        array): the slip of the exit climb against the depth (module doc)."""
        slip = (np.asarray(advance, dtype=float) - self.release_advance) * self.exit_angle
        return np.arctan2(slip, self.depth)


class FiveBarPlanting(Planting):
    """The geared five-bar's planting geometry (paper 1), closed form: one plant per revolution
    at θ ≡ π (the bottom of the path, θ = 0 at the top)."""

    plants_per_revolution = 1

    def __init__(self, l1: float, l2: float, depth: float, spacing: float,
                 planting_phase: float = math.pi, nozzle_width: float = 0.0) -> None:
        for name, value in (('l1', l1), ('l2', l2), ('planting_depth', depth),
                            ('plant_spacing', spacing)):
            _require_positive(name, value)
        self.nozzle_width = _nozzle_width(nozzle_width)
        if not l2 > l1:
            raise DesignError('l2', l2, f'> l1 = {l1:.6g} m', 'the nozzle must loop')
        if not depth < 2.0 * (l1 + l2):
            raise DesignError('planting_depth', depth, f'< 2(l1 + l2) = {2 * (l1 + l2):.6g} m')
        self.l1, self.l2 = float(l1), float(l2)
        self.depth, self.spacing = float(depth), float(spacing)
        self.planting_phase = float(planting_phase)
        # nozzle tip speed in the frame at the bottom is (l2 - l1)·ω backwards
        self.sync_advance = self.l2 - self.l1
        self.release_advance = self.sync_advance
        self.exit_angle = depth_angle(self.depth, self.l1 + self.l2)
        self.entry_angle = self.exit_angle          # the path is symmetric about the bottom

    def tip_sweep(self, advance: ArrayLike) -> Floats:
        """The tip's swept extent (m) below the soil for advance v/ω (m/rad, array)."""
        advance = np.asarray(advance, dtype=float)
        return np.asarray(hole_geometry(self.l1, self.l2, self.depth, advance).width)

    def tip_path(self, phi: ArrayLike) -> tuple[Floats, Floats]:
        """The tip in the mechanism frame relative to its planting point (x forward, y up; m)
        at shaft angles `phi` (rad) from the planting instant."""
        _, y = static_trajectory(self.l1, self.l2, math.pi + np.asarray(phi, dtype=float))
        return self.tip_x(phi), y + (self.l1 + self.l2)

    def tip_x(self, phi: ArrayLike) -> Floats:
        return static_x(self.l1, self.l2, math.pi + np.asarray(phi, dtype=float))


class PathPlanting(Planting):
    """Any mechanism given by one nozzle tip's closed path in the mechanism frame (the three-arm
    through its tip trajectory): x forward, y up, as functions of the shaft (carrier) angle over
    one revolution; n plants per revolution, each arm the same path shifted by 2π/n.

    The samples are joined by a periodic cubic spline; the planting instant is the lowest point
    (or `planting_phase` if given); the hole is the tip's swept extent in the soil frame between
    the surface crossings around it, taken on `ARC_SAMPLES` points of that arc.
    """

    ARC_SAMPLES = 2048

    def __init__(self, tip_path: tuple[Sequence[float] | FloatArray, Sequence[float] | FloatArray,
                                       Sequence[float] | FloatArray],
                 plants_per_revolution: int, depth: float, spacing: float,
                 planting_phase: float | None = None, nozzle_width: float = 0.0) -> None:
        """`tip_path`: (shaft angle rad, x m, y m) samples of one tip over one revolution."""
        # lazy: scipy.interpolate costs 440 ms, scipy.optimize 300 ms: loaded when a planting
        # arc is built, never by importing kinematics (test_skip_what_a_scene_does_not_need)
        from scipy.interpolate import CubicSpline
        from scipy.optimize import brentq, minimize_scalar  # lazy: as the line above

        _require_positive('planting_depth', depth)
        _require_positive('plant_spacing', spacing)
        self.nozzle_width = _nozzle_width(nozzle_width)
        n = int(plants_per_revolution)
        if n < 1 or n != plants_per_revolution:
            raise DesignError('plants_per_revolution', plants_per_revolution, 'integer >= 1')
        angle, x, y = (np.asarray(a, dtype=float) for a in tip_path)
        if not (angle.ndim == 1 and angle.shape == x.shape == y.shape and angle.size >= 8):
            raise DesignError('tip_path', f'{angle.size} samples', '>= 8 samples of equal length '
                              'angle, x, y')
        if not (np.all(np.isfinite(angle)) and np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
            raise DesignError('tip_path', 'non-finite samples', 'finite angle, x, y')
        if not (np.all(np.diff(angle) > 0) and angle[-1] - angle[0] < TWO_PI):
            raise DesignError('tip_path', 'angle samples', 'increasing, spanning < 2π rad')
        ext = np.append(angle, angle[0] + TWO_PI)
        self._x = CubicSpline(ext, np.append(x, x[0]), bc_type='periodic')
        self._y = CubicSpline(ext, np.append(y, y[0]), bc_type='periodic')
        self._angle0 = angle[0]
        self.plants_per_revolution = n
        self.depth, self.spacing = float(depth), float(spacing)

        if planting_phase is None:
            grid = np.linspace(angle[0], angle[0] + TWO_PI, 4096, endpoint=False)
            i = int(np.argmin(self._y(grid)))
            step = TWO_PI / grid.size
            def height(phi: float) -> float:
                return float(self._y(phi))
            planting_phase = minimize_scalar(height, bracket=None,
                                             bounds=(grid[i] - step, grid[i] + step),
                                             method='bounded', options={'xatol': 1e-12}).x
        phi_p = float(planting_phase)
        self.planting_phase = phi_p
        y_soil = float(self._y(phi_p)) + self.depth
        if float(np.max(self._y(np.linspace(phi_p, phi_p + TWO_PI, 4096)))) <= y_soil:
            raise DesignError('planting_depth', depth, '< the height of the tip path',
                              'the nozzle never leaves the soil')

        def below(phi: float) -> float:
            return float(self._y(phi)) - y_soil

        def crossing(direction: float) -> float:
            # first surface crossing from the planting point in `direction`
            grid = phi_p + direction * np.linspace(0.0, math.pi, 4097)[1:]
            above = np.nonzero(self._y(grid) > y_soil)[0]
            if above.size == 0:
                raise DesignError('planting_depth', depth, '< the tip path height within half a '
                                  'revolution of the planting point')
            j = above[0]
            lo = phi_p if j == 0 else grid[j - 1]
            return brentq(below, min(lo, grid[j]), max(lo, grid[j]), xtol=1e-14)

        phi_in, phi_out = crossing(-1.0), crossing(+1.0)
        self.exit_angle = phi_out - phi_p
        self.entry_angle = phi_p - phi_in
        self._arc = np.linspace(phi_in, phi_out, self.ARC_SAMPLES) - phi_p
        self._arc_x = self._x(self._arc + phi_p)
        # frame velocity of the tip along x at release: zero slip when v/ω = -dx/dφ
        self.release_advance = -float(self._x(phi_p, 1))
        self.sync_advance = n * self.spacing / TWO_PI

    def tip_sweep(self, advance: ArrayLike) -> Floats:
        advance = np.asarray(advance, dtype=float)
        xs = self._arc_x + advance[..., None] * self._arc
        sweep: FloatArray = xs.max(axis=-1) - xs.min(axis=-1)
        return sweep

    def tip_path(self, phi: ArrayLike) -> tuple[Floats, Floats]:
        """The tip in the mechanism frame relative to its planting point (x forward, y up; m)
        at carrier angles `phi` (rad) from the planting instant."""
        angle = self.planting_phase + np.asarray(phi, dtype=float)
        return self.tip_x(phi), self._y(angle) - float(self._y(self.planting_phase))

    def tip_x(self, phi: ArrayLike) -> Floats:
        angle = self.planting_phase + np.asarray(phi, dtype=float)
        return self._x(angle) - float(self._x(self.planting_phase))


def _require_positive(name: str, value: float) -> None:
    try:
        ok = math.isfinite(float(value)) and float(value) > 0
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise DesignError(name, value, 'finite and > 0 m')


def _nozzle_width(value: object) -> float:
    """The nozzle width checked against the scene's range (DesignError, one line)."""

    try:
        width: float = coerce(spec_of(DesignInputs, 'nozzle_width'), value)
        return width
    except ConfigError as exc:
        raise DesignError.from_message(str(exc)) from None
