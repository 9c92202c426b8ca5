"""Per-plant predictions from what the machine measured: where each seedling went, how wide its
hole is and whether it stands upright.

Inputs are measurements, never commands: ground speed samples (t, v) and mechanism shaft samples
(t, θ unwrapped, ω) from drive feedback. A plant is set each time the shaft passes a planting
angle θ_k = phase + 2πk/n (n plants per revolution: the five-bar's bottom θ ≡ π, or each arm of
the three-arm at its lowest point). For each plant:

* position: travelled distance at that instant (trapezoid integral of the measured speed,
  interpolated), spacing to the previous plant and its error against the design spacing d;
* speed ratio λ = A0·ω/v with A0 the synchronous advance (five-bar: l2 - l1 = d/2π);
* tip sweep: the nozzle tip's swept horizontal extent below the soil line at depth D for the
  actual advance v/ω; the tip is a point, so the hole the soil sees is hole width = tip sweep +
  the nozzle's width along the row (the design's `nozzle_width`, a scene value);
* tilt: how far the stem is dragged from vertical by the nozzle's slip against the soil while
  it climbs out (positive = top leaning forward). Both come from the mechanism's planting
  geometry (kinematics.planting, which explains them); the assumptions are listed in
  doc/monitor_recording.md.
* upright: the stem's angle to the ground, π/2 - |tilt|, at least `upright_threshold`;
  and a rolling uprightness rate over the last N plants.

Gaps in the inputs: where two consecutive joint samples, or two consecutive accepted ground-speed
samples, are more than `max_input_gap` apart, little is known about what happened in between.
A planting instant inside such a gap is still reported (every instant is accounted for): the
shaft angle before and after the gap says how many instants there were; their time (from the
shaft angle) and position (from the travelled distance) are interpolated across the gap, the
plant is flagged `input_gap` = 1 and its λ, tip sweep, hole, tilt and upright are NaN (not
known). It has no spacing, and the first plant after a gap starts a new sequence: it has no
spacing (NaN), like the first plant of a stream. The rolling rate counts the known plants.

A new design (d, the mechanism's geometry) arriving at time t takes effect at the next planting
instant, as in the sync law: the first plant set after t (its crossing later than t) is the
old design's last — its spacing is scored against the old d — and every later plant is scored
and described with the new design; plants and positions go on across the change (no new
sequence). Several changes before that plant: the latest applies.

A row's section switched off and on again is a break like an input gap (prediction.sections).

`predict_plants` does a whole recording at once (vectorised), `predict_rows` the recordings of
all a machine's rows at once (replay: each row from its own inputs alone, the rows' measured
arcs in one pass over their concatenated samples); `PlantPredictor` does the same sample by
sample (the live monitor) with the same arithmetic, so both agree. The plants come as `Plants`
(prediction.plants); `planting_model_from_design` builds a design's planting
geometry. Pure numpy/scipy: no ROS here.
"""

from __future__ import annotations

import bisect
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
import math
from typing import NamedTuple, TypedDict, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planter_ros.config import check, setting
from planter_ros.design.model import Design, FiveBar, ThreeArm
from planter_ros.kinematics.arrays import FloatArray, Floats
from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.planting import TWO_PI, FiveBarPlanting, PathPlanting, Planting
from planter_ros.sensing.ground_speed_filter import (
    GroundSpeedFilter, GroundSpeedLimits, filter_ground_speed)

from .motion import Motion, arc_figures
from .plants import Plants
from .seedlings import INPUT_GAP, NO_SENSOR, UNKNOWN

__all__ = ['planting_model_from_design', 'prediction_notes', 'PredictionSettings',
           'clean_samples', 'travelled_distance', 'plant_values', 'predict_plants',
           'predict_rows', 'RowInputs', 'PlantPredictor']


# ----------------------------------------------------------------------------- the design

def planting_model_from_design(design: Design, nozzle_width: float | None = None) -> Planting:
    """Build the planting geometry of a typed design (planter_ros.design; SI units).

    five_bar: l1, l2, planting_depth, plant_spacing. three_arm: tip_path of one arm over one
    revolution, plants_per_revolution, planting_depth, plant_spacing, planting_phase.
    Every mechanism: the design's nozzle_width (m), the nozzle's width along the row, unless
    `nozzle_width` is given (it then replaces the design's: replay's override, a bag older than
    the field).
    """
    if nozzle_width is None:
        nozzle_width = design.nozzle_width
        if nozzle_width is None:
            raise DesignError('design', 'no nozzle_width', "key nozzle_width (m): the nozzle's "
                              'width along the row, a scene value')
    phase = design.planting_phase
    if isinstance(design, FiveBar):
        return FiveBarPlanting(design.l1, design.l2, design.planting_depth,
                               design.plant_spacing, math.pi if phase is None else float(phase),
                               nozzle_width)
    if not isinstance(design, ThreeArm):
        raise DesignError('mechanism', design.mechanism, 'five_bar or three_arm')
    path = design.tip_path
    return PathPlanting((path.angle, path.x, path.y), design.plants_per_revolution,
                        design.planting_depth, design.plant_spacing, phase,
                        nozzle_width=nozzle_width)


