"""The planetary train of seven non-circular gears and the three arms (paper 2, §3 eqs 4–14).

Frame (as the five-bar): origin at the carrier centre O1, x forward along the row, y up; absolute
angles in rad counter-clockwise from +x. The carrier turns clockwise: φ_H = Φ0 − θ (eq 4) with
θ the carrier angle (the drive's joint angle). The sun gear is fixed (eq 5).

Reading of the paper's ambiguous parts (also in doc/design.md):

* One convention for every angle the paper attaches to the gears: pitch-curve polar angles, γ0
  and β0 are measured in the carrier's sense of rotation (clockwise), like θ itself. That is
  what eq 7 says for the sun (the sun point at polar angle θ is in mesh at carrier angle θ), and
  with it the published set plants at the lowest point near θ = 191° as the paper's Table 1
  states (at 194.5°; with γ0, β0 counter-clockwise it falls at 107°).
* Gears: sun S = ρ(θ); intermediate I = the conjugate a − ρ at polar angle ψ = Ψ(θ),
  Ψ(θ) = ∫₀^θ ρ/(a−ρ) (eqs 2, 3, 7); planet P meshes with I at the same centre distance (eq 13),
  so its curve is a − (a − ρ) = ρ: the planet is a copy of the sun. Eq 9 is read as pure rolling
  of I on P: with Θ = Ψ⁻¹ the planet's pitch point is w(θ) = Θ(Ψ(θ) + c) and the planet turns
  φ_3H = w(θ) − w(0) relative to the carrier, where c = π − γ0 is the intermediate's polar angle
  of the I–P line (the paper writes the limits from γ0, i.e. from the other end of the line).
  Eq 10's φ_30 = Θ(c) is the planet's mesh phase at θ = 0.
* Planet absolute angle (eq 8 with the phase made explicit): the planet's polar axis points at
  φ3 = φ_H − γ0 + π + w(θ), so its pitch point w sits on the line O3→O2; the arm, mounted at
  planet polar angle β0, points at α = φ3 − β0 (eq 14). The tip is D = O3 + S·e(α).
* Arm k (k = 0, 1, 2 for I, II, III) sits 2πk/3 ahead on the carrier (counter-clockwise), so its
  sun mesh point is u_k = θ − 2πk/3 and it passes every pose 120° of carrier later than arm I
  (Table 1: picking at 20°, 140°, 260°). Each arm is evaluated from its own gear mesh, not by
  shifting arm I, so the 120° symmetry is a tested property, not an assumption.
* H1 (pusher offset): the seedling pusher slides along the line through the tip at distance H1
  from O3, i.e. the arm line turned clockwise about D by δ = asin(H1/S). Its angle to the
  horizontal is the arm attitude of the picking and pushing goals.

Ψ and Θ are tabulated once per design on the interpolant's analytic pieces (Gauss–Legendre
cumulative integrals, values plus first and second derivatives in quintic Hermite form), so an
evaluation never rebuilds the spline or re-solves the closure.
"""

from __future__ import annotations

from collections.abc import Mapping
import math
from typing import TYPE_CHECKING, Generic, NamedTuple, Protocol, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from planter_ros.config import specs

from ..arrays import FloatArray, Floats
from ..errors import DesignError
from ..design_inputs import ThreeArmInputs
from .pitch_curve import (
    INTERPOLANTS, TWO_PI, PitchCurve, leggauss, solve_centre_distance, subdivide)

if TYPE_CHECKING:
    from scipy.interpolate import PPoly

ARMS = 3
ARM_PHASE = TWO_PI / ARMS
TABLE_SPLITS = 4            # 2**4 Hermite intervals per analytic piece of ρ
TABLE_GAUSS = 12            # Gauss–Legendre points per Hermite interval for Ψ


