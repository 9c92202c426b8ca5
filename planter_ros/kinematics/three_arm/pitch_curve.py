"""Pitch curves of the non-circular gears: control points -> smooth periodic curve -> closure.

The driving (sun) gear's pitch curve is given by control points (r_i, θ_i), polar angles in
rad measured in the carrier's sense of rotation (see gear_train). The paper does not say how
the curve runs between the points; the interpolant is one swappable piece (`INTERPOLANTS`):

* ``periodic_cubic`` (default): scipy's periodic cubic spline through the points. C² and
  periodic, local-ish, the usual choice for non-circular gear pitch curves; a piecewise cubic,
  so every integral over it is split at the knots, where it is analytic.
* ``trigonometric``: the trigonometric polynomial of lowest degree through the points
  (analytic everywhere; swings more between unevenly spaced points).

Average ratio 1 (paper eq. 2): the mating (intermediate) gear has radius a − ρ(θ) at polar angle
ψ(θ) = ∫₀^θ ρ/(a−ρ) dθ, and closes after one turn iff (1/2π)∮ ρ/(a−ρ) dθ = 1. The left side
falls strictly from +∞ (a → max ρ) to 0, so the centre distance a is the unique root in
(max ρ, 2 max ρ], found by brentq. The integral is evaluated by Gauss–Legendre on each piece
between knots (where the integrand is analytic, so the rule converges exponentially), with the
pieces bisected until two rules agree to 1e-14. The paper's 1° sum (eq. 2, left Riemann sum on
360 points, which is the periodic trapezoid rule) is kept as method ``paper`` for comparison,
and ``trapezoid`` takes any grid size.
"""

from functools import lru_cache
import math

import numpy as np

from ..errors import DesignError

TWO_PI = 2.0 * math.pi
CLOSURE_METHODS = ('gauss', 'trapezoid', 'paper')
_GL_NODES = 16
_GL_TOL = 1e-14
_END_MERGE = 1e-9          # rad: knots this close to 0 or 2π join the end piece
_GL_MAX_SPLITS = 9          # at most 2**9 sub-pieces per knot interval


@lru_cache(maxsize=8)
def leggauss(n):
    """Gauss–Legendre nodes and weights on [-1, 1] (cached: numpy recomputes them each call)."""
    x, w = np.polynomial.legendre.leggauss(n)
    x.flags.writeable = False
    w.flags.writeable = False
    return x, w


def subdivide(ends, m):
    """Split each interval of the sorted `ends` into m equal parts; returns all the new ends."""
    lo, hi = ends[:-1, None], ends[1:, None]
    return np.r_[(lo + (hi - lo) * (np.arange(m) / m)).ravel(), ends[-1]]


class _PeriodicCubic:
    """Periodic cubic spline r(θ) through the control points (scipy CubicSpline)."""

    name = 'periodic_cubic'

    def __init__(self, radii, angles):
        from scipy.interpolate import CubicSpline
        x = np.r_[angles, angles[0] + TWO_PI]
        y = np.r_[radii, radii[0]]
        self._spline = CubicSpline(x, y, bc_type='periodic')
        self._start = float(angles[0])
        self._d1 = self._spline.derivative(1)
        self._d2 = self._spline.derivative(2)
        self.breakpoints = np.sort(np.mod(angles, TWO_PI))

    def _wrap(self, theta):
        return np.mod(np.asarray(theta, dtype=float) - self._start, TWO_PI) + self._start

    def __call__(self, theta, nu=0):
        t = self._wrap(theta)
        return (self._spline, self._d1, self._d2)[nu](t)

    def extrema(self):
        """Polar angles of the local extrema of r (exact roots of the spline's derivative)."""
        roots = self._d1.roots(extrapolate=False)
        return np.mod(roots[np.isfinite(roots)], TWO_PI)


class _Trigonometric:
    """Lowest-degree trigonometric polynomial through the control points (analytic)."""

    name = 'trigonometric'

    def __init__(self, radii, angles):
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

    def __call__(self, theta, nu=0):
        t = np.asarray(theta, dtype=float)
        k = self._k.reshape((-1,) + (1,) * t.ndim)
        m = len(self._k)
        ca = self._c[1:1 + m].reshape(k.shape)
        sb = self._c[1 + m:1 + 2 * m].reshape(k.shape)
        kt = k * t
        # d^nu/dθ^nu of cos, sin: rotate the phase by nu·π/2 and scale by k^nu
        shift = nu * math.pi / 2
        out = (np.sum(k ** nu * (ca * np.cos(kt + shift) + sb * np.sin(kt + shift)), axis=0)
               + (self._c[0] if nu == 0 else 0.0))
        if self._even:
            n2 = self._n2
            out = out + self._c[-1] * n2 ** nu * np.cos(n2 * (t - self._a0) + shift)
        return out

    def extrema(self):
        grid = np.linspace(0.0, TWO_PI, 4097)[:-1]
        d = self(grid, 1)
        idx = np.nonzero(np.sign(d) != np.sign(np.roll(d, -1)))[0]
        return grid[idx]


INTERPOLANTS = {cls.name: cls for cls in (_PeriodicCubic, _Trigonometric)}


