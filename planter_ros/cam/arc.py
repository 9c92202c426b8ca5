"""The out-of-soil arc: θ(s) between two given states (θ, θ′, θ″) over a given distance, C2 at
both ends, with the smallest peak load.

The arc's θ″ is piecewise linear on `pieces` equal steps (so θ is a C2 piecewise cubic and θ‴
is constant per step). Its knot values are the unknowns of a linear programme (scipy HiGHS):

    minimise   t + w·(peak jerk + peak torque + peak acceleration utilisations)
                 + a small multiple of the mean jerk utilisation (the total variation of θ″,
                 which picks the smoothest of the profiles with the same peaks)
    subject to θ″ at both ends as given; θ′ and θ at the far end as given (two equalities);
               v·θ′ ≤ t·ω_max at every knot; θ′ ≥ 0 everywhere (its Bernstein coefficients
               on each step ≥ 0: no reversing);
               v²·|θ″| ≤ p_α·α_max at every knot (α_max: the acceleration limit, or without
               one the torque-limited acceleration, then only a scale: p_α ≤ t is dropped);
               v³·|Δθ″/h| ≤ p_j·j_max on every step;
               |T_m| ≤ p_T·T_peak at every knot, T_m = k_α(θ)·v²θ″ + k_ω(θ)·v²θ′² + g(θ)
               linearised about the previous solution (θ′² ≈ 2pθ′ − p², k(θ) at its θ),
               repeated a few times;  p_α, p_j, p_T ≤ t;

so t is the largest utilisation of any limit at the top speed v, made as small as possible, and
where the ends already force t (the in-soil speed, say) each limit's own peak still is. The
end equalities are then closed to round-off by a 2×2 correction of two interior knots.
"""

import math

import numpy as np

from .errors import CamPlanningError
from .piecewise import Piecewise

__all__ = ['plan_arc', 'ARC_PIECES']

ARC_PIECES = 64
LINEARISATIONS = 4
MARGIN = 0.998               # the programme keeps this far inside the limits (knots only)
PEAK_WEIGHT = 0.05           # weight of each limit's own peak against the largest one
SMOOTHING = 1e-3             # weight of the mean jerk utilisation (total variation of θ″)


def _integrals(n, h):
    """Matrices B, C with θ′_j = θ′_0 + B[j]·x and θ_j = θ_0 + θ′_0·s_j + C[j]·x for knot
    values x of θ″ (piecewise linear)."""
    b = np.zeros((n + 1, n + 1))
    c = np.zeros((n + 1, n + 1))
    for j in range(1, n + 1):
        c[j] = c[j - 1] + h * b[j - 1]
        c[j, j - 1] += h * h / 3.0
        c[j, j] += h * h / 6.0
        b[j] = b[j - 1]
        b[j, j - 1] += 0.5 * h
        b[j, j] += 0.5 * h
    return b, c


def _integrate(x, h, theta0, d0):
    """θ and θ′ at the knots from the knot values of θ″ (the cubic pieces' own recurrence)."""
    n = x.size - 1
    th = np.empty(n + 1)
    d1 = np.empty(n + 1)
    th[0], d1[0] = theta0, d0
    for j in range(n):
        th[j + 1] = th[j] + d1[j] * h + h * h * (x[j] / 3.0 + x[j + 1] / 6.0)
        d1[j + 1] = d1[j] + 0.5 * h * (x[j] + x[j + 1])
    return th, d1


def _close(x, h, start, end):
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


def _quintic_guess(length, start, end, knots):
    """θ, θ′ at the knots of the quintic that meets both end states (the first linearisation
    point of the torque)."""
    from scipy.interpolate import BPoly
    poly = BPoly.from_derivatives([0.0, length], [list(start), list(end)])
    return poly(knots), poly(knots, 1)