class GearTrain:
    """Sun/intermediate/planet pitch curves and the mesh maps Ψ (sun→intermediate), Θ = Ψ⁻¹."""

    def __init__(self, curve: PitchCurve, closure_method: str = 'gauss') -> None:
        self.curve = curve
        self.closure = solve_centre_distance(curve, closure_method)
        a = self.a = self.closure.a
        # nodes: the analytic pieces of ρ, each split evenly; cumulative Ψ by Gauss per interval
        nodes = subdivide(curve.pieces, 2 ** TABLE_SPLITS)
        x, w = leggauss(TABLE_GAUSS)
        lo, hi = nodes[:-1, None], nodes[1:, None]
        half = 0.5 * (hi - lo)
        q = lo + half * (x + 1.0)
        rq = curve(q)
        inc = np.sum(half * w * rq / (a - rq), axis=1)
        psi = np.r_[0.0, np.cumsum(inc)]
        psi *= TWO_PI / psi[-1]     # remove the last ulp-level closure error (residual ~1e-15)
        rho, d1 = curve(nodes), curve(nodes, 1)
        f = rho / (a - rho)                       # dΨ/dθ
        f1 = a * d1 / (a - rho) ** 2              # d²Ψ/dθ²
        self._psi = quintic_hermite(nodes, psi, f, f1)
        g = 1.0 / f                                # dΘ/dψ
        g1 = -f1 / f ** 3                          # d²Θ/dψ²
        self._theta = quintic_hermite(psi, nodes, g, g1)
        self.ratio_range = (float(f.min()), float(f.max()))

    def psi(self, u: ArrayLike, nu: int = 0) -> FloatArray:
        """Intermediate polar angle in mesh with the sun's polar angle u (any real u), or its
        nu-th derivative (nu = 1: the transmission ratio ρ/(a−ρ))."""
        u = np.asarray(u, dtype=float)
        turns = np.floor(u / TWO_PI)
        out = self._psi(u - turns * TWO_PI, nu)
        return out + turns * TWO_PI if nu == 0 else out

    def theta(self, p: ArrayLike, nu: int = 0) -> FloatArray:
        """Inverse of psi: the sun (or planet) polar angle in mesh with intermediate angle p, or
        its nu-th derivative."""
        p = np.asarray(p, dtype=float)
        turns = np.floor(p / TWO_PI)
        out = self._theta(p - turns * TWO_PI, nu)
        return out + turns * TWO_PI if nu == 0 else out

    def conjugate_curve(self, samples: int = 720) -> tuple[FloatArray, FloatArray]:
        """Intermediate pitch curve as (polar angle ψ, radius a − ρ) over one turn."""
        u = np.linspace(0.0, TWO_PI, samples + 1)
        return self.psi(u), self.a - self.curve(u)


class PitchCurves(Protocol):
    """What the goals read of the sun's pitch curve: one design's (PitchCurve) or a batch's
    (batch.BatchCurve, arrays of the batch's shape)."""

    @property
    def pieces(self) -> FloatArray: ...
    @property
    def interpolant(self) -> str: ...
    @property
    def rho_min(self) -> Floats: ...
    @property
    def rho_max(self) -> Floats: ...
    def __call__(self, theta: FloatArray, nu: int = 0, /) -> FloatArray: ...
    def length(self) -> Floats: ...


class ClosureFigures(Protocol):
    """How well the pair closes (pitch_curve.Closure, or a batch's)."""

    @property
    def residual(self) -> Floats: ...
    @property
    def method(self) -> str: ...


class MeshMaps(Protocol):
    """A gear train as the mechanism uses it: GearTrain, or batch.BatchGearTrain."""

    @property
    def a(self) -> Floats: ...
    @property
    def curve(self) -> PitchCurves: ...
    @property
    def closure(self) -> ClosureFigures: ...
    def psi(self, u: ArrayLike, nu: int = 0) -> FloatArray: ...
    def theta(self, p: ArrayLike, nu: int = 0) -> FloatArray: ...


_V = TypeVar('_V')