class PredictionNote(TypedDict):
    """Which plant fields a caveat is about, and the caveat in words."""

    fields: list[str]
    text: str


def prediction_notes(design: Design, model: Planting) -> list[PredictionNote]:
    """What the figures of this design mean where the model is not validated: a list of
    {fields, text} (empty for the five-bar the model was made for). Shown next to the figures
    by replay and the demo, and in their JSON."""
    notes: list[PredictionNote] = []
    mechanism = design.mechanism
    if mechanism != 'five_bar':
        notes.append({'fields': ['tilt', 'upright', 'uprightness_rate'],
                      'text': f"the tilt model (a duckbill holding the stem until it leaves "
                              f"the soil) is not validated for the {mechanism.replace('_', '-')}"
                              "'s pusher, which throws the seedling: read tilt and uprightness "
                              'as a kinematic slip indicator only'})
    ratio = model.release_advance / model.sync_advance
    if abs(ratio - 1.0) > 0.1:
        n = model.plants_per_revolution
        notes.append({'fields': ['tip_sweep', 'hole_width', 'tilt'],
                      'text': f'at planting the tip moves along the row at '
                              f'{model.release_advance:.3f} m/rad against the ground\'s '
                              f'{model.sync_advance:.3f} m/rad in sync: no slip would need a '
                              f'spacing of {TWO_PI * model.release_advance / n:.3f} m, so '
                              'every hole is wide and every plant leans'})
    return notes


# ----------------------------------------------------------------------------- settings

@dataclass(frozen=True)
class PredictionSettings:
    """User choices of the monitor (SI): parameters of the monitor node, recorded in its bags
    and read back by replay. No standard upright threshold is confirmed: the literature counts
    a seedling at < 30° to the ground as fallen, hence the default."""

    upright_threshold: float = setting(math.radians(30.0), "minimum stem angle to the ground "
                                       'for an upright plant; the literature counts < 30 deg as '
                                       'fallen, no standard value is confirmed', unit='rad',
                                       range=(0.0, 0.5 * math.pi))
    window: int = setting(20, 'plants in the rolling uprightness rate', range=(1, 10000))
    max_input_gap: float = setting(0.5, 'longest time between two ground-speed or two joint '
                                   'samples that is interpolated; a longer gap reports no plant '
                                   'inside it and the first plant after it has no spacing',
                                   unit='s', range=(0.01, 3600.0))
    measured_arc: bool = setting(True, "each plant's hole and tilt from the motion measured "
                                 'through its in-soil arc (prediction.motion); false: from the '
                                 'speed ratio at the planting instant alone, as monitors before '
                                 'this setting did')
    # which ground-speed samples to believe: the sync node's rule (spikes, NaN, too fast)
    speed_limits: GroundSpeedLimits = GroundSpeedLimits()

    def __post_init__(self) -> None:
        check(self, DesignError.from_message)


# ----------------------------------------------------------------------------- the model

def clean_samples(t: ArrayLike, *values: ArrayLike) -> tuple[FloatArray, ...]:
    """Drop samples with a non-finite time or first value, and samples whose time does not
    increase (out-of-order or repeated stamps). Both paths apply the same rule."""
    times = np.asarray(t, dtype=np.float64)
    columns = [np.asarray(v, dtype=np.float64) for v in values]
    ok = np.isfinite(times) & np.isfinite(columns[0])
    times = times[ok]
    columns = [v[ok] for v in columns]
    if times.size:
        prev_max = np.concatenate(([-np.inf], np.maximum.accumulate(times)[:-1]))
        keep = times > prev_max
        times = times[keep]
        columns = [v[keep] for v in columns]
    return (times, *columns)


def travelled_distance(t: FloatArray, v: FloatArray) -> FloatArray:
    """Trapezoid integral of the ground speed from the first sample (m)."""
    inc = 0.5 * (v[:-1] + v[1:]) * (t[1:] - t[:-1])
    return np.concatenate(([0.0], np.cumsum(inc)))