def _check_control_points(radii, angles):
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

    def __init__(self, radii, angles, interpolant='periodic_cubic'):
        if interpolant not in INTERPOLANTS:
            raise DesignError('interpolant', interpolant, ' | '.join(INTERPOLANTS))
        self.radii, self.angles = _check_control_points(radii, angles)
        self.interpolant = interpolant
        self._f = INTERPOLANTS[interpolant](self.radii, self.angles)
        # knots within 1e-9 rad of the ends 0 and 2π would make pieces of ~0 width (their
        # quintic tables divide by width⁵); a kink that close to an end changes no integral
        knots = np.asarray(self._f.breakpoints, dtype=float)
        knots = knots[(knots > _END_MERGE) & (knots < TWO_PI - _END_MERGE)]
        self._pieces = np.unique(np.r_[0.0, knots, TWO_PI])
        self.rho_min, self.rho_max = self._range()
        if not self.rho_min > 0.0:
            raise DesignError('control_radii', float(self.radii.min()), 'a pitch curve that '
                              'stays outside the gear centre',
                              f'the {interpolant} interpolant dips to '
                              f'{self.rho_min * 1e3:.3g} mm between the points')

    def __call__(self, theta, nu=0):
        """ρ (nu=0) or its nu-th derivative with respect to θ."""
        return self._f(theta, nu)

    @property
    def pieces(self):
        """Ends of the pieces in [0, 2π] on which ρ is analytic (knots of the interpolant)."""
        return self._pieces

    def _range(self):
        cand = np.r_[self._f.extrema(), self._pieces, np.linspace(0, TWO_PI, 721)]
        values = self(cand)
        return float(values.min()), float(values.max())

    def gauss_nodes(self, splits=0):
        """Gauss–Legendre nodes and weights over [0, 2π], 2**splits sub-pieces per piece."""
        x, w = leggauss(_GL_NODES)
        sub = subdivide(self._pieces, 2 ** splits)
        lo, hi = sub[:-1, None], sub[1:, None]
        half = 0.5 * (hi - lo)
        nodes = (lo + half * (x + 1.0)).ravel()
        weights = (half * w).ravel()
        return nodes, weights

    def curvature_radius(self, theta):
        """Signed radius of curvature (m) of the pitch curve; > 0 convex, < 0 concave."""
        r, r1, r2 = self(theta), self(theta, 1), self(theta, 2)
        return polar_curvature_radius(r, r1, r2)

    def length(self):
        nodes, weights = self.gauss_nodes(2)
        return float(np.sum(weights * np.hypot(self(nodes), self(nodes, 1))))


def polar_curvature_radius(r, r1, r2):
    """Signed radius of curvature of a polar curve from ρ, ρ' and ρ'' (arrays; inf where
    straight)."""
    num = (r * r + r1 * r1) ** 1.5
    den = r * r + 2.0 * r1 * r1 - r * r2
    with np.errstate(divide='ignore'):
        return np.where(den == 0.0, np.inf, num / np.where(den == 0.0, 1.0, den))


def closure_mean(rho, weights, a):
    """(1/2π) Σ w ρ/(a−ρ): the mean transmission ratio for centre distance a (1 = closed)."""
    return float(np.dot(weights, rho / (a - rho))) / TWO_PI


class Closure:
    """Centre distance a of the mating pair and how well the closure condition holds."""

    def __init__(self, a, residual, method, evaluations):
        self.a = a
        self.residual = residual        # |mean ratio − 1| at a, by the refined Gauss rule
        self.method = method
        self.evaluations = evaluations  # ρ samples the method used

    def __repr__(self):
        return (f'Closure(a={self.a:.12g}, residual={self.residual:.3g}, method={self.method},'
                f' evaluations={self.evaluations})')


def _converged_gauss(curve, a):
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


def solve_centre_distance(curve, method='gauss', samples=None):
    """Solve (1/2π)∮ρ/(a−ρ)dθ = 1 for the centre distance a (m).

    method 'gauss' (default) is exponentially convergent; 'trapezoid' uses `samples` uniform
    points (default 360); 'paper' is the paper's 1° sum. The residual is always measured with
    the converged Gauss rule, so the methods are compared on the same footing.
    """
    from scipy.optimize import brentq
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
        nodes = np.arange(n) * (TWO_PI / n)
        rho = curve(nodes)
        weights = np.full(n, TWO_PI / n)
        a = _root(brentq, rho, weights, max(rmax, float(rho.max())))
        evaluations = n
    _, _, _, mean = _converged_gauss(curve, a)
    return Closure(a, abs(mean - 1.0), method, evaluations)


def _root(brentq, rho, weights, rmax):
    lo = rmax * (1.0 + 1e-12)
    hi = 2.0 * rmax
    f = lambda a: closure_mean(rho, weights, a) - 1.0  # noqa: E731
    flo = f(lo)
    while flo <= 0.0:       # the peak of ρ is so narrow that even a ≈ max ρ under-closes
        lo = rmax + (lo - rmax) * 1e-3
        if lo - rmax <= rmax * 1e-15:
            raise DesignError('control_radii', rmax, 'a pitch curve whose largest radius is '
                              'not an isolated spike', 'no centre distance closes the pair')
        flo = f(lo)
    return brentq(f, lo, hi, xtol=rmax * 1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)
