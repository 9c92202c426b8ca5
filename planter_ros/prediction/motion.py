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

`arc_figures` follows the arcs of many groups of plants at once (the rows of a machine, the
designs in force): a few small arrays per row would cost numpy's call overhead many times
over, so the groups' samples are concatenated and every step but the search of each group's
own samples runs once over all plants; a plant's figures depend on its own row's samples
alone. Pure numpy: no ROS.
"""

from collections.abc import Sequence
from typing import Literal, NamedTuple

import numpy as np

from planter_ros.kinematics.planting import Planting

__all__ = ['ARC_SAMPLES', 'Motion', 'arc_figures']

ARC_SAMPLES = 33          # instants along the in-soil arc, equally spaced in time (129: 2.5x
#                           the time for an interior extreme 5x closer, 0.09 -> 0.02 µm)
_NEWTON_STEPS = 8


class Motion(NamedTuple):
    """A row's measured motion as the arcs read it: joint samples (jt s, running-maximum shaft
    angle theta rad, speeds jw rad/s, NaN = not measured) and speed samples (st s, sv m/s, ss
    their trapezoid distance m)."""

    jt: np.ndarray
    theta: np.ndarray
    jw: np.ndarray
    st: np.ndarray
    sv: np.ndarray
    ss: np.ndarray


def _locate(samples: Sequence[np.ndarray], queries: Sequence[np.ndarray],
            side: Literal['left', 'right']) -> tuple[np.ndarray, np.ndarray]:
    """Each group's queries (`queries[g]`) among its sorted samples (`samples[g]`): the sample
    interval each falls in, as the index of the interval's end in the concatenation of
    `samples` (clipped to the group's first and last interval), and whether the query lies
    inside the samples; both concatenated in group order."""
    index, inside, offset = [], [], 0
    for x, q in zip(samples, queries):
        i = np.searchsorted(x, q, side=side)
        inside.append((i >= 1) & (i < x.size))
        index.append(np.clip(i, 1, x.size - 1) + offset)
        offset += x.size
    return np.concatenate(index), np.concatenate(inside)


def _intervals(jt: np.ndarray, theta: np.ndarray, jw: np.ndarray,
               i: np.ndarray) -> tuple[np.ndarray, ...]:
    """The joint-sample intervals ending at indices `i`: t0, h, θ0, Δθ, the Hermite's end
    slopes in rad per unit interval, and whether the Hermite is used there."""
    k = i - 1
    t0, th0, w0 = jt[k], theta[k], jw[k]
    h, dth, w1 = jt[i] - t0, theta[i] - th0, jw[i]
    m0, m1 = w0 * h, w1 * h
    with np.errstate(invalid='ignore', divide='ignore'):
        a, b = m0 / dth, m1 / dth
        hermite = (np.isfinite(w0) & np.isfinite(w1) & (w0 > 0) & (w1 > 0) & (dth > 0)
                   & (a * a + b * b <= 9.0))
    return t0, h, th0, dth, np.where(hermite, m0, 0.0), np.where(hermite, m1, 0.0), hermite


def _rise(u: np.ndarray, dth: np.ndarray, m0: np.ndarray, m1: np.ndarray) -> np.ndarray:
    """The unit-interval Hermite's rise from θ0 at u."""
    u2, u3 = u * u, u * u * u
    rise: np.ndarray = (-2 * u3 + 3 * u2) * dth + (u3 - 2 * u2 + u) * m0 + (u3 - u2) * m1
    return rise


def _cubic(u: np.ndarray, dth: np.ndarray, m0: np.ndarray,
           m1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The unit-interval Hermite's rise from θ0 at u, and its slope d/du."""
    u2 = u * u
    df = (-6 * u2 + 6 * u) * dth + (3 * u2 - 4 * u + 1) * m0 + (3 * u2 - 2 * u) * m1
    return _rise(u, dth, m0, m1), df


def _angle_at(t: np.ndarray, i: np.ndarray, jt: np.ndarray, theta: np.ndarray,
              jw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The measured shaft angle (rad) at instants `t` (s) in the joint-sample intervals ending
    at `i` (of samples jt s, non-decreasing angle `theta` rad, speeds `jw` rad/s, NaN = not
    measured), and the length of each interval (s)."""
    t0, h, th0, dth, m0, m1, hermite = _intervals(jt, theta, jw, i)
    u = (t - t0) / h
    return th0 + np.where(hermite, _rise(u, dth, m0, m1), u * dth), h


def _time_at_angle(angle: np.ndarray, i: np.ndarray, jt: np.ndarray, theta: np.ndarray,
                   jw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The instant (s) the measured shaft angle reached each `angle` in the joint-sample
    intervals ending at `i` (the inverse of `_angle_at`), and the length of each interval (s)."""
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
    return t0 + u * h, h


def _distance_at(t: np.ndarray, j: np.ndarray, st: np.ndarray, sv: np.ndarray,
                 ss: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Travelled distance (m) at instants `t` in the speed-sample intervals ending at `j` (of
    samples st s, sv m/s, ss their trapezoid distance), and the length of each interval (s)."""
    t0, t1, v0, v1 = st[j - 1], st[j], sv[j - 1], sv[j]
    with np.errstate(invalid='ignore'):
        g = (t - t0) / (t1 - t0)
        v = v0 + g * (v1 - v0)
        s = ss[j - 1] + 0.5 * (v0 + v) * (t - t0)
    return s, t1 - t0


def arc_figures(arcs: Sequence[tuple[Planting, np.ndarray, Motion]],
                max_input_gap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tip sweep (m), tilt (rad) and whether the measurement covers the arc, for the plants of
    each (planting model, shaft angles θ_k of its plants, the row's Motion) in `arcs`: the rows
    of a machine and the designs in force, all in one pass over their concatenated arrays (a
    plant's figures depend on its own row's samples alone). The three arrays follow `arcs`:
    its first entry's plants, then the next one's. Where not covered the figures are NaN (the
    caller keeps its own)."""
    sizes = np.array([np.size(theta_k) for _, theta_k, _ in arcs], dtype=np.intp)
    n = int(sizes.sum())
    sweep, tilt, covered = np.full(n, np.nan), np.full(n, np.nan), np.zeros(n, dtype=bool)
    usable = np.array([size > 0 and motion.theta.size >= 2 and motion.st.size >= 2
                       for size, (_, _, motion) in zip(sizes, arcs)], dtype=bool)
    if not np.any(usable):
        return sweep, tilt, covered
    groups = [arc for arc, ok in zip(arcs, usable) if ok]
    count = sizes[usable]
    cuts = np.cumsum(count)[:-1]
    models = [model for model, _, _ in groups]
    motions = [motion for _, _, motion in groups]

    def per_plant(values: list[float]) -> np.ndarray:
        return np.repeat(np.asarray(values, dtype=float), count)

    theta_k = np.concatenate([np.asarray(t, dtype=float) for _, t, _ in groups])
    # times relative to each row's first joint sample: epoch stamps (1.7e9 s) keep 0.24 µs only
    jts = [m.jt - m.jt[0] for m in motions]
    sts = [m.st - m.jt[0] for m in motions]
    jt, st = np.concatenate(jts), np.concatenate(sts)
    theta, jw = (np.concatenate(c) for c in ([m.theta for m in motions],
                                             [m.jw for m in motions]))
    sv, ss = (np.concatenate(c) for c in ([m.sv for m in motions], [m.ss for m in motions]))
    entry, exit_ = per_plant([m.entry_angle for m in models]), per_plant([m.exit_angle
                                                                          for m in models])
    # the soil entry, the planting instant and the soil exit
    ends = np.column_stack((theta_k - entry, theta_k, theta_k + exit_))
    i, inside = _locate([m.theta for m in motions], np.split(ends, cuts), 'left')
    t_ends, h = _time_at_angle(ends, i, jt, theta, jw)
    end_known = inside & (h <= max_input_gap)     # in a joint-sample interval short enough
    fraction = np.linspace(0.0, 1.0, ARC_SAMPLES)
    t = t_ends[:, :1] + (t_ends[:, 2:] - t_ends[:, :1]) * fraction
    t[:, -1] = t_ends[:, 2]
    i, inside = _locate(jts, np.split(t, cuts), 'right')
    angle, h = _angle_at(t, i, jt, theta, jw)
    joint_known = inside & (h <= max_input_gap)
    at = np.column_stack((t_ends[:, 1], t))
    j, inside = _locate(sts, np.split(at, cuts), 'right')
    s, h = _distance_at(at, j, st, sv, ss)
    speed_known = inside & np.isfinite(at) & (h <= max_input_gap)
    ok = ((per_plant([m.theta[-1] for m in motions]) >= ends[:, 2])
          & np.all(end_known, axis=1) & np.all(joint_known, axis=1)
          & np.all(speed_known, axis=1)
          & (t_ends[:, 2] - t_ends[:, 1] <= max_input_gap))
    covered[np.repeat(usable, sizes)] = ok
    if not np.any(ok):
        return sweep, tilt, covered
    phi = angle[ok] - theta_k[ok, None]
    phi[:, 0], phi[:, -1] = -entry[ok], exit_[ok]                 # the ends exactly
    x_path = _tip_x(models, np.repeat(np.arange(len(models)), count)[ok], phi)
    s0, s_arc = s[ok, :1], s[ok, 1:]
    x = x_path + (s_arc - s0)
    sweep[covered] = (_extreme(x, np.argmax(x, axis=1), +1)
                      - _extreme(x, np.argmin(x, axis=1), -1))
    slip = (s_arc[:, -1] - s0[:, 0]
            - per_plant([m.release_advance * m.exit_angle for m in models])[ok])
    tilt[covered] = np.arctan2(slip, per_plant([m.depth for m in models])[ok])
    return sweep, tilt, covered


def _tip_x(models: Sequence[Planting], group: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """The tip path's x (m) at shaft angles `phi` (rad, a row of them per plant) from the
    planting instant, each row by the model of its group (`models[group[row]]`), each distinct
    model called once."""
    distinct: dict[int, tuple[Planting, list[int]]] = {}
    for k, model in enumerate(models):
        distinct.setdefault(id(model), (model, []))[1].append(k)
    if len(distinct) == 1:
        return np.asarray(models[0].tip_x(phi), dtype=float)
    x = np.empty(phi.shape)
    for model, ks in distinct.values():
        rows = np.isin(group, ks)
        x[rows] = model.tip_x(phi[rows])
    return x


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
    extreme: np.ndarray = np.where(refined, peak, value)
    return extreme