@overload
def _threshold(model: Planting, k: float) -> float: ...
@overload
def _threshold(model: Planting, k: FloatArray) -> FloatArray: ...
def _threshold(model: Planting, k: Floats) -> Floats:
    return model.planting_phase + k * (TWO_PI / model.plants_per_revolution)


def _first_k(model: Planting, theta0: float) -> int:
    """Smallest planting index k whose angle lies strictly beyond theta0."""
    n = model.plants_per_revolution
    k = math.floor((theta0 - model.planting_phase) * n / TWO_PI)
    while _threshold(model, k) > theta0:
        k -= 1
    while _threshold(model, k) <= theta0:
        k += 1
    return k


def _crossing(theta_k: Floats, before: tuple[Floats, Floats, Floats],
              after: tuple[Floats, Floats, Floats]) -> tuple[Floats, Floats]:
    """Instant and shaft speed where the running-maximum shaft angle reaches theta_k between
    two joint samples `before` and `after` (t s, running-maximum angle rad, speed rad/s)."""
    (t0, th0, w0), (t1, th1, w1) = before, after
    frac = (theta_k - th0) / (th1 - th0)
    t_e = t0 + frac * (t1 - t0)
    slope = (th1 - th0) / (t1 - t0)
    w = w0 + frac * (w1 - w0)
    omega = np.where(np.isfinite(w) & (w > 0), w, slope)
    return t_e, omega


def _at_speed(t_e: Floats, t0: Floats, t1: Floats, v0: Floats, v1: Floats,
              s0: Floats) -> tuple[Floats, Floats]:
    """Ground speed and travelled distance at t_e inside the speed sample interval [t0, t1)."""
    g = (t_e - t0) / (t1 - t0)
    v_e = v0 + g * (v1 - v0)
    s_e = s0 + 0.5 * (v0 + v_e) * (t_e - t0)
    return v_e, s_e


def plant_values(model: Planting, settings: PredictionSettings, omega: ArrayLike,
                 v: ArrayLike, arc_sweep: ArrayLike | None = None,
                 arc_tilt: ArrayLike | None = None
                 ) -> tuple[FloatArray, Floats, Floats, Floats, FloatArray]:
    """λ, tip sweep, hole width (tip sweep + the model's nozzle width), tilt and upright flag
    for arrays of shaft speed ω > 0 and ground speed v at the planting instants. The sweep and
    tilt of the measured arc (`arc_sweep`, `arc_tilt`: prediction.motion; NaN where the
    measurement does not cover it) replace the constant-ratio ones where given."""
    omega = np.asarray(omega, dtype=float)
    v = np.asarray(v, dtype=float)
    advance = v / omega
    with np.errstate(divide='ignore'):
        ratio = np.where(v != 0, model.sync_advance * omega / np.where(v != 0, v, 1.0), np.inf)
    sweep = model.tip_sweep(advance)
    tilt = model.tilt(advance)
    if arc_sweep is not None:
        measured_sweep = np.asarray(arc_sweep, float)
        measured_tilt = np.asarray(arc_tilt, float)
        covered = np.isfinite(measured_sweep) & np.isfinite(measured_tilt)
        sweep = np.where(covered, measured_sweep, sweep)
        tilt = np.where(covered, measured_tilt, tilt)
    upright = (0.5 * math.pi - np.abs(tilt) >= settings.upright_threshold).astype(float)
    return ratio, sweep, sweep + model.nozzle_width, tilt, upright


class RowInputs(NamedTuple):
    """One row's recorded inputs for `predict_rows`: ground speed samples (speed_t s, speed_v
    m/s) and shaft samples (joint_t s, joint_pos rad unwrapped, joint_vel rad/s: NaN or empty =
    not measured) on one clock, the row field of its plants, and the (start, end) times s
    across which its section was off."""

    speed_t: ArrayLike
    speed_v: ArrayLike
    joint_t: ArrayLike
    joint_pos: ArrayLike
    joint_vel: ArrayLike
    row: int = 0
    breaks: Sequence[tuple[float, float]] = ()


def predict_plants(inputs: RowInputs, model: Planting,
                   settings: PredictionSettings = PredictionSettings(),
                   speed_filter: bool = True,
                   changes: Sequence[tuple[float, Planting]] = ()) -> Plants:
    """All plants of one row's recording at once (vectorised): `predict_rows` of one row.
    `inputs`: times in s (same clock for both inputs), speeds m/s, shaft angle rad
    (unwrapped), shaft speed rad/s (NaN or empty = not measured), the row field of every plant
    and the (start, end) times across which the row's section was off (the first plant after
    one has no spacing, like after a gap in the inputs). `speed_filter` False takes speeds that
    already passed the plausibility rule (a row's speed from sensing.row_speed). `changes`:
    (time s, model) of each later design, in time order, each in force from the next planting
    instant after its time (module doc)."""
    return predict_rows([inputs], model, settings, speed_filter, changes)