class Installation(NamedTuple, Generic[_V]):
    """How a three-arm's gear train is installed (SI): floats for one design, arrays (P,) for
    a batch of P (three_arm.batch.MechanismBatch)."""

    carrier_initial_angle: _V        # Φ0 (rad)
    arm_initial_angle: _V            # β0 (rad)
    arm_length: _V                   # S (m)
    pusher_offset: _V                # H1 (m), 0 ≤ H1 < S
    planet_carrier_angle: _V         # γ0 (rad)


class ThreeArmMechanism:
    """A built three-arm mechanism: gear train plus installation (SI units).

    Build once (`from_parameters`), then evaluate any number of carrier angles; all methods take
    numpy arrays of carrier angles θ (rad) and an arm index 0, 1, 2.

    The pose methods are plain numpy broadcasting over the installation values and the gear
    maps, so `three_arm.batch.MechanismBatch` (a batch of designs, values of shape (P, 1))
    inherits them unchanged; `batch_shape` is () here and (P,) there.
    """

    # one design: floats; a MechanismBatch: arrays of shape (P, 1) (its train a BatchGearTrain)
    batch_shape: tuple[int, ...] = ()
    phi0: Floats
    beta0: Floats
    arm_length: Floats
    pusher_offset: Floats
    gamma0: Floats
    delta: Floats
    a: Floats
    train: MeshMaps
    _c: Floats
    _w0: list[Floats]

    def __init__(self, curve: PitchCurve, installation: Installation[float],
                 closure_method: str = 'gauss') -> None:
        (carrier_initial_angle, arm_initial_angle, arm_length, pusher_offset,
         planet_carrier_angle) = installation
        values: dict[str, object] = installation._asdict()
        for name, value in values.items():
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise DesignError(name, value, 'a finite number')
        if not arm_length > 0:
            raise DesignError('arm_length', arm_length, '> 0 m')
        if not 0 <= pusher_offset < arm_length:
            raise DesignError('pusher_offset', pusher_offset, f'0 ≤ H1 < arm_length '
                              f'({arm_length:g} m)')
        self.phi0 = float(carrier_initial_angle)
        self.beta0 = float(arm_initial_angle)
        self.arm_length = float(arm_length)
        self.pusher_offset = float(pusher_offset)
        self.gamma0 = gamma0 = float(planet_carrier_angle)
        self.delta = math.asin(float(pusher_offset) / float(arm_length))
        self.train = train = GearTrain(curve, closure_method)
        self.a = train.a
        self._c = c = math.pi - gamma0
        self._w0 = [float(train.theta(train.psi(-k * ARM_PHASE) + c)) for k in range(ARMS)]

    @classmethod
    def from_parameters(cls, params: Mapping[str, object]) -> ThreeArmMechanism:
        """Build from a scene's parameter dict (names as in config/rice_three_arm.yaml)."""
        missing = [k for k in PARAMETER_NAMES if k not in params]
        if missing:
            raise DesignError(missing[0], 'missing', 'present in the scene (three_arm)')
        interpolant = params.get('interpolant', 'periodic_cubic')
        if not isinstance(interpolant, str):
            raise DesignError('interpolant', interpolant, ' | '.join(INTERPOLANTS))
        curve = PitchCurve(_floats(params, 'control_radii'), _floats(params, 'control_angles'),
                           interpolant)
        return cls(curve, Installation(
            carrier_initial_angle=_float(params, 'carrier_initial_angle'),
            arm_initial_angle=_float(params, 'arm_initial_angle'),
            arm_length=_float(params, 'arm_length'),
            pusher_offset=_float(params, 'pusher_offset'),
            planet_carrier_angle=_float(params, 'planet_carrier_angle')))

    # --- angles --------------------------------------------------------------------------
    def carrier_angle(self, theta: ArrayLike, arm: int = 0) -> Floats:
        """Absolute angle of the carrier line O1→O2 of the arm (eq 4 plus the arm's phase)."""
        return self.phi0 - np.asarray(theta, dtype=float) + arm * ARM_PHASE

    def intermediate_angle(self, theta: ArrayLike, arm: int = 0) -> Floats:
        """Rotation of the arm's intermediate gear relative to the carrier (clockwise > 0)."""
        u = np.asarray(theta, dtype=float) - arm * ARM_PHASE
        return self.train.psi(u) - self.train.psi(-arm * ARM_PHASE)

    def planet_mesh_angle(self, theta: ArrayLike, arm: int = 0) -> Floats:
        """w(θ): the planet's polar angle in mesh with its intermediate gear."""
        u = np.asarray(theta, dtype=float) - arm * ARM_PHASE
        return self.train.theta(self.train.psi(u) + self._c)

    def planet_relative_angle(self, theta: ArrayLike, arm: int = 0) -> Floats:
        """φ_3H: planet rotation relative to the carrier since θ = 0 (counter-clockwise > 0)."""
        return self.planet_mesh_angle(theta, arm) - self._w0[arm]

    def attitude(self, theta: ArrayLike, arm: int = 0) -> Floats:
        """Absolute angle α of the arm line O3→D (rad, counter-clockwise from +x)."""
        return self._attitude(self.carrier_angle(theta, arm), self.planet_mesh_angle(theta, arm))

    def _attitude(self, carrier: Floats, mesh: Floats) -> Floats:
        return carrier - self.gamma0 + math.pi + mesh - self.beta0

    def pusher_attitude(self, theta: ArrayLike, arm: int = 0) -> Floats:
        """Absolute angle of the pusher axis (towards the tip): α − asin(H1/S)."""
        return self.attitude(theta, arm) - self.delta

    # --- positions -----------------------------------------------------------------------
    def centres(self, theta: ArrayLike,
                arm: int = 0) -> tuple[tuple[Floats, Floats], tuple[Floats, Floats]]:
        """(O2, O3): intermediate and planet centres, each an (x, y) array pair (eqs 12, 13)."""
        ph = self.carrier_angle(theta, arm)
        o2 = (self.a * np.cos(ph), self.a * np.sin(ph))
        o3 = (o2[0] + self.a * np.cos(ph - self.gamma0), o2[1] + self.a * np.sin(ph - self.gamma0))
        return o2, o3

    def tip(self, theta: ArrayLike, arm: int = 0) -> tuple[Floats, Floats]:
        """Tip D of the arm in the frame (absolute, static machine): (x, y) in m (eq 14)."""
        ph = self.carrier_angle(theta, arm)
        return self._tip(ph, self._attitude(ph, self.planet_mesh_angle(theta, arm)))

    def _tip(self, ph: Floats, alpha: Floats) -> tuple[Floats, Floats]:
        a, s, g = self.a, self.arm_length, self.gamma0
        x = a * (np.cos(ph) + np.cos(ph - g)) + s * np.cos(alpha)
        y = a * (np.sin(ph) + np.sin(ph - g)) + s * np.sin(alpha)
        return x, y

    def tip_velocity(self, theta: ArrayLike, arm: int = 0) -> tuple[Floats, Floats]:
        """d(tip)/dθ in the frame (m/rad): the carrier turns at −1, the arm at −1 + dw/dθ with
        dw/dθ = Θ'(Ψ(u) + c)·Ψ'(u) from the tabulated gear maps."""
        ph = self.carrier_angle(theta, arm)
        u = np.asarray(theta, dtype=float) - arm * ARM_PHASE
        p = self.train.psi(u) + self._c
        w = self.train.theta(p)
        dalpha = -1.0 + self.train.theta(p, 1) * self.train.psi(u, 1)
        alpha = self._attitude(ph, w)
        a, s, g = self.a, self.arm_length, self.gamma0
        dx = a * (np.sin(ph) + np.sin(ph - g)) - s * np.sin(alpha) * dalpha
        dy = -a * (np.cos(ph) + np.cos(ph - g)) + s * np.cos(alpha) * dalpha
        return dx, dy

    def tip_relative(self, theta: ArrayLike, arm: int = 0) -> tuple[Floats, Floats]:
        """Tip in the carrier frame (coordinates that turn with the carrier, equal at θ = 0)."""
        theta = np.asarray(theta, dtype=float)
        x, y = self.tip(theta, arm)
        c, s = np.cos(theta), np.sin(theta)
        return c * x - s * y, s * x + c * y

    def tip_ground(self, theta: ArrayLike, plant_spacing: float,
                   arm: int = 0) -> tuple[Floats, Floats]:
        """Tip relative to the ground while the machine advances 3·d per carrier turn."""
        x, y = self.tip(theta, arm)
        return x + (ARMS * plant_spacing / TWO_PI) * np.asarray(theta, dtype=float), y

    def cycle(self, samples: int = 360) -> tuple[FloatArray, FloatArray, FloatArray]:
        """One carrier revolution of all three arms: θ (n,), tips (..., 3, 2, n), attitudes
        (..., 3, n), the leading axes being batch_shape."""
        theta = np.linspace(0.0, TWO_PI, samples, endpoint=False)
        # all arms in one evaluation of the gear maps: arm k's angles follow arm I's
        phase = (np.arange(ARMS) * ARM_PHASE)[:, None]
        u = (theta - phase).ravel()                        # each arm's sun mesh angle
        ph = self.phi0 + (phase - theta).ravel()           # carrier_angle of each arm
        alpha = self._attitude(ph, self.train.theta(self.train.psi(u) + self._c))
        x, y = self._tip(ph, alpha)
        shape = self.batch_shape + (ARMS, samples)
        return theta, np.stack([np.reshape(x, shape), np.reshape(y, shape)], axis=-2), \
            np.reshape(alpha, shape)


