"""A plant's hole and tilt from the motion the machine measured through its in-soil arc.

The constant-ratio model (`Planting.tip_sweep`, `Planting.tilt` of the advance v/ω at the
planting instant) holds while the shaft and the ground keep their speeds through the arc. An
electronic cam (planter_ros.cam) shapes the shaft's speed inside each revolution, and a drive
can lag its targets: then only the motion itself tells where the tip went. For a plant at shaft
angle θ_k (instant t_k, travelled distance s_k) the tip, relative to the soil, is at

    x(φ) = x_path(φ) + s(t(θ_k + φ)) − s_k,     φ from −entry_angle to +exit_angle,

x_path the mechanism's tip path relative to its planting point (`Planting.tip_path`), t(θ) the
measured shaft angle's inverse (between two joint samples: the cubic Hermite through both
angles and both measured speeds; linear where a speed is missing), s(t) the travelled distance
(the trapezoid integral of the measured ground speed, as for the plant's position). The
Hermite is used where it is monotone (the Fritsch–Carlson bound α² + β² ≤ 9 on the speeds
against the chord), so both directions, θ(t) and t(θ), are the same curve. Then

* tip sweep = max x − min x over the arc (ARC_SAMPLES instants equally spaced from the soil
  entry to the exit, each interior extreme refined by the parabola through its neighbours);
* tilt = atan2(slip, D) with slip = s(t_exit) − s_k − A_r·exit_angle: the nozzle's travel
  against the soil while it climbs out, beyond what the synchronous path does (A_r the release
  advance; kinematics.planting explains the tilt model).

At constant speeds both reduce to the constant-ratio figures: to 1e-15 m where the extremes
are the arc's ends, to 1e-7 m where one is inside it (λ > 1; a test holds both).

The arc is followed only where the measurement covers it: every point of it lies between two
joint samples and between two ground-speed samples no more than `max_input_gap` apart, and the
shaft reaches the soil exit no later than `max_input_gap` after the planting instant. Elsewhere
(the recording ends or starts inside the arc, a gap, a shaft stopped in the soil) the plant
keeps the constant-ratio figures at its instant; `covered` says which. The live monitor
(`PlantPredictor`) applies the same rule sample by sample, so both give the same plants.
Pure numpy: no ROS.
"""

import numpy as np

from planter_ros.kinematics.planting import Planting

__all__ = ['ARC_SAMPLES', 'arc_figures', 'angle_at', 'time_at_angle', 'distance_at']

ARC_SAMPLES = 33          # instants along the in-soil arc, equally spaced in time (129: 2.5x
#                           the time for an interior extreme 5x closer, 0.09 -> 0.02 µm)
_NEWTON_STEPS = 8


def _intervals(jt: np.ndarray, theta: np.ndarray, jw: np.ndarray,
               i: np.ndarray) -> tuple[np.ndarray, ...]:
    """The joint-sample intervals ending at indices `i`: t0, h, θ0, Δθ, the Hermite's end
    slopes in rad per unit interval, and whether the Hermite is used there."""
    t0, h = jt[i - 1], jt[i] - jt[i - 1]
    th0, dth = theta[i - 1], theta[i] - theta[i - 1]
    w0, w1 = jw[i - 1], jw[i]
    m0, m1 = w0 * h, w1 * h
    with np.errstate(invalid='ignore', divide='ignore'):
        a, b = m0 / dth, m1 / dth
        hermite = (np.isfinite(w0) & np.isfinite(w1) & (w0 > 0) & (w1 > 0) & (dth > 0)
                   & (a * a + b * b <= 9.0))
    return t0, h, th0, dth, np.where(hermite, m0, 0.0), np.where(hermite, m1, 0.0), hermite