def predict_rows(rows: Sequence[RowInputs], model: Planting,
                 settings: PredictionSettings = PredictionSettings(),
                 speed_filter: bool = True,
                 changes: Sequence[tuple[float, Planting]] = ()) -> Plants:
    """The plants of every row of a machine (RowInputs each; `model`, `changes`,
    `speed_filter` as in `predict_plants`, the same for every row): one Plants, the rows'
    plants one after the other in `rows` order, each row's in time order. Each row is
    predicted from its own inputs alone, as `predict_plants` of that row; the rows' measured
    arcs are followed in one pass (prediction.motion) and their plants assembled in one."""
    models = [model] + [m for _, m in changes]
    change_times = [t for t, _ in changes]
    found = [(inputs.row, one) for inputs in rows
             if (one := _instants(inputs, models, change_times, settings, speed_filter))
             is not None]
    if not found:
        return Plants.empty()
    parts = [one for _, one in found]
    arcs = (_measured_arcs([(one.motion, one.which, one.theta_k) for one in parts], models,
                           settings.max_input_gap)
            if settings.measured_arc else None)
    located = _Located([models[w] for one in parts for w in one.which],
                       np.concatenate([one.t_e for one in parts]),
                       np.concatenate([one.omega for one in parts]),
                       np.concatenate([one.v_e for one in parts]),
                       np.concatenate([one.s_e for one in parts]),
                       np.concatenate([one.in_gap for one in parts]),
                       np.concatenate([_after_gap(one.t_e, -np.inf, one.breaks)
                                       for one in parts]),
                       None if arcs is None else (np.concatenate([a[0] for a in arcs]),
                                                  np.concatenate([a[1] for a in arcs])))
    return _assemble(located, settings, _FIRST,
                     [(row, one.t_e.size) for row, one in found])


class _RowInstants(NamedTuple):
    """One row's planting instants located in its ground-speed samples, one entry per plant."""

    motion: Motion                   # the row's cleaned samples
    which: NDArray[np.intp]          # index into `models` of the design in force
    theta_k: FloatArray              # planting angle (rad)
    t_e: FloatArray                  # instant (s)
    omega: FloatArray                # shaft speed (rad/s)
    v_e: FloatArray                  # ground speed (m/s)
    s_e: FloatArray                  # travelled distance (m)
    in_gap: NDArray[np.bool_]        # inside an input gap
    breaks: FloatArray               # (start, end) rows: the input gaps and section breaks


def _instants(inputs: RowInputs, models: Sequence[Planting], change_times: Sequence[float],
              settings: PredictionSettings, speed_filter: bool) -> _RowInstants | None:
    """One row's planting instants (_RowInstants); None for a row without any."""
    joint_vel = np.asarray(inputs.joint_vel, dtype=float)
    if joint_vel.size != np.size(inputs.joint_t):
        joint_vel = np.full(np.size(inputs.joint_t), np.nan)
    st, sv = clean_samples(inputs.speed_t, inputs.speed_v)
    if speed_filter:
        st, sv = (np.asarray(a, dtype=float)
                  for a in filter_ground_speed(st, sv, settings.speed_limits))
    jt, jp, jw = clean_samples(inputs.joint_t, inputs.joint_pos, joint_vel)
    if st.size < 2 or jt.size < 2:
        return None
    ss = travelled_distance(st, sv)
    theta = np.maximum.accumulate(jp)
    i, t_e, omega, which, theta_k = _crossings(models, change_times, jt, theta, jw)
    if not t_e.size:
        return None
    gap = settings.max_input_gap
    j = np.searchsorted(st, t_e, side='right')
    located = (j >= 1) & (j < st.size)
    jc = np.clip(j, 1, st.size - 1)
    # a plant inside a gap of either input: reported, interpolated and flagged
    in_gap = (jt[i] - jt[i - 1] > gap) | (st[jc] - st[jc - 1] > gap)
    keep = located
    t_e, omega, j, which, theta_k = t_e[keep], omega[keep], j[keep], which[keep], theta_k[keep]
    in_gap = in_gap[keep]
    v_e, s_e = _at_speed(t_e, st[j - 1], st[j], sv[j - 1], sv[j], ss[j - 1])
    starts = np.concatenate((_gaps(jt, gap), _gaps(st, gap),
                             np.asarray(inputs.breaks, dtype=float).reshape(-1, 2)))
    return _RowInstants(Motion(jt, theta, jw, st, sv, ss), which, theta_k, t_e, omega,
                        np.asarray(v_e), np.asarray(s_e), in_gap, starts)


