"""Many three-arm designs at once: spline, closure, gear maps and cycle for a batch (numpy).

The optimiser scores a whole differential-evolution population per call. Its designs share the
control angles and the interpolant, and differ in the radii and the five installation values.
For an interpolant that is linear in the radii (pitch_curve's `linear`: all but the Cartesian
B-spline) every design's ρ, ρ', ρ'' on a common set of angles is one matrix product with the
basis (the interpolant of each unit radius vector), so the whole batch shares its nodes:

* closure: Σ w ρ/(a−ρ) = 2π on the gear-map quadrature nodes (Gauss–Legendre on the Hermite
  intervals, each analytic piece split 2**4 times as in GearTrain; `GAUSS_POINTS` per interval),
  solved for every design at once by Newton steps on 1/mean − 1 (nearly linear in a) kept
  inside a bracket;
* gear maps Ψ and Θ = Ψ⁻¹ as quintic Hermite pieces, as GearTrain, one row per design;
* the pose methods and the eight goals are those of ThreeArmMechanism and goals.py (numpy
  broadcasting over a leading batch axis), not a second copy.

What differs from one design built alone: ρ's extremes come from the samples (goal 8's 2048
per turn, the knots and the quadrature nodes) rather than from the roots of ρ', and the closure
uses one fixed rule rather than the adaptive one — differences far below the goals' tolerances
(tested against ThreeArmMechanism), and the optimiser re-checks its result with the
single-design path.
A design the single-design path would refuse (a curve dipping to ρ ≤ 0, H1 ≥ S) is marked in
`valid` and computed on a harmless stand-in so the batch has no NaN.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..arrays import FloatArray
from ..errors import DesignError
from .gear_train import (ARM_PHASE, ARMS, TABLE_SPLITS, Installation, ThreeArmMechanism,
                         quintic_coefficients)
from .goals import MODULE_SAMPLES
from .pitch_curve import (INTERPOLANTS, LENGTH_SPLITS, TWO_PI, _check_control_points,
                          analytic_pieces, gauss_nodes, subdivide)

# Gauss–Legendre points per Hermite interval for the closure and Ψ: GearTrain's 12 where the
# intervals are few and wide (trigonometric: one analytic piece), down to 4 where there are
# enough intervals (a spline's 12 pieces × 16) for 768 nodes per turn
GAUSS_POINTS = (4, 12)
GAUSS_NODES_PER_TURN = 768
_NEWTON_STEPS = 60


class CurveBasis:
    """The pitch curves of every design with these control angles, as a linear map of radii.

    `matrix(u, nu)` (n, len(u)) gives ρ^(nu)(u) = radii @ matrix; matrices are cached per set of
    angles u, so a run of many batches evaluates the basis once.
    """

    def __init__(self, angles: ArrayLike, interpolant: str = 'periodic_cubic') -> None:
        if interpolant not in INTERPOLANTS:
            raise DesignError('interpolant', interpolant, ' | '.join(INTERPOLANTS))
        cls = INTERPOLANTS[interpolant]
        if not cls.linear:
            linear = [name for name, c in INTERPOLANTS.items() if c.linear]
            raise DesignError('interpolant', interpolant, ' | '.join(linear),
                              'scoring many designs as one batch needs a curve linear in the '
                              'radii')
        n = len(np.ravel(angles))
        _, self.angles = _check_control_points(np.ones(n), angles)
        self.interpolant = interpolant
        self._unit = [cls(row, self.angles) for row in np.eye(n)]
        self.pieces = analytic_pieces(self._unit[0].breakpoints)
        self._cache: dict[_CacheKey, FloatArray] = {}
        self.table_nodes = subdivide(self.pieces, 2 ** TABLE_SPLITS)
        intervals = len(self.table_nodes) - 1
        points = int(np.clip(math.ceil(GAUSS_NODES_PER_TURN / intervals), *GAUSS_POINTS))
        q, w = gauss_nodes(self.pieces, TABLE_SPLITS, points)
        self.quad_nodes = q.reshape(-1, points)
        self.quad_weights = w.reshape(-1, points)
        self.length_nodes, self.length_weights = gauss_nodes(self.pieces, LENGTH_SPLITS)
        # goals.gear_module_limit's samples: ρ's extremes come from them and the nodes
        self.range_nodes = np.r_[np.linspace(0.0, TWO_PI, MODULE_SAMPLES, endpoint=False),
                                 self.pieces]

    def matrix(self, u: ArrayLike, nu: int = 0) -> FloatArray:
        """(n, len(u)): row i is the i-th unit curve's nu-th derivative at u."""
        u = np.ascontiguousarray(u, dtype=float)
        key = (u.shape, u.tobytes(), nu)
        out = self._cache.get(key)
        if out is None:
            out = np.stack([f(u, nu) for f in self._unit])
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = out
        return out


# a cached evaluation: (shape, bytes of the angles u, derivative order)
_CacheKey = tuple[tuple[int, ...], bytes, int]