def _cubic(u: np.ndarray, dth: np.ndarray, m0: np.ndarray,
           m1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The unit-interval Hermite's rise from θ0 at u, and its slope d/du."""
    u2, u3 = u * u, u * u * u
    f = (-2 * u3 + 3 * u2) * dth + (u3 - 2 * u2 + u) * m0 + (u3 - u2) * m1
    df = (-6 * u2 + 6 * u) * dth + (3 * u2 - 4 * u + 1) * m0 + (3 * u2 - 2 * u) * m1
    return f, df


def angle_at(t: np.ndarray, jt: np.ndarray, theta: np.ndarray,
             jw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The measured shaft angle (rad) at instants `t` (s) from joint samples (jt s, non-
    decreasing angle `theta` rad, speeds `jw` rad/s, NaN = not measured), and the length of
    the joint-sample interval each fell in (s; inf outside the samples)."""
    t = np.asarray(t, dtype=float)
    i = np.searchsorted(jt, t, side='right')
    inside = (i >= 1) & (i < jt.size)
    i = np.clip(i, 1, jt.size - 1)
    t0, h, th0, dth, m0, m1, hermite = _intervals(jt, theta, jw, i)
    u = (t - t0) / h
    rise, _ = _cubic(u, dth, m0, m1)
    return th0 + np.where(hermite, rise, u * dth), np.where(inside, h, np.inf)


def time_at_angle(angle: np.ndarray, jt: np.ndarray, theta: np.ndarray,
                  jw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The instant (s) the measured shaft angle reached each `angle` (the inverse of
    `angle_at`), and the length of the joint-sample interval it fell in (s; inf outside)."""
    angle = np.asarray(angle, dtype=float)
    i = np.searchsorted(theta, angle, side='left')
    inside = (i >= 1) & (i < theta.size)
    i = np.clip(i, 1, theta.size - 1)
    t0, h, th0, dth, m0, m1, hermite = _intervals(jt, theta, jw, i)
    target = angle - th0
    with np.errstate(divide='ignore', invalid='ignore'):
        u = np.clip(np.where(dth > 0, target / dth, 0.0), 0.0, 1.0)
    if np.any(hermite):
        v = u[hermite]
        d, a, b, y = dth[hermite], m0[hermite], m1[hermite], target[hermite]
        for _ in range(_NEWTON_STEPS):
            f, df = _cubic(v, d, a, b)
            with np.errstate(divide='ignore', invalid='ignore'):
                v = np.clip(v - np.where(df > 0, (f - y) / df, 0.0), 0.0, 1.0)
        u[hermite] = v
    return t0 + u * h, np.where(inside, h, np.inf)


def distance_at(t: np.ndarray, st: np.ndarray, sv: np.ndarray,
                ss: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Travelled distance (m) at instants `t` from speed samples (st s, sv m/s, ss their
    trapezoid distance), and the length of the speed-sample interval each fell in (s; inf
    outside the samples)."""
    t = np.asarray(t, dtype=float)
    j = np.searchsorted(st, t, side='right')
    inside = (j >= 1) & (j < st.size) & np.isfinite(t)
    j = np.clip(j, 1, st.size - 1)
    t0, t1, v0, v1 = st[j - 1], st[j], sv[j - 1], sv[j]
    with np.errstate(invalid='ignore'):
        g = (t - t0) / (t1 - t0)
        v = v0 + g * (v1 - v0)
        s = ss[j - 1] + 0.5 * (v0 + v) * (t - t0)
    return s, np.where(inside, t1 - t0, np.inf)


def arc_figures(model: Planting, theta_k: np.ndarray, jt: np.ndarray, theta: np.ndarray,
                jw: np.ndarray, st: np.ndarray, sv: np.ndarray, ss: np.ndarray,
                max_input_gap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tip sweep (m), tilt (rad) and whether the measurement covers the arc, for plants at
    shaft angles `theta_k` of one planting model, from the row's joint samples (jt s, running-
    maximum angle `theta` rad, speeds jw rad/s) and speed samples (st s, sv m/s, ss m). Where
    not covered the figures are NaN (the caller keeps its own)."""
    theta_k = np.asarray(theta_k, dtype=float)
    n = theta_k.size
    sweep, tilt = np.full(n, np.nan), np.full(n, np.nan)
    if n == 0 or theta.size < 2 or st.size < 2:
        return sweep, tilt, np.zeros(n, dtype=bool)
    # times relative to the first joint sample: epoch stamps (1.7e9 s) keep 0.24 µs only
    ref = jt[0]
    jt, st = jt - ref, st - ref
    # the soil entry, the planting instant and the soil exit
    ends = np.column_stack((theta_k - model.entry_angle, theta_k, theta_k + model.exit_angle))
    t_ends, end_gaps = time_at_angle(ends, jt, theta, jw)
    fraction = np.linspace(0.0, 1.0, ARC_SAMPLES)
    t = t_ends[:, :1] + (t_ends[:, 2:] - t_ends[:, :1]) * fraction
    t[:, -1] = t_ends[:, 2]
    angle, joint_gap = angle_at(t, jt, theta, jw)
    s, speed_gap = distance_at(np.column_stack((t_ends[:, 1], t)), st, sv, ss)
    covered = ((theta[-1] >= ends[:, 2])
               & np.all(end_gaps <= max_input_gap, axis=1)
               & np.all(joint_gap <= max_input_gap, axis=1)
               & np.all(speed_gap <= max_input_gap, axis=1)
               & (t_ends[:, 2] - t_ends[:, 1] <= max_input_gap))
    if not np.any(covered):
        return sweep, tilt, covered
    phi = angle[covered] - theta_k[covered, None]
    phi[:, 0], phi[:, -1] = -model.entry_angle, model.exit_angle    # the ends exactly
    x_path, _ = model.tip_path(phi)
    s0, s_arc = s[covered, :1], s[covered, 1:]
    x = np.asarray(x_path, dtype=float) + (s_arc - s0)
    sweep[covered] = _extreme(x, np.argmax(x, axis=1), +1) - _extreme(x, np.argmin(x, axis=1),
                                                                      -1)
    slip = s_arc[:, -1] - s0[:, 0] - model.release_advance * model.exit_angle
    tilt[covered] = np.arctan2(slip, model.depth)
    return sweep, tilt, covered


def _extreme(x: np.ndarray, k: np.ndarray, sign: int) -> np.ndarray:
    """Each row's extreme at sample k, refined by the parabola through k−1, k, k+1 (equal
    steps in time; x is smooth in time where the Hermite is) where k is interior."""
    rows = np.arange(x.shape[0])
    value = x[rows, k]
    interior = (k > 0) & (k < x.shape[1] - 1)
    kc = np.clip(k, 1, x.shape[1] - 2)
    a, b, c = x[rows, kc - 1], x[rows, kc], x[rows, kc + 1]
    curvature = a - 2 * b + c
    with np.errstate(divide='ignore', invalid='ignore'):
        peak = b - (c - a) ** 2 / (8 * curvature)
    refined = interior & (sign * curvature < 0) & np.isfinite(peak)
    return np.where(refined, peak, value)