def _measured_arcs(rows: Sequence[tuple[Motion, NDArray[np.intp], FloatArray]],
                   models: Sequence[Planting], gap: float
                   ) -> list[tuple[FloatArray, FloatArray]]:
    """(sweep, tilt) of the measured arcs of each row's plants (NaN: not covered), every row
    and design in one pass (motion.arc_figures). `rows`: (the row's Motion, index into `models`
    of each plant's design, each plant's planting angle)."""
    groups, places = [], []
    for r, (motion, which, theta_k) in enumerate(rows):
        for w in np.unique(which):
            mine = which == w
            groups.append((models[w], theta_k[mine], motion))
            places.append((r, mine))
    sweep, tilt, _ = arc_figures(groups, gap)
    out = [(np.full(theta_k.size, np.nan), np.full(theta_k.size, np.nan))
           for _, _, theta_k in rows]
    at = 0
    for (r, mine), (_, theta_k, _) in zip(places, groups):
        out[r][0][mine], out[r][1][mine] = sweep[at:at + theta_k.size], tilt[at:at + theta_k.size]
        at += theta_k.size
    return out


def _crossings(models: Sequence[Planting], change_times: Sequence[float], jt: FloatArray,
               theta: FloatArray, jw: FloatArray
               ) -> tuple[NDArray[np.intp], FloatArray, FloatArray, NDArray[np.intp],
                          FloatArray]:
    """Every planting instant of a running-maximum shaft angle `theta` (at times `jt`):
    (index of the joint sample after it, instant, shaft speed, index into `models` of the
    design in force, planting angle). models[0] is in force from the start, models[c] from
    the first crossing after change_times[c - 1] (that crossing still the earlier design's)."""
    parts: list[tuple[NDArray[np.intp], FloatArray, FloatArray, NDArray[np.intp],
                      FloatArray]] = []
    lo, current = float(theta[0]), 0           # thresholds strictly beyond lo
    while True:
        model = models[current]
        ks = np.arange(_first_k(model, lo), _first_k(model, theta[-1]))
        if not ks.size:
            break
        theta_k = _threshold(model, ks.astype(float))
        i = np.searchsorted(theta, theta_k, side='left')
        t_e, omega = (np.asarray(v) for v in _crossing(
            theta_k, (jt[i - 1], theta[i - 1], jw[i - 1]), (jt[i], theta[i], jw[i])))
        # models[current + 1] comes with change_times[current]
        later = (np.nonzero(t_e > change_times[current])[0] if current < len(change_times)
                 else np.zeros(0, dtype=np.intp))
        if not len(later):
            parts.append((i, t_e, omega, np.full(t_e.size, current), theta_k))
            break
        last = later[0]                        # the old design's last plant
        parts.append((i[:last + 1], t_e[:last + 1], omega[:last + 1],
                      np.full(last + 1, current), theta_k[:last + 1]))
        # in force after it: the latest change before it
        current = int(np.searchsorted(np.asarray(change_times, dtype=float), t_e[last],
                                      side='left'))
        lo = float(theta_k[last])
    if not parts:
        return (np.zeros(0, dtype=int), np.zeros(0), np.zeros(0), np.zeros(0, dtype=int),
                np.zeros(0))
    i, t_e, omega, which, theta_k = (np.concatenate(c) for c in zip(*parts))
    return i, t_e, omega, which, theta_k


def _gaps(t: FloatArray, gap: float) -> FloatArray:
    """(start, end) of every interval between consecutive samples `t` longer than `gap`."""
    k = np.nonzero(np.diff(t) > gap)[0]
    return np.column_stack((t[k], t[k + 1]))


def _after_gap(t_e: FloatArray, t_before: float, gaps: FloatArray) -> NDArray[np.bool_]:
    """For plants at increasing instants `t_e` (the previous one at `t_before`): does an input
    gap (rows of start, end) lie between each plant and the one before it?"""
    if not len(gaps) or not t_e.size:
        return np.zeros(t_e.size, dtype=bool)
    order = np.argsort(gaps[:, 0], kind='stable')
    starts, latest_end = gaps[order, 0], np.maximum.accumulate(gaps[order, 1])
    before = np.concatenate(([t_before], t_e[:-1]))
    n = np.searchsorted(starts, t_e, side='left')          # gaps starting before each plant
    return (n > 0) & (latest_end[np.maximum(n - 1, 0)] > before)


