"""The out-of-soil arc: θ(s) between two given states (θ, θ′, θ″) over a given distance, C2 at
both ends, with the smallest peak load.

The arc's θ″ is piecewise linear on `pieces` steps (so θ is a C2 piecewise cubic and θ‴ is
constant per step), equal but where an end's θ″ must be turned round within the jerk limit
(finer there: `_grid`). Its knot values are the unknowns of a linear programme (scipy HiGHS):

    minimise   t + w·(peak speed + jerk + torque + acceleration utilisations)
                 + a small multiple of the mean jerk utilisation (the total variation of θ″,
                 which picks the smoothest of the profiles with the same peaks)
    subject to θ″ at both ends as given; θ′ and θ at the far end as given (two equalities);
               θ′ ≥ 0 everywhere (θ′'s Bernstein coefficients on each step ≥ 0: no
               reversing); v·θ′ ≤ p_s·ω_max everywhere (θ′'s Bernstein coefficients on each
               step: the speed held between the knots too);
               v²·|θ″| ≤ p_α·α_max at every knot (α_max: the acceleration limit, or without
               one the torque-limited acceleration, then only a scale: p_α ≤ t is dropped);
               v³·|Δθ″/h| ≤ p_j·j_max on every step;
               |T_m| ≤ p_T·T_peak at every knot, T_m = k_α(θ)·v²θ″ + k_ω(θ)·v²θ′² + g(θ)
               linearised about the previous solution (θ′² ≈ 2pθ′ − p², k(θ) at its θ),
               repeated a few times;  p_s, p_α, p_j, p_T ≤ t;

so t is the largest utilisation of any limit at the top speed v, made as small as possible, and
where the ends already force t (the in-soil speed, say) each limit's own peak still is. A
constraint the end states alone fix (a knot at an end, the first part of the first step) is
left out: it is what it is, and must not lift t over the rest of the arc. Speed, acceleration
and jerk are held exactly (hull, knots, steps); the torque, linearised and held at the knots,
keeps `MARGIN` inside its limit. The end equalities are then closed to round-off by a 2×2
correction of two interior knots.
"""

from collections.abc import Callable
from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import NDArray

from planter_ros.kinematics.arrays import FloatArray

from .drive import EffectiveLimits, TorqueTerms
from .errors import CamPlanningError
from .piecewise import Piecewise, State

__all__ = ['plan_arc', 'straight_arc', 'ArcEnds', 'ARC_PIECES']

ARC_PIECES = 64
LINEARISATIONS = 4
MARGIN = 0.998               # the torque kept this far inside its limit (linearised, knots
#                              only); speed, acceleration and jerk are exact (hull, knots, steps)
PEAK_WEIGHT = 0.05           # weight of each limit's own peak against the largest one
SMOOTHING = 1e-3             # weight of the mean jerk utilisation (total variation of θ″)
SPEED_SUBSTEPS = 1           # parts of a step the speed's convex hull is taken on
END_STEPS = 8                # fine steps where an end's θ″ must be turned round (`_grid`)


@dataclass(frozen=True)
class ArcEnds:
    """What an out-of-soil arc joins: `length` (m) of row from the state `start` to the state
    `end`, (θ, θ′, θ″) each (rad, rad/m, rad/m²)."""

    length: float
    start: State
    end: State


def _grid(ends: ArcEnds, n: int, jerk_per_m3: float) -> FloatArray:
    """The knots' steps (n of them, summing to `length`): equal, except where an end state
    has a large θ″: the jerk limit then needs the distance λ = |θ″|/j (j the jerk limit in
    rad/m³ at the planning speed) to turn it round, and a coarse first step lets the speed
    overshoot meanwhile (a soil exit near the speed limit: 0.2 % over it). There `END_STEPS`
    steps cover 2λ (at most a quarter of the arc), the rest are equal."""
    length = ends.length
    uniform = length / n
    fine = []
    for state in (ends.start, ends.end):
        ramp = abs(state[2]) / jerk_per_m3
        fine.append(min(2.0 * ramp, 0.25 * length) if ramp > uniform / END_STEPS else 0.0)
    counts = [END_STEPS if f else 0 for f in fine]
    middle = n - sum(counts)
    return np.array([fine[0] / END_STEPS] * counts[0]
                    + [(length - fine[0] - fine[1]) / middle] * middle
                    + [fine[1] / END_STEPS] * counts[1])


