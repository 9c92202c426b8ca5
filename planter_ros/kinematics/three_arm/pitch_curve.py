"""Pitch curves of the non-circular gears: control points -> smooth periodic curve -> closure.

The driving (sun) gear's pitch curve is given by control points (r_i, θ_i), polar angles in
rad measured in the carrier's sense of rotation (see gear_train). The paper does not say how
the curve runs between the points; the interpolant is one swappable piece (`INTERPOLANTS`):

* ``periodic_cubic`` (default): scipy's periodic cubic spline through the points. C² and
  periodic, local-ish, the usual choice for non-circular gear pitch curves; a piecewise cubic,
  so every integral over it is split at the knots, where it is analytic.
* ``trigonometric``: the trigonometric polynomial of lowest degree through the points
  (analytic everywhere; swings more between unevenly spaced points).
* ``bspline_polar``: approximating, not interpolating: the periodic cubic B-spline
  ρ(θ) = Σ r_i N_i(θ) with knots at the control angles, the points (θ_i, r_i) being its control
  polygon in the polar plane (basis i centred on θ_i). C², passes near but not through the
  points, and never leaves their convex hull in (θ, ρ).
* ``bspline_cartesian``: approximating: the uniform closed cubic B-spline in the gear plane
  whose control polygon is the points r_i·(cos θ_i, sin θ_i); ρ(θ) is its distance from the
  centre at polar angle θ. A curve that does not wind once around the centre with a monotone
  polar angle is refused.

The first three are linear in the radii for fixed control angles (`linear`), which the batch
evaluation of many designs (three_arm.batch) uses.

Average ratio 1 (paper eq. 2): the mating (intermediate) gear has radius a − ρ(θ) at polar angle
ψ(θ) = ∫₀^θ ρ/(a−ρ) dθ, and closes after one turn iff (1/2π)∮ ρ/(a−ρ) dθ = 1. The left side
falls strictly from +∞ (a → max ρ) to 0, so the centre distance a is the unique root in
(max ρ, 2 max ρ], found by brentq. The integral is evaluated by Gauss–Legendre on each piece
between knots (where the integrand is analytic, so the rule converges exponentially), with the
pieces bisected until two rules agree to 1e-14. The paper's 1° sum (eq. 2, left Riemann sum on
360 points, which is the periodic trapezoid rule) is kept as method ``paper`` for comparison,
and ``trapezoid`` takes any grid size.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
import math
from typing import TYPE_CHECKING, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..arrays import FloatArray, Floats
from ..errors import DesignError

if TYPE_CHECKING:
    from scipy.interpolate import PPoly

TWO_PI = 2.0 * math.pi
CLOSURE_METHODS = ('gauss', 'trapezoid', 'paper')
_GL_NODES = 16
_GL_TOL = 1e-14
_END_MERGE = 1e-9          # rad: knots this close to 0 or 2π join the end piece
_GL_MAX_SPLITS = 9          # at most 2**9 sub-pieces per knot interval


@lru_cache(maxsize=8)
def leggauss(n: int) -> tuple[FloatArray, FloatArray]:
    """Gauss–Legendre nodes and weights on [-1, 1] (cached: numpy recomputes them each call)."""
    x, w = np.polynomial.legendre.leggauss(n)
    x.flags.writeable = False
    w.flags.writeable = False
    return x, w


def subdivide(ends: FloatArray, m: int) -> FloatArray:
    """Split each interval of the sorted `ends` into m equal parts; returns all the new ends."""
    lo, hi = ends[:-1, None], ends[1:, None]
    out: FloatArray = np.r_[(lo + (hi - lo) * (np.arange(m) / m)).ravel(), ends[-1]]
    return out


class _PiecewisePolynomial:
    """A periodic curve held as a scipy PPoly over [start, start + 2π), evaluated wrapped."""

    linear = True

    def _init_ppoly(self, ppoly: PPoly, start: float, knots: FloatArray) -> None:
        self._pp = (ppoly, ppoly.derivative(1), ppoly.derivative(2))
        self._start = float(start)
        self.breakpoints = np.sort(np.mod(knots, TWO_PI))

    def _wrap(self, theta: ArrayLike) -> Floats:
        return np.mod(np.asarray(theta, dtype=float) - self._start, TWO_PI) + self._start

    def __call__(self, theta: ArrayLike, nu: int = 0) -> Floats:
        return self._pp[nu](self._wrap(theta))

    def extrema(self) -> FloatArray:
        """Polar angles of the local extrema of r (exact roots of the derivative's pieces)."""
        roots = self._pp[1].roots(extrapolate=False)
        roots = roots[np.isfinite(roots)]
        roots = roots[(roots >= self._start) & (roots <= self._start + TWO_PI)]
        return np.mod(roots, TWO_PI)


class _PeriodicCubic(_PiecewisePolynomial):
    """Periodic cubic spline r(θ) through the control points (scipy CubicSpline)."""

    name = 'periodic_cubic'

    def __init__(self, radii: FloatArray, angles: FloatArray) -> None:
        from scipy.interpolate import CubicSpline  # lazy: 440 ms, only a built curve needs it
        x = np.r_[angles, angles[0] + TWO_PI]
        y = np.r_[radii, radii[0]]
        self._init_ppoly(CubicSpline(x, y, bc_type='periodic'), angles[0], angles)


class _PolarBSpline(_PiecewisePolynomial):
    """Periodic cubic B-spline ρ(θ) = Σ r_i N_i(θ), knots at the control angles (scipy BSpline).

    The basis function with knots θ_{i-2} … θ_{i+2} (centred on θ_i, its Greville abscissa
    (θ_{i-1} + θ_i + θ_{i+1})/3) carries r_i.
    """

    name = 'bspline_polar'

    def __init__(self, radii: FloatArray, angles: FloatArray) -> None:
        from scipy.interpolate import BSpline, PPoly  # lazy: 440 ms, only a built curve
        n = len(radii)
        knots = np.r_[angles[n - 3:] - TWO_PI, angles, angles[:4] + TWO_PI]
        coef = np.r_[radii[n - 1], radii, radii[0], radii[1]]
        spline = BSpline(knots, coef, 3, extrapolate=False)
        # the spline's (t, c, k) and its extrapolate flag: what from_spline(spline) reads
        self._init_ppoly(PPoly.from_spline(spline.tck, extrapolate=False), angles[0], angles)


class _Trigonometric:
    """Lowest-degree trigonometric polynomial through the control points (analytic)."""

    name = 'trigonometric'
    linear = True

    def __init__(self, radii: FloatArray, angles: FloatArray) -> None:
        n = len(radii)
        self._k = np.arange(1, (n - 1) // 2 + 1)
        cols = [np.ones(n)] + [np.cos(k * angles) for k in self._k] + \
            [np.sin(k * angles) for k in self._k]
        self._even = n % 2 == 0
        if self._even:     # one more cosine (a half-degree term) makes the system square
            cols.append(np.cos(n // 2 * (angles - angles[0])))
        mat = np.column_stack(cols)
        cond = np.linalg.cond(mat)
        if not np.isfinite(cond) or cond > 1e10:
            raise DesignError('control_angles', 'spacing', 'spread enough for trigonometric '
                              'interpolation', f'the system is singular (condition {cond:.3g})')
        self._c = np.linalg.solve(mat, radii)
        self._n2 = n // 2
        self._a0 = angles[0]
        self.breakpoints = np.array([0.0])

    def __call__(self, theta: ArrayLike, nu: int = 0) -> Floats:
        t = np.asarray(theta, dtype=float)
        k = self._k.reshape((-1,) + (1,) * t.ndim)
        m = len(self._k)
        ca = self._c[1:1 + m].reshape(k.shape)
        sb = self._c[1 + m:1 + 2 * m].reshape(k.shape)
        kt = k * t
        # d^nu/dθ^nu of cos, sin: rotate the phase by nu·π/2 and scale by k^nu
        shift = nu * math.pi / 2
        out: Floats = (np.sum(k ** nu * (ca * np.cos(kt + shift) + sb * np.sin(kt + shift)),
                              axis=0)
                       + (self._c[0] if nu == 0 else 0.0))
        if self._even:
            n2 = self._n2
            out = out + self._c[-1] * n2 ** nu * np.cos(n2 * (t - self._a0) + shift)
        return out

    def extrema(self) -> FloatArray:
        grid = np.linspace(0.0, TWO_PI, 4097)[:-1]
        d = self(grid, 1)
        idx = np.nonzero(np.sign(d) != np.sign(np.roll(d, -1)))[0]
        return grid[idx]


# the uniform closed cubic B-spline segment: C(t) = [t³ t² t 1] · _BSPLINE_MATRIX · [P_{i-1} …
# P_{i+2}], t in [0, 1], segment i running from near P_i to near P_{i+1}
_BSPLINE_MATRIX = np.array([[-1.0, 3.0, -3.0, 1.0], [3.0, -6.0, 3.0, 0.0],
                            [-3.0, 0.0, 3.0, 0.0], [1.0, 4.0, 1.0, 0.0]]) / 6.0
_POWERS = (lambda t: (t ** 3, t * t, t, np.ones_like(t)),
           lambda t: (3.0 * t * t, 2.0 * t, np.ones_like(t), np.zeros_like(t)),
           lambda t: (6.0 * t, np.full_like(t, 2.0), np.zeros_like(t), np.zeros_like(t)))


class _CartesianBSpline:
    """Uniform closed cubic B-spline in the plane with control polygon r_i (cos θ_i, sin θ_i).

    ρ(θ) is the curve's distance from the centre where its polar angle is θ: each query finds
    its segment by polar angle, then solves C(t) × (cos θ, sin θ) = 0 (a cubic in t with one
    root in the segment, as the polar angle is monotone) by safeguarded Newton steps. Polar
    derivatives come from the parametric ones: dρ/dθ = ρ_t/θ_t, d²ρ/dθ² =
    (ρ_tt θ_t − ρ_t θ_tt)/θ_t³.
    """

    name = 'bspline_cartesian'
    linear = False

    def __init__(self, radii: FloatArray, angles: FloatArray) -> None:
        n = len(radii)
        pts = np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=1)
        window = (np.arange(n)[:, None] + np.arange(-1, 3)[None, :]) % n
        # (segment, power t³ t² t 1, xy)
        self._coef = np.einsum('ij,sjk->sik', _BSPLINE_MATRIX, pts[window])
        self._n = n
        self._check_star_shaped()
        start = self._coef[:, 3, :]
        begin = np.mod(np.arctan2(start[:, 1], start[:, 0]), TWO_PI)
        self._order = np.argsort(begin)
        self._begin = begin[self._order]
        self.breakpoints = self._begin.copy()

    def _check_star_shaped(self) -> None:
        """The polar angle must grow along the whole curve: C × C' > 0 (a quintic per segment),
        and the curve must turn once around the centre."""
        poly = np.polynomial.Polynomial
        worst = np.inf
        for c in self._coef:
            cx, cy = poly(c[::-1, 0]), poly(c[::-1, 1])
            cross = cx * cy.deriv() - cy * cx.deriv()
            roots = [complex(r) for r in cross.deriv().roots()]
            crit = [r.real for r in roots if abs(r.imag) < 1e-12 and 0.0 <= r.real <= 1.0]
            worst = min(worst, float(np.min(cross(np.r_[0.0, 1.0, crit]))))
        start = self._coef[:, 3, :]
        turns = np.sum(np.diff(np.unwrap(np.r_[np.arctan2(start[:, 1], start[:, 0]),
                                                np.arctan2(start[0, 1], start[0, 0])]))) / TWO_PI
        if not (worst > 0.0 and abs(turns - 1.0) < 1e-9):
            raise DesignError('control_radii', 'the control polygon', 'a Cartesian B-spline '
                              'whose polar angle grows all the way round the gear centre',
                              'the curve does not wind once round the centre')

    def _point(self, seg: NDArray[np.intp], t: FloatArray, nu: int = 0) -> FloatArray:
        c = self._coef[seg]                       # (..., 4, 2)
        powers = _POWERS[nu](t)
        point: FloatArray = sum(p[..., None] * c[..., j, :] for j, p in enumerate(powers))
        return point

    def _parameter(self, theta: ArrayLike) -> tuple[NDArray[np.intp], FloatArray]:
        """(segment, t) of the curve point at polar angle θ (arrays)."""
        th = np.mod(np.asarray(theta, dtype=float), TWO_PI)
        j = np.searchsorted(self._begin, th, side='right') - 1     # -1: the wrapping segment
        seg = self._order[j % self._n]
        ux, uy = np.cos(th), np.sin(th)
        lo, hi = np.zeros_like(th), np.ones_like(th)
        t = np.full_like(th, 0.5)
        for _ in range(64):
            c, c1 = self._point(seg, t), self._point(seg, t, 1)
            g = c[..., 0] * uy - c[..., 1] * ux          # > 0 while the point is short of θ
            g1 = c1[..., 0] * uy - c1[..., 1] * ux
            lo = np.where(g > 0, t, lo)
            hi = np.where(g > 0, hi, t)
            with np.errstate(divide='ignore', invalid='ignore'):
                step = t - g / g1
            step = np.where((step > lo) & (step < hi), step, 0.5 * (lo + hi))
            done = np.all(np.abs(step - t) <= 4e-16)
            t = step
            if done:
                break
        return seg, t

    def __call__(self, theta: ArrayLike, nu: int = 0) -> Floats:
        seg, t = self._parameter(theta)
        c, c1 = self._point(seg, t), self._point(seg, t, 1)
        r = np.hypot(c[..., 0], c[..., 1])
        if nu == 0:
            return r
        cross = c[..., 0] * c1[..., 1] - c[..., 1] * c1[..., 0]
        dot = np.sum(c * c1, axis=-1)
        r_t, th_t = dot / r, cross / (r * r)
        if nu == 1:
            first: FloatArray = r_t / th_t
            return first
        c2 = self._point(seg, t, 2)
        r_tt = (np.sum(c1 * c1, axis=-1) + np.sum(c * c2, axis=-1)) / r - dot * dot / r ** 3
        cross2 = c[..., 0] * c2[..., 1] - c[..., 1] * c2[..., 0]
        th_tt = cross2 / (r * r) - 2.0 * cross * dot / r ** 4
        second: FloatArray = (r_tt * th_t - r_t * th_tt) / th_t ** 3
        return second

    def extrema(self) -> FloatArray:
        """Polar angles where ρ is stationary: roots of C · C' (a quintic per segment)."""
        poly = np.polynomial.Polynomial
        out = []
        for c in self._coef:
            cx, cy = poly(c[::-1, 0]), poly(c[::-1, 1])
            for root in map(complex, (cx * cx.deriv() + cy * cy.deriv()).roots()):
                if abs(root.imag) < 1e-12 and 0.0 <= root.real <= 1.0:
                    x, y = cx(root.real), cy(root.real)
                    out.append(math.atan2(y, x))
        angles: FloatArray = np.mod(np.asarray(out, dtype=float), TWO_PI)
        return angles


INTERPOLANTS = {cls.name: cls for cls in (_PeriodicCubic, _Trigonometric, _PolarBSpline,
                                          _CartesianBSpline)}


def _check_control_points(radii: ArrayLike, angles: ArrayLike) -> tuple[FloatArray, FloatArray]:
    radii = np.asarray(radii, dtype=float).ravel()
    angles = np.asarray(angles, dtype=float).ravel()
    if radii.size < 4:
        raise DesignError('control_radii', f'{radii.size} values', 'at least 4 control points')
    if angles.size != radii.size:
        raise DesignError('control_angles', f'{angles.size} values',
                          f'one per control radius ({radii.size})')
    for name, arr in (('control_radii', radii), ('control_angles', angles)):
        bad = ~np.isfinite(arr)
        if bad.any():
            raise DesignError(name, float(arr[bad][0]), 'finite numbers')
    if np.any(radii <= 0):
        raise DesignError('control_radii', float(radii[radii <= 0][0]), '> 0 m')
    step = np.diff(angles)
    if np.any(step <= 0) or angles[-1] - angles[0] >= TWO_PI:
        raise DesignError('control_angles', 'order', 'strictly increasing within one turn '
                          '(last − first < 2π rad)')
    gap = min(step.min(), TWO_PI - (angles[-1] - angles[0]))
    if gap < 1e-3:
        raise DesignError('control_angles', float(gap), 'neighbours ≥ 1e-3 rad apart',
                          'coincident control points')
    return radii, angles


class PitchCurve:
    """The sun (and planet) gear pitch curve ρ(θ) in m, θ in rad, periodic with 2π."""

    def __init__(self, radii: ArrayLike, angles: ArrayLike,
                 interpolant: str = 'periodic_cubic') -> None:
        if interpolant not in INTERPOLANTS:
            raise DesignError('interpolant', interpolant, ' | '.join(INTERPOLANTS))
        self.radii, self.angles = _check_control_points(radii, angles)
        self.interpolant = interpolant
        self._f = INTERPOLANTS[interpolant](self.radii, self.angles)
        self._pieces = analytic_pieces(self._f.breakpoints)
        self.rho_min, self.rho_max = self._range()
        if not self.rho_min > 0.0:
            raise DesignError('control_radii', float(self.radii.min()), 'a pitch curve that '
                              'stays outside the gear centre',
                              f'the {interpolant} interpolant dips to '
                              f'{self.rho_min * 1e3:.3g} mm between the points')

    @overload
    def __call__(self, theta: FloatArray, nu: int = 0) -> FloatArray: ...
    @overload
    def __call__(self, theta: ArrayLike, nu: int = 0) -> Floats: ...
    def __call__(self, theta: ArrayLike, nu: int = 0) -> Floats:
        """ρ (nu=0) or its nu-th derivative with respect to θ (an array for an array θ)."""
        return self._f(theta, nu)

    @property
    def pieces(self) -> FloatArray:
        """Ends of the pieces in [0, 2π] on which ρ is analytic (knots of the interpolant)."""
        return self._pieces

    def _range(self) -> tuple[float, float]:
        cand = np.r_[self._f.extrema(), self._pieces, np.linspace(0, TWO_PI, 721)]
        values = self(cand)
        return float(values.min()), float(values.max())

    def gauss_nodes(self, splits: int = 0) -> tuple[FloatArray, FloatArray]:
        """Gauss–Legendre nodes and weights over [0, 2π], 2**splits sub-pieces per piece."""
        return gauss_nodes(self._pieces, splits)

    def curvature_radius(self, theta: ArrayLike) -> FloatArray:
        """Signed radius of curvature (m) of the pitch curve; > 0 convex, < 0 concave."""
        r, r1, r2 = self(theta), self(theta, 1), self(theta, 2)
        return polar_curvature_radius(r, r1, r2)

    def length(self) -> float:
        nodes, weights = self.gauss_nodes(LENGTH_SPLITS)
        return float(np.sum(weights * np.hypot(self(nodes), self(nodes, 1))))


LENGTH_SPLITS = 2       # Gauss rule of the pitch-curve length: 2**2 sub-pieces per piece


def analytic_pieces(breakpoints: ArrayLike) -> FloatArray:
    """Ends in [0, 2π] of the pieces on which an interpolant with these knots is analytic.

    Knots within 1e-9 rad of the ends 0 and 2π would make pieces of ~0 width (their quintic
    tables divide by width⁵); a kink that close to an end changes no integral.
    """
    knots = np.asarray(breakpoints, dtype=float)
    knots = knots[(knots > _END_MERGE) & (knots < TWO_PI - _END_MERGE)]
    return np.unique(np.r_[0.0, knots, TWO_PI])


def gauss_nodes(pieces: FloatArray, splits: int = 0,
                points: int = _GL_NODES) -> tuple[FloatArray, FloatArray]:
    """Gauss–Legendre nodes and weights over [0, 2π], 2**splits sub-pieces per piece."""
    x, w = leggauss(points)
    sub = subdivide(pieces, 2 ** splits)
    lo, hi = sub[:-1, None], sub[1:, None]
    half = 0.5 * (hi - lo)
    return (lo + half * (x + 1.0)).ravel(), (half * w).ravel()


def polar_curvature_radius(r: Floats, r1: Floats, r2: Floats) -> FloatArray:
    """Signed radius of curvature of a polar curve from ρ, ρ' and ρ'' (arrays; inf where
    straight)."""
    num = (r * r + r1 * r1) ** 1.5
    den = r * r + 2.0 * r1 * r1 - r * r2
    with np.errstate(divide='ignore'):
        return np.where(den == 0.0, np.inf, num / np.where(den == 0.0, 1.0, den))


def closure_mean(rho: FloatArray, weights: FloatArray, a: float) -> float:
    """(1/2π) Σ w ρ/(a−ρ): the mean transmission ratio for centre distance a (1 = closed)."""
    return float(np.dot(weights, rho / (a - rho))) / TWO_PI


class Closure:
    """Centre distance a of the mating pair and how well the closure condition holds."""

    def __init__(self, a: float, residual: float, method: str, evaluations: int) -> None:
        self.a = a
        self.residual = residual        # |mean ratio − 1| at a, by the refined Gauss rule
        self.method = method
        self.evaluations = evaluations  # ρ samples the method used

    def __repr__(self) -> str:
        return (f'Closure(a={self.a:.12g}, residual={self.residual:.3g}, method={self.method},'
                f' evaluations={self.evaluations})')


def _converged_gauss(curve: PitchCurve,
                     a: float) -> tuple[FloatArray, FloatArray, FloatArray, float]:
    """Gauss rule with enough splits that the closure mean is converged at centre distance a."""
    prev = None
    for splits in range(_GL_MAX_SPLITS + 1):
        nodes, weights = curve.gauss_nodes(splits)
        rho = curve(nodes)
        val = closure_mean(rho, weights, a)
        if prev is not None and abs(val - prev) <= _GL_TOL * abs(val):
            return nodes, weights, rho, val
        prev = val
    return nodes, weights, rho, val


def solve_centre_distance(curve: PitchCurve, method: str = 'gauss',
                          samples: int | None = None) -> Closure:
    """Solve (1/2π)∮ρ/(a−ρ)dθ = 1 for the centre distance a (m).

    method 'gauss' (default) is exponentially convergent; 'trapezoid' uses `samples` uniform
    points (default 360); 'paper' is the paper's 1° sum. The residual is always measured with
    the converged Gauss rule, so the methods are compared on the same footing.
    """
    from scipy.optimize import brentq  # lazy: 300 ms, only a closure solved needs it
    if method not in CLOSURE_METHODS:
        raise DesignError('closure method', method, ' | '.join(CLOSURE_METHODS))
    rmax = curve.rho_max
    if method == 'gauss':
        splits = 0
        for _ in range(3):      # the rule must be converged at the root, not at the guess
            nodes, weights = curve.gauss_nodes(splits)
            rho = curve(nodes)
            a = _root(brentq, rho, weights, rmax)
            nodes, weights, rho, _ = _converged_gauss(curve, a)
            splits_new = int(round(math.log2(len(nodes) / (_GL_NODES * (len(curve.pieces) - 1)))))
            if splits_new == splits:
                break
            splits = splits_new
        evaluations = len(nodes)
    else:
        n = 360 if method == 'paper' else int(samples or 360)
        if n < 8:
            raise DesignError('samples', n, '≥ 8')
        rho = curve(np.arange(n, dtype=np.float64) * (TWO_PI / n))
        weights = np.full(n, TWO_PI / n)
        a = _root(brentq, rho, weights, max(rmax, float(rho.max())))
        evaluations = n
    _, _, _, mean = _converged_gauss(curve, a)
    return Closure(a, abs(mean - 1.0), method, evaluations)


def _root(brentq: Callable[..., float], rho: FloatArray, weights: FloatArray,
          rmax: float) -> float:
    lo = rmax * (1.0 + 1e-12)
    hi = 2.0 * rmax

    def f(a: float) -> float:
        return closure_mean(rho, weights, a) - 1.0
    flo = f(lo)
    while flo <= 0.0:       # the peak of ρ is so narrow that even a ≈ max ρ under-closes
        lo = rmax + (lo - rmax) * 1e-3
        if lo - rmax <= rmax * 1e-15:
            raise DesignError('control_radii', rmax, 'a pitch curve whose largest radius is '
                              'not an isolated spike', 'no centre distance closes the pair')
        flo = f(lo)
    return brentq(f, lo, hi, xtol=rmax * 1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)