def plan_arc(length, start, end, speed, limits, torque_terms, pieces=ARC_PIECES):
    """A C2 arc of `length` (m) from state `start` to `end` ((θ, θ′, θ″) each), planned for
    ground speed `speed` (m/s) against `limits` (drive.EffectiveLimits); `torque_terms(θ)`
    gives (k_α, k_ω, g) of the motor torque. Returns (Piecewise over [0, length], t) with t the
    largest utilisation at the knots."""
    from scipy.optimize import linprog
    from scipy.sparse import csr_matrix, vstack

    n = int(pieces)
    h = length / n
    knots = h * np.arange(n + 1)
    bm, cm = _integrals(n, h)
    v = float(speed)
    # unknowns: x (θ″ at the knots), t (the largest utilisation), the peaks of jerk, torque
    # and (where limited) acceleration, e (each step's |jerk| / j_max, for the smoothing)
    it, ij, itq, ia = n + 1, n + 2, n + 3, n + 4
    ie = n + 5
    nv = ie + n
    cost = np.zeros(nv)
    cost[it] = 1.0
    cost[[ij, itq]] = PEAK_WEIGHT
    cost[ia] = PEAK_WEIGHT
    cost[ie:] = SMOOTHING / n
    eq = np.zeros((2, nv))
    eq[0, :n + 1] = bm[n]
    eq[1, :n + 1] = cm[n]
    eq_rhs = [end[1] - start[1], end[0] - start[0] - start[1] * length]
    bounds = [(None, None)] * (n + 1) + [(0.0, None)] * (4 + n)
    bounds[0] = (start[2], start[2])
    bounds[n] = (end[2], end[2])

    def rows(block_x, col=None, coef=None, col_e=None):
        m = block_x.shape[0]
        full = np.zeros((m, nv))
        full[:, :n + 1] = block_x
        if col is not None:
            full[:, col] = coef
        if col_e is not None:
            full[:, ie:] = col_e
        return full

    fixed_rows, fixed_rhs = [], []
    # each peak below t (the acceleration's only where it is a limit: without one it is
    # measured against the torque-limited acceleration, a scale for the objective)
    for col in (ij, itq, ia) if limits.acceleration else (ij, itq):
        r = np.zeros((1, nv))
        r[0, col], r[0, it] = 1.0, -1.0
        fixed_rows.append(r)
        fixed_rhs.append(np.zeros(1))
    # speed: v (θ′0 + B x) ≤ t ω_max ; no reversing: −(θ′0 + B x) ≤ 0
    fixed_rows.append(rows(v * bm, it, -MARGIN * limits.speed))
    fixed_rhs.append(np.full(n + 1, -v * start[1]))
    fixed_rows.append(rows(-bm))
    fixed_rhs.append(np.full(n + 1, start[1]))
    # ... and between them: on a step θ′ is a quadratic whose Bernstein coefficients are
    # θ′_i, θ′_i + h x_i / 2 and θ′_(i+1); all ≥ 0 keeps θ′ ≥ 0 over the whole step
    middle = bm[:-1] + 0.5 * h * np.eye(n + 1)[:-1]
    fixed_rows.append(rows(-middle))
    fixed_rhs.append(np.full(n, start[1]))
    eye = np.eye(n + 1)
    for sign in (1.0, -1.0):
        fixed_rows.append(rows(sign * v * v * eye, ia,
                               -MARGIN * (limits.acceleration or limits.torque_acceleration)))
        fixed_rhs.append(np.zeros(n + 1))
    diff = (np.eye(n + 1, k=1) - np.eye(n + 1))[:n] / h      # Δθ″/h per step
    scale = v ** 3 / limits.jerk
    for sign in (1.0, -1.0):
        fixed_rows.append(rows(sign * scale * diff, ij, -MARGIN))
        fixed_rhs.append(np.zeros(n))
        fixed_rows.append(rows(sign * scale * diff, col_e=-np.eye(n)))
        fixed_rhs.append(np.zeros(n))
    a_fixed = csr_matrix(np.vstack(fixed_rows))
    b_fixed = np.concatenate(fixed_rhs)

    theta_k, d1_k = _quintic_guess(length, start, end, knots)
    x = None
    for _ in range(LINEARISATIONS):
        k_alpha, k_omega, g = torque_terms(theta_k)
        # T = v² k_α x + v² k_ω (2 p θ′ − p²) + g, θ′ = θ′0 + B x
        lin = v * v * (np.diag(k_alpha) + (2.0 * k_omega * d1_k)[:, None] * bm)
        const = v * v * k_omega * (2.0 * d1_k * start[1] - d1_k ** 2) + g
        torque_rows = [rows(lin, itq, -MARGIN * limits.torque),
                       rows(-lin, itq, -MARGIN * limits.torque)]
        a_ub = vstack([a_fixed, csr_matrix(np.vstack(torque_rows))])
        b_ub = np.concatenate([b_fixed, -const, const])
        res = linprog(cost, A_ub=a_ub, b_ub=b_ub, A_eq=eq, b_eq=eq_rhs, bounds=bounds,
                      method='highs')
        if res.status != 0:
            raise CamPlanningError(f'out-of-soil arc of {length:.6g} m: the linear programme '
                                   f'failed ({res.message})')
        x_new = np.array(res.x[:n + 1])
        x_new[0], x_new[n] = start[2], end[2]
        x_new = _close(x_new, h, start, end)
        theta_new, d1_new = _integrate(x_new, h, start[0], start[1])
        done = x is not None and np.max(np.abs(x_new - x)) <= 1e-9 * max(np.max(np.abs(x)), 1.0)
        x, theta_k, d1_k = x_new, theta_new, d1_new
        if done:
            break
    th, d1 = _integrate(x, h, start[0], start[1])
    coeffs = np.column_stack([th[:-1], d1[:-1], 0.5 * x[:-1], (x[1:] - x[:-1]) / (6.0 * h)])
    if not np.all(np.isfinite(coeffs)):
        raise CamPlanningError(f'out-of-soil arc of {length:.6g} m: non-finite result')
    return Piecewise(knots, coeffs), float(res.x[it])


def straight_arc(length, start, end):
    """The arc when both ends already lie on one straight line θ = θ0 + θ′·s (constant speed):
    one linear piece, or None if they do not (to round-off)."""
    rate = start[1]
    if start[2] != 0.0 or end[2] != 0.0 or end[1] != rate:
        return None
    if not math.isclose(start[0] + rate * length, end[0], rel_tol=0.0,
                        abs_tol=1e-12 * max(1.0, abs(end[0]))):
        return None
    return Piecewise([0.0, length], [[start[0], (end[0] - start[0]) / length]])