class _Located(NamedTuple):
    """Plants' planting instants located in the inputs, one entry per plant."""

    models: Sequence[Planting]       # the design in force
    t_e: FloatArray                  # instant (s)
    omega: FloatArray                # shaft speed (rad/s)
    v_e: FloatArray                  # ground speed (m/s)
    s_e: FloatArray                  # travelled distance (m)
    in_gap: NDArray[np.bool_]        # inside an input gap
    new_sequence: NDArray[np.bool_]  # an input gap or a break since the plant before
    arcs: tuple[FloatArray, FloatArray] | None    # (sweep, tilt) of the measured arcs


class _Before(NamedTuple):
    """Where a row's plants go on from: the index of the next plant, the position of the last
    one (m; NaN: none) and the upright flags of the last ones (the rolling rate's)."""

    index0: int
    prev_position: float
    recent: Sequence[float]


_FIRST = _Before(0, math.nan, ())


def _assemble(located: _Located, settings: PredictionSettings, before: _Before,
              sizes: Sequence[tuple[int, int]]) -> Plants:
    """Plants from their located instants (`located.models[p]` the design in force for plant
    p). `sizes`: (row, count) of each row, the plants being the rows' one after the other,
    every row numbered from `before.index0`, its first spacing from `before.prev_position`
    and its rolling rate on its own plants (`before.recent`: the flags before the first
    row's)."""
    models, t_e, omega, v_e, s_e, in_gap, new_sequence, arcs = located
    index0, prev_position, recent = before
    n = t_e.size
    rows = np.asarray([row for row, _ in sizes], dtype=float)
    counts = np.asarray([count for _, count in sizes], dtype=np.intp)
    first = np.cumsum(counts) - counts                   # each row's first plant
    in_gap = np.asarray(in_gap, dtype=bool)
    if arcs is None:
        arcs = (np.full(n, np.nan), np.full(n, np.nan))
    ratio, sweep, hole, tilt, upright = (np.zeros(n) for _ in range(5))
    d = np.zeros(n)
    for model in {id(m): m for m in models}.values():
        mine = np.array([m is model for m in models], dtype=bool)
        ratio[mine], sweep[mine], hole[mine], tilt[mine], upright[mine] = plant_values(
            model, settings, omega[mine], v_e[mine], arcs[0][mine], arcs[1][mine])
        d[mine] = model.spacing
    for values in (ratio, sweep, hole, tilt, upright):
        values[in_gap] = np.nan            # interpolated across a gap: not known
    spacing = s_e - np.concatenate(([prev_position], s_e[:-1]))
    starts = first[counts > 0]
    spacing[starts] = s_e[starts] - prev_position
    spacing[new_sequence] = np.nan         # no spacing across a gap in the inputs
    # rolling rate over the last `window` plants of the row, continuing from `recent` flags;
    # a plant whose uprightness is not known (NaN) counts in neither the upright nor the total
    window = settings.window
    history = np.concatenate((np.asarray(recent, dtype=float), upright))
    known = np.isfinite(history)
    csum = np.concatenate(([0.0], np.cumsum(np.where(known, history, 0.0))))
    ccount = np.concatenate(([0], np.cumsum(known)))
    end = np.arange(len(recent), len(recent) + n) + 1
    floor = np.repeat(np.where(first > 0, first + len(recent), 0), counts)
    start = np.maximum(end - window, floor)
    counted = ccount[end] - ccount[start]
    with np.errstate(invalid='ignore', divide='ignore'):
        rate = np.where(counted > 0, (csum[end] - csum[start]) / np.maximum(counted, 1),
                        np.nan) if n else np.zeros(0)
    return Plants(index=(np.arange(n) - np.repeat(first, counts) + index0).astype(float),
                  time=t_e, position=s_e, spacing=spacing, spacing_error=spacing - d,
                  speed_ratio=ratio, ground_speed=v_e, shaft_speed=omega, hole_width=hole,
                  tilt=tilt, upright=upright, uprightness_rate=rate,
                  row=np.repeat(rows, counts), tip_sweep=sweep,
                  latitude=np.full(n, np.nan), longitude=np.full(n, np.nan),
                  input_gap=in_gap.astype(float), seedlings=np.full(n, np.nan),
                  status=np.full(n, float(UNKNOWN)),
                  reason=np.where(in_gap, float(INPUT_GAP), float(NO_SENSOR)))


# a joint sample (t s, running-maximum shaft angle rad, shaft speed rad/s) and a speed sample
# (t s, v m/s, travelled distance m)
_Joint = tuple[float, float, float]
_Speed = tuple[float, float, float]


