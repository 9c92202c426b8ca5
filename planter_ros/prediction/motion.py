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
(the trapezoid integral of the measured ground speed, as for the plant's position). Then

* tip sweep = max x − min x over the arc (sampled at ARC_SAMPLES points, each interior extreme
  refined by the parabola through its neighbours);
* tilt = atan2(slip, D) with slip = s(t_exit) − s_k − A_r·exit_angle: the nozzle's travel
  against the soil while it climbs out, beyond what the synchronous path does (A_r the release
  advance; kinematics.planting explains the tilt model).

At constant speeds both reduce to the constant-ratio figures (a test holds them to 1e-9 m).

The arc is followed only where the measurement covers it: every point of it lies between two
joint samples and between two ground-speed samples no more than `max_input_gap` apart, and the
shaft reaches the soil exit no later than `max_input_gap` after the planting instant. Elsewhere
(the recording ends or starts inside the arc, a gap, a shaft stopped in the soil) the plant
keeps the constant-ratio figures at its instant; `covered` says which. The live monitor
(`PlantPredictor`) applies the same rule sample by sample, so both give the same plants.
Pure numpy: no ROS.
"""

from functools import lru_cache

import numpy as np

from planter_ros.kinematics.planting import Planting

__all__ = ['ARC_SAMPLES', 'arc_figures', 'time_at_angle', 'distance_at']

ARC_SAMPLES = 257          # points along the in-soil arc, equally spaced in φ
_NEWTON_STEPS = 6


@lru_cache(maxsize=64)
def _arc(model: Planting) -> tuple[np.ndarray, np.ndarray]:
    """The arc's shaft angles φ from the planting instant and the tip's x_path there."""
    phi = np.linspace(-model.entry_angle, model.exit_angle, ARC_SAMPLES)
    x, _ = model.tip_path(phi)
    return phi, np.asarray(x, dtype=float)


def time_at_angle(angle: np.ndarray, jt: np.ndarray, theta: np.ndarray,
                  jw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The instant (s) the non-decreasing measured shaft angle `theta` (rad, at times `jt`,
    speeds `jw` rad/s, NaN = not measured) reached each `angle`, and the length of the
    joint-sample interval it fell in (s; inf outside the samples). Cubic Hermite between two
    samples with both speeds measured and positive; linear otherwise."""
    angle = np.asarray(angle, dtype=float)
    i = np.searchsorted(theta, angle, side='left')
    inside = (i >= 1) & (i < theta.size)
    i = np.clip(i, 1, theta.size - 1)
    t0, t1 = jt[i - 1], jt[i]
    th0, th1 = theta[i - 1], theta[i]
    h = t1 - t0
    dth = th1 - th0
    with np.errstate(divide='ignore', invalid='ignore'):
        u = np.where(dth > 0, (angle - th0) / dth, 0.0)
    u = np.clip(u, 0.0, 1.0)
    w0, w1 = jw[i - 1], jw[i]
    hermite = np.isfinite(w0) & np.isfinite(w1) & (w0 > 0) & (w1 > 0) & (dth > 0)
    if np.any(hermite):
        # θ(u) = th0 + dth·(h00'...) in the unit interval: m0, m1 the slopes in rad per unit
        m0, m1 = w0 * h, w1 * h
        target = angle - th0
        v = u.copy()
        for _ in range(_NEWTON_STEPS):
            v2, v3 = v * v, v * v * v
            f = (-2 * v3 + 3 * v2) * dth + (v3 - 2 * v2 + v) * m0 + (v3 - v2) * m1 - target
            df = (-6 * v2 + 6 * v) * dth + (3 * v2 - 4 * v + 1) * m0 + (3 * v2 - 2 * v) * m1
            with np.errstate(divide='ignore', invalid='ignore'):
                step = np.where(df > 0, f / df, 0.0)
            v = np.clip(v - step, 0.0, 1.0)
        # a Hermite that is not monotone here (speeds far from the chord's): the chord
        v2 = v * v
        slope = (-6 * v2 + 6 * v) * dth + (3 * v2 - 4 * v + 1) * m0 + (3 * v2 - 2 * v) * m1
        u = np.where(hermite & (slope > 0), v, u)
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
    phi, x_path = _arc(model)
    # times relative to the first joint sample: epoch stamps (1.7e9 s) keep 0.24 µs only
    ref = jt[0]
    jt, st = jt - ref, st - ref
    # the instant itself through the same interpolation as the arc (the slip is relative)
    angles = np.column_stack((theta_k, theta_k[:, None] + phi))
    t, joint_gap = time_at_angle(angles, jt, theta, jw)
    s, speed_gap = distance_at(t, st, sv, ss)
    covered = ((theta[-1] >= theta_k + model.exit_angle)
               & np.all(joint_gap <= max_input_gap, axis=1)
               & np.all(speed_gap <= max_input_gap, axis=1)
               & (t[:, -1] - t[:, 0] <= max_input_gap))
    if not np.any(covered):
        return sweep, tilt, covered
    s0, s_arc = s[covered, :1], s[covered, 1:]
    x = x_path + (s_arc - s0)
    sweep[covered] = _extreme(x, np.argmax(x, axis=1), +1) - _extreme(x, np.argmin(x, axis=1),
                                                                      -1)
    slip = s_arc[:, -1] - s0[:, 0] - model.release_advance * model.exit_angle
    tilt[covered] = np.arctan2(slip, model.depth)
    return sweep, tilt, covered


def _extreme(x: np.ndarray, k: np.ndarray, sign: int) -> np.ndarray:
    """Each row's extreme at sample k, refined by the parabola through k−1, k, k+1 (equal
    steps in φ) where k is interior."""
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