class BatchCurve:
    """The pitch curves of a batch: ρ^(nu) at shared angles u -> (P, len(u))."""

    def __init__(self, basis: CurveBasis, radii: FloatArray) -> None:
        self.basis = basis
        self.radii = radii
        self.interpolant = basis.interpolant
        self.pieces = basis.pieces
        self._memo: dict[_CacheKey, FloatArray] = {}
        first, *others = (self(nodes) for nodes in
                          (basis.range_nodes, basis.quad_nodes.ravel(), basis.table_nodes))
        lo: FloatArray = first.min(axis=-1)
        hi: FloatArray = first.max(axis=-1)
        for rho in others:
            lo = np.minimum(lo, rho.min(axis=-1))
            hi = np.maximum(hi, rho.max(axis=-1))
        self.rho_min, self.rho_max = lo, hi

    def __call__(self, u: ArrayLike, nu: int = 0) -> FloatArray:
        """ρ^(nu) of every design at the shared 1-D angles u (remembered per u)."""
        u = np.ascontiguousarray(np.ravel(u), dtype=float)
        key = (u.shape, u.tobytes(), nu)
        out = self._memo.get(key)
        if out is None:
            # einsum's own loop, not BLAS: OpenBLAS threads spin badly on a loaded machine
            out = self._memo[key] = np.einsum('pn,nm->pm', self.radii, self.basis.matrix(u, nu))
        return out

    def length(self) -> FloatArray:
        b = self.basis
        r, r1 = self(b.length_nodes), self(b.length_nodes, 1)
        length: FloatArray = np.sum(b.length_weights * np.hypot(r, r1), axis=-1)
        return length


class _Closure:
    """What a batch knows of its closure (for symmetry with GearTrain.closure)."""

    method = 'gauss (fixed rule, batch)'

    def __init__(self, a: FloatArray, residual: FloatArray) -> None:
        self.a = a
        self.residual = residual


class BatchGearTrain:
    """Closure and the mesh maps Ψ, Θ for every design of a batch (rows)."""

    def __init__(self, curve: BatchCurve) -> None:
        b = curve.basis
        self.curve = curve
        rho = curve(b.quad_nodes.ravel()).reshape(len(curve.radii), *b.quad_nodes.shape)
        w = b.quad_weights
        self.a = _solve_centre_distance(rho, w, curve.rho_max)
        a = self.a[:, None, None]
        inc = np.sum(w * rho / (a - rho), axis=-1)
        psi = np.concatenate([np.zeros((len(inc), 1)), np.cumsum(inc, axis=-1)], axis=-1)
        self.closure = _Closure(self.a, np.abs(psi[:, -1] / TWO_PI - 1.0))
        psi *= TWO_PI / psi[:, -1:]
        x = b.table_nodes
        r, r1 = curve(x), curve(x, 1)
        a = self.a[:, None]
        f = r / (a - r)
        f1 = a * r1 / (a - r) ** 2
        self._x = x
        self._psi = quintic_coefficients(np.broadcast_to(x, psi.shape), psi, f, f1)
        self._psi_nodes = psi
        self._theta = quintic_coefficients(psi, np.broadcast_to(x, psi.shape), 1.0 / f,
                                           -f1 / f ** 3)
        rows = len(psi)
        # per-row search in one sorted array: row k's nodes shifted by k·_ROW_OFFSET
        self._flat = (psi + _ROW_OFFSET * np.arange(rows)[:, None]).ravel()
        self._rows = rows

    def _rows_of(self, v: ArrayLike) -> FloatArray:
        v = np.asarray(v, dtype=float)
        if v.ndim == 0:
            v = v.reshape(1, 1)
        elif v.ndim == 1:
            v = v[None, :]
        return np.broadcast_to(v, (self._rows, v.shape[-1]))

    def psi(self, u: ArrayLike, nu: int = 0) -> FloatArray:
        """Ψ (or its nu-th derivative) of each row at angles u: (m,), (P, 1) or (P, m)."""
        u = self._rows_of(u)
        turns = np.floor(u / TWO_PI)
        s = u - turns * TWO_PI
        k = len(self._x) - 1
        idx = np.clip(np.searchsorted(self._x, s, side='right') - 1, 0, k - 1)
        out = _horner(self._psi[np.arange(self._rows)[:, None], idx], s - self._x[idx], nu)
        return out + turns * TWO_PI if nu == 0 else out

    def theta(self, p: ArrayLike, nu: int = 0) -> FloatArray:
        """Θ = Ψ⁻¹ (or its nu-th derivative) of each row at intermediate angles p."""
        p = self._rows_of(p)
        turns = np.floor(p / TWO_PI)
        s = p - turns * TWO_PI
        k = self._psi_nodes.shape[1] - 1
        rows = np.arange(self._rows)[:, None]
        pos = np.searchsorted(self._flat, (s + _ROW_OFFSET * rows).ravel(), side='right')
        idx = np.clip(pos.reshape(s.shape) - 1 - rows * (k + 1), 0, k - 1)
        out = _horner(self._theta[rows, idx], s - self._psi_nodes[rows, idx], nu)
        return out + turns * TWO_PI if nu == 0 else out