def quintic_hermite(x: FloatArray, y: FloatArray, dy: FloatArray, d2y: FloatArray) -> PPoly:
    """Piecewise quintic through values, slopes and second derivatives (scipy PPoly, C¹…C²).

    The vectorised twin of scipy's BPoly.from_derivatives for this one case, which builds a
    polynomial per interval in Python and would dominate the build time.
    """
    # lazy: scipy.interpolate costs 440 ms: only a built three-arm loads it, never an import
    # of kinematics (test_skip_what_a_scene_does_not_need)
    from scipy.interpolate import PPoly
    return PPoly(np.moveaxis(quintic_coefficients(x, y, dy, d2y), -1, 0), x, extrapolate=True)


def quintic_coefficients(x: FloatArray, y: FloatArray, dy: FloatArray,
                         d2y: FloatArray) -> FloatArray:
    """Coefficients (..., intervals, 6) of the quintic Hermite pieces, highest power first, in
    powers of (x − x_i) (scipy PPoly's order); leading axes are a batch of curves."""
    h = np.diff(x, axis=-1)
    dy0, dy1 = dy[..., :-1] * h, dy[..., 1:] * h
    s0, s1 = d2y[..., :-1] * h * h, d2y[..., 1:] * h * h
    dd = y[..., 1:] - y[..., :-1]
    c3 = 10.0 * dd - 6.0 * dy0 - 4.0 * dy1 - 0.5 * (3.0 * s0 - s1)
    c4 = -15.0 * dd + 8.0 * dy0 + 7.0 * dy1 + 0.5 * (3.0 * s0 - 2.0 * s1)
    c5 = 6.0 * dd - 3.0 * (dy0 + dy1) + 0.5 * (s1 - s0)
    return np.stack([c5 / h ** 5, c4 / h ** 4, c3 / h ** 3, 0.5 * s0 / h ** 2, dy0 / h,
                     y[..., :-1]], axis=-1)


# the scene values the model is built from, in the constructor's order after the curve
PARAMETER_NAMES = tuple(spec.name for spec in specs(ThreeArmInputs) if spec.required)


def _float(params: Mapping[str, object], key: str) -> float:
    value = params[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise DesignError(key, value, 'a number (SI units)')
    return float(value)


def _floats(params: Mapping[str, object], key: str) -> FloatArray:
    value = params[key]
    if not isinstance(value, (list, tuple, np.ndarray)) or \
            any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
        raise DesignError(key, value, 'a list of numbers (SI units)')
    return np.asarray(value, dtype=float)