class _Pending(NamedTuple):
    """A planting instant not yet completed."""

    t_e: float                 # the instant (s)
    omega: float               # shaft speed there (rad/s)
    model: Planting            # the design in force
    theta_k: float             # planting angle (rad)
    in_gap: bool               # inside a gap of the joint samples


class PlantPredictor:
    """The same model fed one sample at a time (the live monitor). `add_speed` and `add_joint`
    return the plants completed by that sample (a Plants, often empty). A plant is completed
    once the shaft has left the soil after it and a ground speed sample later than that has
    arrived (its measured arc is then known: prediction.motion), or once `max_input_gap` has
    passed since its planting instant without that. `finish` completes what is left when the
    inputs end."""

    SPEED_HISTORY = 4096      # speed samples kept to locate plants reported late by the drive

    def __init__(self, model: Planting, settings: PredictionSettings = PredictionSettings(),
                 row: int = 0, speed_filter: bool = True) -> None:
        """`row`: the row field of its plants; `speed_filter` False: speeds already passed
        the plausibility rule (a row's speed from sensing.row_speed)."""
        self.model = model
        self.settings = settings
        self.row = row
        self._speed: deque[_Speed] = deque(maxlen=self.SPEED_HISTORY)   # the samples kept
        self._speed_filter = GroundSpeedFilter(settings.speed_limits) if speed_filter else None
        self._speed_seen = -math.inf                     # latest finite sample time
        self._joint: _Joint | None = None                # the last joint sample
        self._joints: deque[_Joint] = deque(maxlen=self.SPEED_HISTORY)  # kept for the arcs
        self._next_k = 0                   # planting index of the next crossing (first joint)
        self._pending: list[_Pending] = []
        self._changes: list[tuple[float, Planting]] = []     # (t, model) not yet in force
        self._count = 0
        self._prev_position = math.nan
        self._prev_time = -math.inf                      # instant of the last plant reported
        self._gaps: list[tuple[float, float]] = []       # input gaps (start, end) since then
        self._recent: deque[float] = deque(maxlen=settings.window)

    def change_model(self, model: Planting, t: float) -> None:
        """A new design arrived at `t` (s): in force from the next planting instant (the
        first crossing later than `t`, still the old design's plant; module doc)."""
        if self._joint is None:                  # nothing turned yet: in force at once
            self.model, self._changes = model, []
            return
        self._changes.append((float(t), model))

    def add_speed(self, t: float, v: float) -> Plants:
        t, v = float(t), float(v)
        if not (math.isfinite(t) and math.isfinite(v)) or not t > self._speed_seen:
            return self._nothing()
        self._speed_seen = t
        if self._speed_filter is not None:
            used, _ = self._speed_filter.check(v, t)
            if used is None:
                return self._nothing()
            v = used
        if self._speed:
            t0, v0, s0 = self._speed[-1]
            s = s0 + 0.5 * (v0 + v) * (t - t0)
            if t - t0 > self.settings.max_input_gap:
                self._gaps.append((t0, t))
        else:
            s = 0.0
        self._speed.append((t, v, s))
        return self._resolve()

    def add_break(self, start: float, end: float) -> None:
        """The row's section was off from `start` to `end` (s): the first plant after it has
        no spacing (call before that plant is completed)."""
        self._gaps.append((float(start), float(end)))

    def add_joint(self, t: float, position: float,
                  velocity: float | None = math.nan) -> Plants:
        t, position = float(t), float(position)
        velocity = float(velocity) if velocity is not None else math.nan
        if not (math.isfinite(t) and math.isfinite(position)):
            return self._nothing()
        if self._joint is None:
            self._joint = (t, position, velocity)
            self._joints.append(self._joint)
            self._next_k = _first_k(self.model, position)
            return self._nothing()
        t0, th0, w0 = self._joint
        if not t > t0:
            return self._nothing()
        th1 = max(th0, position)
        in_gap = t - t0 > self.settings.max_input_gap
        if in_gap:
            self._gaps.append((t0, t))
        while _threshold(self.model, float(self._next_k)) <= th1:
            theta_k = _threshold(self.model, float(self._next_k))
            t_e, omega = _crossing(theta_k, (t0, th0, w0), (t, th1, velocity))
            # a crossing inside a gap: reported, interpolated and flagged (module doc)
            self._pending.append(_Pending(float(t_e), float(omega), self.model, theta_k,
                                          in_gap))
            self._next_k += 1
            if self._changes and self._changes[0][0] < t_e:
                # this plant was the old design's last; the latest change before it is in force
                n = sum(1 for change_t, _ in self._changes if change_t < t_e)
                self.model = self._changes[n - 1][1]
                self._changes = self._changes[n:]
                self._next_k = _first_k(self.model, theta_k)
        self._joint = (t, th1, velocity)
        self._joints.append(self._joint)
        return self._resolve()

    def finish(self) -> Plants:
        """The inputs ended: complete every plant that has a position (its arc as far as it
        was measured, else the figures at its instant)."""
        return self._resolve(final=True)

    def _arc_done(self, joint: _Joint, t_e: float, model: Planting, theta_k: float,
                  last_t: float) -> bool:
        """Is the plant's arc measured as far as it will be (prediction.motion)? Yes once the
        shaft is past the soil exit and a speed sample later than that has come, or once the
        joint samples have run on `max_input_gap` past the planting instant without that (a
        plant whose feedback stops waits for it, or for `finish`)."""
        exit_angle = theta_k + model.exit_angle
        t_joint, th_last, _ = joint
        if th_last < exit_angle:
            # the exit comes later than max_input_gap after the instant: not covered (judged
            # on the joint stamps alone: speed samples may run ahead of late feedback)
            return t_joint - t_e > self.settings.max_input_gap
        past = t_joint                       # the first joint sample at or past the exit
        for t, th, _ in reversed(self._joints):
            if th < exit_angle:
                break
            past = t
        return past < last_t

    def _resolve(self, final: bool = False) -> Plants:
        joint = self._joint           # set with the first joint sample, before any plant
        if not self._pending or len(self._speed) < 2 or joint is None:
            return self._nothing()
        first_t, last_t = self._speed[0][0], self._speed[-1][0]
        done: list[_Pending] = []
        keep: list[_Pending] = []
        for pending in self._pending:
            t_e, _, model, theta_k, _ = pending
            if keep or t_e >= last_t:
                keep.append(pending)    # in order: none completes before an earlier one
            elif t_e < first_t:
                pass        # before the first speed sample: no position, dropped (as in replay)
            elif (final or not self.settings.measured_arc
                  or self._arc_done(joint, t_e, model, theta_k, last_t)):
                done.append(pending)
            else:
                keep.append(pending)
        self._pending = keep
        if not done:
            return self._nothing()
        times = [s[0] for s in self._speed]
        rows: list[tuple[float, float, float, float, float, bool]] = []
        models: list[Planting] = []
        for t_e, omega, model, theta_k, in_gap in done:
            j = _bisect_right(times, t_e)
            (t0, v0, s0), (t1, v1, _) = self._speed[j - 1], self._speed[j]
            # inside a gap of the ground speed: reported, interpolated and flagged
            in_gap = in_gap or t1 - t0 > self.settings.max_input_gap
            v_e, s_e = _at_speed(np.float64(t_e), t0, t1, v0, v1, s0)
            rows.append((t_e, omega, float(v_e), float(s_e), theta_k, in_gap))
            models.append(model)
        if not rows:
            return self._nothing()
        instants, omegas, speeds, places, angles, gaps = (np.array(c) for c in zip(*rows))
        arcs = self._arcs(models, angles) if self.settings.measured_arc else None
        new_sequence = _after_gap(instants, self._prev_time,
                                  np.array(self._gaps).reshape(-1, 2))
        plants = _assemble(_Located(models, instants, omegas, speeds, places,
                                    gaps.astype(bool), new_sequence, arcs), self.settings,
                           _Before(self._count, self._prev_position, tuple(self._recent)),
                           [(self.row, instants.size)])
        self._count += len(plants)
        self._prev_position = float(plants.position[-1])
        self._prev_time = float(plants.time[-1])
        # a gap ending before the last plant can no longer lie between two future plants
        self._gaps = [g for g in self._gaps if g[1] > self._prev_time]
        self._recent.extend(plants.upright.tolist())
        return plants

    def _arcs(self, models: Sequence[Planting],
              theta_k: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(sweep, tilt) of the measured arcs of plants at `theta_k` (NaN: not covered)."""
        jt, theta, jw = (np.array(c, dtype=float) for c in zip(*self._joints))
        st, sv, ss = (np.array(c, dtype=float) for c in zip(*self._speed))
        distinct: list[Planting] = list({id(m): m for m in models}.values())
        which = np.array([next(w for w, d in enumerate(distinct) if d is m) for m in models],
                         dtype=np.intp)
        return _measured_arcs([(Motion(jt, theta, jw, st, sv, ss), which, theta_k)], distinct,
                              self.settings.max_input_gap)[0]

    def _nothing(self) -> Plants:
        return Plants.empty()


def _bisect_right(a: Sequence[float], x: float) -> int:
    return bisect.bisect_right(a, x)