def _integrals(h: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Matrices B, C with θ′_j = θ′_0 + B[j]·x and θ_j = θ_0 + θ′_0·s_j + C[j]·x for knot
    values x of θ″ (piecewise linear), steps h (array)."""
    n = h.size
    b = np.zeros((n + 1, n + 1))
    c = np.zeros((n + 1, n + 1))
    for j in range(1, n + 1):
        hj = h[j - 1]
        c[j] = c[j - 1] + hj * b[j - 1]
        c[j, j - 1] += hj * hj / 3.0
        c[j, j] += hj * hj / 6.0
        b[j] = b[j - 1]
        b[j, j - 1] += 0.5 * hj
        b[j, j] += 0.5 * hj
    return b, c


def _speed_hull(bm: FloatArray, h: FloatArray, parts: int) -> FloatArray:
    """Rows R with R·x + θ′_0 = every Bernstein coefficient of θ′ on `parts` equal parts of
    every step (the parts' start values and middle coefficients; the ends are knots): θ′
    on step i is θ′_i + x_i τ + (x_(i+1) − x_i) τ²/(2h_i)."""
    n = bm.shape[0] - 1
    eye = np.eye(n + 1)
    out = []
    delta = (h / parts)[:, None]
    hh = h[:, None]
    for q in range(parts):
        tau = q * delta
        value = bm[:-1] + tau * eye[:-1] + tau * tau / (2.0 * hh) * (eye[1:] - eye[:-1])
        slope = eye[:-1] + tau / hh * (eye[1:] - eye[:-1])
        if q:
            out.append(value)
        out.append(value + 0.5 * delta * slope)
    return np.vstack(out)


def _integrate(x: FloatArray, h: FloatArray, theta0: float,
               d0: float) -> tuple[FloatArray, FloatArray]:
    """θ and θ′ at the knots from the knot values of θ″ (the cubic pieces' own recurrence),
    steps h (array)."""
    n = x.size - 1
    th = np.empty(n + 1)
    d1 = np.empty(n + 1)
    th[0], d1[0] = theta0, d0
    for j in range(n):
        hj = h[j]
        th[j + 1] = th[j] + d1[j] * hj + hj * hj * (x[j] / 3.0 + x[j + 1] / 6.0)
        d1[j + 1] = d1[j] + 0.5 * hj * (x[j] + x[j + 1])
    return th, d1


def _close(x: FloatArray, h: FloatArray, start: State, end: State) -> FloatArray:
    """Move two interior knots so θ′ and θ at the far end match `end` to round-off."""
    n = x.size - 1
    j1, j2 = max(1, n // 3), max(2, (2 * n) // 3)
    for _ in range(2):
        th, d1 = _integrate(x, h, start[0], start[1])
        r = np.array([d1[-1] - end[1], th[-1] - end[0]])
        if not np.any(r):
            break
        jac = np.empty((2, 2))
        for col, j in enumerate((j1, j2)):
            e = np.zeros_like(x)
            e[j] = 1.0
            th_e, d1_e = _integrate(e, h, 0.0, 0.0)
            jac[:, col] = (d1_e[-1], th_e[-1])
        dx = np.linalg.solve(jac, r)
        x[j1] -= dx[0]
        x[j2] -= dx[1]
    return x


def _quintic_guess(ends: ArcEnds, knots: FloatArray) -> tuple[FloatArray, FloatArray]:
    """θ, θ′ at the knots of the quintic that meets both end states (the first linearisation
    point of the torque)."""
    # lazy: scipy.interpolate costs 0.39 s (python -X importtime); only planning needs it, not
    # the command process, which imports the cam to run planned profiles
    from scipy.interpolate import BPoly
    poly = BPoly.from_derivatives([0.0, ends.length], [list(ends.start), list(ends.end)])
    return poly(knots), poly(knots, 1)


def plan_arc(ends: ArcEnds, speed: float, limits: EffectiveLimits,
             torque_terms: Callable[[FloatArray], TorqueTerms],
             pieces: int = ARC_PIECES) -> tuple[Piecewise, float]:
    """A C2 arc over `ends` (its length, m, from state `start` to `end`), planned for
    ground speed `speed` (m/s) against `limits` (drive.EffectiveLimits); `torque_terms(θ)`
    gives (k_α, k_ω, g) of the motor torque. Returns (Piecewise over [0, length], t) with t the
    largest utilisation at the knots."""
    # lazy: scipy.optimize costs 0.28 s (python -X importtime): only planning needs it, not
    # the command process, which imports the cam to run planned profiles
    from scipy.optimize import linprog
    from scipy.sparse import csr_matrix, vstack  # lazy: 0.13 s, the same reason

    length, start, end = ends.length, ends.start, ends.end

    n = int(pieces)
    v = float(speed)
    h = _grid(ends, n, limits.jerk / max(v, 1e-3) ** 3)
    knots = np.concatenate(([0.0], np.cumsum(h)))
    knots[-1] = length
    bm, cm = _integrals(h)
    # unknowns: x (θ″ at the knots), t (the largest utilisation), the peaks of jerk, torque,
    # speed and (where limited) acceleration, e (each step's |jerk| / j_max, for the
    # smoothing)
    it, ij, itq, ia, isp = n + 1, n + 2, n + 3, n + 4, n + 5
    ie = n + 6
    nv = ie + n
    cost = np.zeros(nv)
    cost[it] = 1.0
    cost[[ij, itq, ia, isp]] = PEAK_WEIGHT
    cost[ie:] = SMOOTHING / n
    eq = np.zeros((2, nv))
    eq[0, :n + 1] = bm[n]
    eq[1, :n + 1] = cm[n]
    eq_rhs = [end[1] - start[1], end[0] - start[0] - start[1] * length]
    bounds: list[tuple[float | None, float | None]] = \
        [(None, None)] * (n + 1) + [(0.0, None)] * (5 + n)
    bounds[0] = (start[2], start[2])
    bounds[n] = (end[2], end[2])

    def rows(block_x: FloatArray, col: int | None = None, coef: float | None = None,
             col_e: FloatArray | None = None) -> FloatArray:
        m = block_x.shape[0]
        full = np.zeros((m, nv))
        full[:, :n + 1] = block_x
        if col is not None:
            full[:, col] = coef
        if col_e is not None:
            full[:, ie:] = col_e
        return full

    def free(block_x: FloatArray) -> NDArray[np.bool_]:
        """The rows of a block that move with the free knots (1..n−1): a row fixed by the
        end states alone is what it is, and must not force the utilisation up."""
        moving: NDArray[np.bool_] = np.any(block_x[:, 1:n] != 0.0, axis=1)
        return moving

    fixed_rows, fixed_rhs = [], []
    # each peak below t (the acceleration's only where it is a limit: without one it is
    # measured against the torque-limited acceleration, a scale for the objective)
    for col in (ij, itq, isp, ia) if limits.acceleration else (ij, itq, isp):
        r = np.zeros((1, nv))
        r[0, col], r[0, it] = 1.0, -1.0
        fixed_rows.append(r)
        fixed_rhs.append(np.zeros(1))
    # no reversing: −(θ′0 + B x) ≤ 0 at the knots, and between them: on a step θ′ is a
    # quadratic whose Bernstein coefficients are θ′_i, θ′_i + h x_i / 2 and θ′_(i+1); all ≥ 0
    # keeps θ′ ≥ 0 over the whole step
    fixed_rows.append(rows(-bm))
    fixed_rhs.append(np.full(n + 1, start[1]))
    middle = bm[:-1] + 0.5 * h[:, None] * np.eye(n + 1)[:-1]
    fixed_rows.append(rows(-middle))
    fixed_rhs.append(np.full(n, start[1]))
    # speed: v (θ′0 + B x) ≤ p_s ω_max at the knots and over the whole step, not only at the
    # knots: the quadratic's Bernstein coefficients on each of SPEED_SUBSTEPS parts of a step
    # (the part's ends and its middle coefficient) ≤ p_s ω_max (its convex hull; cautious
    # where θ″ is large, which the fine steps of `_grid` keep small)
    speed_rows = np.vstack([bm, _speed_hull(bm, h, SPEED_SUBSTEPS)])
    speed_rows = speed_rows[free(speed_rows)]
    fixed_rows.append(rows(v * speed_rows, isp, -limits.speed))
    fixed_rhs.append(np.full(speed_rows.shape[0], -v * start[1]))
    eye = np.eye(n + 1)[1:n]
    for sign in (1.0, -1.0):
        fixed_rows.append(rows(sign * v * v * eye, ia,
                               -(limits.acceleration or limits.torque_acceleration)))
        fixed_rhs.append(np.zeros(n - 1))
    diff = (np.eye(n + 1, k=1) - np.eye(n + 1))[:n] / h[:, None]    # Δθ″/h per step
    scale = v ** 3 / limits.jerk
    for sign in (1.0, -1.0):
        fixed_rows.append(rows(sign * scale * diff, ij, -1.0))
        fixed_rhs.append(np.zeros(n))
        fixed_rows.append(rows(sign * scale * diff, col_e=-np.eye(n)))
        fixed_rhs.append(np.zeros(n))
    a_fixed = csr_matrix(np.vstack(fixed_rows))
    b_fixed = np.concatenate(fixed_rhs)

    def solve(theta_k: FloatArray, d1_k: FloatArray) -> tuple[FloatArray, float]:
        """The knot values of θ″ with the torque linearised about θ_k, θ′_k (closed to the end
        states), and t."""
        k_alpha, k_omega, g = torque_terms(theta_k)
        # T = v² k_α x + v² k_ω (2 p θ′ − p²) + g, θ′ = θ′0 + B x
        lin = v * v * (np.diag(k_alpha) + (2.0 * k_omega * d1_k)[:, None] * bm)
        const = v * v * k_omega * (2.0 * d1_k * start[1] - d1_k ** 2) + g
        lin, const = lin[1:n], const[1:n]         # the interior knots (the ends are given)
        torque_rows = [rows(lin, itq, -MARGIN * limits.torque),
                       rows(-lin, itq, -MARGIN * limits.torque)]
        a_ub = vstack([a_fixed, csr_matrix(np.vstack(torque_rows))])
        b_ub = np.concatenate([b_fixed, -const, const])
        # scipy-stubs type A_ub as dense only; HiGHS takes a sparse matrix (documented,
        # scipy/optimize/_linprog_highs.py: issparse)
        res = linprog(cost, A_ub=a_ub, b_ub=b_ub,  # type: ignore[call-overload]
                      A_eq=eq, b_eq=eq_rhs, bounds=bounds, method='highs')
        if res.status != 0 or res.x is None:
            raise CamPlanningError(f'out-of-soil arc of {length:.6g} m: the linear programme '
                                   f'failed ({res.message})')
        x_new = np.array(res.x[:n + 1], dtype=np.float64)
        x_new[0], x_new[n] = start[2], end[2]
        return _close(x_new, h, start, end), float(res.x[it])

    x, t = solve(*_quintic_guess(ends, knots))
    for _ in range(LINEARISATIONS - 1):
        x_new, t = solve(*_integrate(x, h, start[0], start[1]))
        done = np.max(np.abs(x_new - x)) <= 1e-9 * max(np.max(np.abs(x)), 1.0)
        x = x_new
        if done:
            break
    th, d1 = _integrate(x, h, start[0], start[1])
    coeffs = np.column_stack([th[:-1], d1[:-1], 0.5 * x[:-1], (x[1:] - x[:-1]) / (6.0 * h)])
    if not np.all(np.isfinite(coeffs)):
        raise CamPlanningError(f'out-of-soil arc of {length:.6g} m: non-finite result')
    return Piecewise(knots, coeffs), t


def straight_arc(ends: ArcEnds) -> Piecewise | None:
    """The arc when both ends already lie on one straight line θ = θ0 + θ′·s (constant speed):
    one linear piece, or None if they do not (to round-off)."""
    length, start, end = ends.length, ends.start, ends.end
    rate = start[1]
    if start[2] != 0.0 or end[2] != 0.0 or end[1] != rate:
        return None
    if not math.isclose(start[0] + rate * length, end[0], rel_tol=0.0,
                        abs_tol=1e-12 * max(1.0, abs(end[0]))):
        return None
    return Piecewise([0.0, length], [[start[0], (end[0] - start[0]) / length]])