_ROW_OFFSET = 8.0       # > 2π: keeps the rows' mesh angles apart in one sorted array


def _horner(coef: FloatArray, dx: FloatArray, nu: int) -> FloatArray:
    """Σ c_j dx^(5−j) (coef (..., 6), highest power first), or its first derivative."""
    if nu == 0:
        out = coef[..., 0]
        for j in range(1, 6):
            out = out * dx + coef[..., j]
        return out
    if nu != 1:
        raise ValueError('batch gear maps give values and first derivatives')
    out = 5.0 * coef[..., 0]
    for j in range(1, 5):
        out = out * dx + (5 - j) * coef[..., j]
    return out


def _solve_centre_distance(rho: FloatArray, w: FloatArray, rho_max: FloatArray) -> FloatArray:
    """a per row with Σ w ρ/(a−ρ) = 2π: Newton on 1/mean − 1 inside the bracket
    (max ρ at the nodes, 2·max ρ]; rows stop once a step moves a by under 1e-14 of it."""
    rho = rho.reshape(len(rho), -1)
    w = w.ravel()
    lo: FloatArray = rho.max(axis=-1)
    hi = 2.0 * np.maximum(rho_max, lo)
    a = 0.5 * (lo + hi)
    todo = np.arange(len(a))
    for _ in range(_NEWTON_STEPS):
        r, x = rho[todo], a[todo]
        d = x[:, None] - r
        q = r / d
        mean = q @ w / TWO_PI
        q /= d
        slope = -(q @ w) / TWO_PI                        # d mean / da < 0
        h = 1.0 / mean - 1.0                             # < 0 below the root
        below = h < 0
        lo[todo] = np.where(below, x, lo[todo])
        hi[todo] = np.where(below, hi[todo], x)
        step = x + h * mean * mean / slope               # a − h / h'
        inside = (step >= lo[todo]) & (step <= hi[todo])
        step = np.where(inside, step, 0.5 * (lo[todo] + hi[todo]))
        a[todo] = step
        todo = todo[np.abs(step - x) > 1e-14 * x]
        if not todo.size:
            break
    return a


class MechanismBatch(ThreeArmMechanism):
    """P designs sharing control angles and interpolant (see the module doc).

    radii (P, n); the installation's five values (P,) each. The pose methods of ThreeArmMechanism
    apply unchanged and return arrays with a leading axis of P; carrier angles may be given as
    (m,) (the same for every design), (P, 1) or (P, m).
    """

    def __init__(self, basis: CurveBasis, radii: ArrayLike,
                 installation: Installation[ArrayLike]) -> None:
        (carrier_initial_angle, arm_initial_angle, arm_length, pusher_offset,
         planet_carrier_angle) = installation
        radii = np.atleast_2d(np.asarray(radii, dtype=float))
        rows = len(radii)
        col = {name: np.broadcast_to(np.asarray(v, dtype=float), (rows,)).copy() for name, v in
               (('phi0', carrier_initial_angle), ('beta0', arm_initial_angle),
                ('s', arm_length), ('h', pusher_offset), ('gamma0', planet_carrier_angle))}
        finite = np.all(np.isfinite(radii), axis=1) & np.all(
            np.isfinite(np.stack(list(col.values()))), axis=0)
        valid = finite & np.all(radii > 0, axis=1) & (col['s'] > 0) & (col['h'] >= 0) & \
            (col['h'] < col['s'])
        stand_in = np.full(radii.shape[1], 0.04)
        radii = np.where(valid[:, None], radii, stand_in)
        for name, safe in (('phi0', 0.0), ('beta0', 0.0), ('s', 0.15), ('h', 0.0),
                           ('gamma0', 0.0)):
            col[name] = np.where(valid, col[name], safe)
        curve = BatchCurve(basis, radii)
        dips = ~(curve.rho_min > 0)
        if dips.any():          # the interpolant dips to ρ ≤ 0 between the points
            valid &= ~dips
            curve = BatchCurve(basis, np.where(valid[:, None], radii, stand_in))
        self.valid = valid
        self.batch_shape = (rows,)
        self.phi0 = col['phi0'][:, None]
        self.beta0 = col['beta0'][:, None]
        self.arm_length = col['s'][:, None]
        self.pusher_offset = col['h'][:, None]
        self.gamma0 = col['gamma0'][:, None]
        self.delta = np.arcsin(self.pusher_offset / self.arm_length)
        self.train = train = BatchGearTrain(curve)
        self.a = train.a[:, None]
        self._c = math.pi - self.gamma0
        self._w0 = [self.train.theta(self.train.psi(-k * ARM_PHASE) + self._c)
                    for k in range(ARMS)]
