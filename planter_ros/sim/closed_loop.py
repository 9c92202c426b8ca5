"""Closed-loop simulation of the phase-locked law against a simple drive model (no ROS, no CAN).

The drive model is a first-order velocity lag with an acceleration limit and a speed scale
(achieved/commanded in steady state: a gear-ratio parameter that is slightly off, or a loaded
speed loop that droops). Plants are placed when the mechanism angle passes the release angle of
each arm; their positions come from the true travelled distance at that instant (sim.spacing).
`python -m planter_ros.sim.closed_loop` prints phase-locked against speed-only spacing, and each
row of a 4-row machine through two 10 m curves with and without turn compensation.

`simulate_rows` runs a whole machine: the sync node's `Machine` (one law per row on the row's
own speed v − ω_z·y) against one drive model per row; every row's plants are placed along the
row's own true travelled distance (FieldProfile.row_distance).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
import math
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
from numpy.typing import NDArray

from planter_ros.control.machine import Machine, TurnConfig
from planter_ros.control.phase_lock import PhaseLock, PhaseLockConfig

from .field import FieldProfile, demo_curves, field_profile
from .spacing import SpacingStats, plant_positions, spacing_stats

if TYPE_CHECKING:
    from typing_extensions import TypeIs

    from planter_ros.control.phase_lock import PlantingAngles

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class DriveModel:
    time_constant: float = 0.05       # s, first-order velocity lag
    max_acceleration: float = 50.0    # rad/s², mechanism shaft
    speed_scale: float = 1.0          # achieved / commanded speed in steady state


# (t s, the drive model from t on): a drive that changes mid-run
DriveChange = tuple[float, 'DriveModel']


def _one_change(change: DriveChange | Sequence[DriveChange]) -> TypeIs[DriveChange]:
    return isinstance(change[0], (int, float))


@dataclass
class SimResult:
    t: np.ndarray            # s
    distance: np.ndarray     # true travelled distance (m)
    angle: np.ndarray        # mechanism angle (rad)
    command: np.ndarray      # speed command (rad/s)
    speed: np.ndarray        # mechanism speed (rad/s)


def simulate(law: PhaseLock, profile: Callable[[float], float], duration: float,
             drive: DriveModel = DriveModel(), dt: float = 0.001, sample_period: float = 0.05,
             feedback_period: float = 0.01, noise: float = 0.0, seed: int = 0,
             drive_change: DriveChange | Sequence[DriveChange] | None = None,
             sensor: Callable[[float, float], float] | None = None) -> SimResult:
    """Run `law` (a PhaseLock with its design set) against `drive` for `duration` s.

    `profile(t)` is the true ground speed; the law sees it every `sample_period` with Gaussian
    `noise` (m/s). `drive_change = (t, DriveModel)` swaps the drive model mid-run (a drive that
    gets slower under load); a list of such pairs, in time order, swaps it several times.
    Commands are computed on every sample and every feedback period, as the sync node does.
    `sensor(t, v)`, if given, turns the true speed into the reading (drop-outs, spikes)
    instead of the Gaussian noise.
    """
    rng = np.random.default_rng(seed)
    changes: list[DriveChange] = []
    if drive_change:
        changes = [drive_change] if _one_change(drive_change) else list(drive_change)
    steps = int(round(duration / dt))
    out = {k: np.empty(steps + 1) for k in ('t', 'distance', 'angle', 'command', 'speed')}
    s = theta = omega = cmd = 0.0
    next_sample = next_feedback = 0.0
    for i in range(steps + 1):
        t = i * dt
        while changes and t >= changes[0][0]:
            drive = changes.pop(0)[1]
        if t >= next_feedback - 1e-12:
            law.feedback(theta, omega, t)
            cmd = law.command(t)
            next_feedback += feedback_period
        if t >= next_sample - 1e-12:
            v = profile(t)
            if sensor is not None:
                v = sensor(t, v)
            elif noise:
                v += rng.normal(0.0, noise)
            law.ground_speed(v, t)
            cmd = law.command(t)
            next_sample += sample_period
        for key, val in (('t', t), ('distance', s), ('angle', theta), ('command', cmd),
                         ('speed', omega)):
            out[key][i] = val
        goal = drive.speed_scale * cmd
        step = (goal - omega) * min(dt / drive.time_constant, 1.0)
        lim = drive.max_acceleration * dt
        omega += min(max(step, -lim), lim)
        theta += omega * dt
        s += profile(t) * dt
    return SimResult(**out)


def run_comparison(config: PhaseLockConfig, spacing: float, plants_per_revolution: int,
                   cruise: float, duration: float = 30.0, drive: DriveModel = DriveModel(),
                   drive_change: DriveChange | None = None, noise: float = 0.01,
                   seed: int = 0) -> dict[str, SpacingStats]:
    """Spacing statistics of the same run with phase lock on and off (speed-only)."""
    from dataclasses import replace
    result: dict[str, SpacingStats] = {}
    for mode, lock in (('phase_locked', True), ('speed_only', False)):
        law = PhaseLock(replace(config, phase_lock=lock))
        law.set_design(spacing, plants_per_revolution, 0.0)
        sim = simulate(law, field_profile(duration, cruise), duration, drive=drive,
                       noise=noise, seed=seed, drive_change=drive_change)
        pos = plant_positions(sim.angle, sim.distance, TWO_PI / plants_per_revolution)
        result[mode] = spacing_stats(pos, spacing)
    return result


class CspDrive:
    """A row's drive in cyclic synchronous position, as the command process drives it (command
    .engine) and the simulated drive follows it (drive.simulated_drive): at each SYNC the drive
    takes the target sent after the last one and interpolates to it over one period; after the
    SYNC the row's next target is its last one advanced by the law's command, pulled onto the
    cam's θ(s) (control.row_loop.cam_csp_target) and sent CSP_LEAD periods ahead
    (csp_setpoint). The motor's speed is the set point's plus the position error over the
    drive's time constant (its position loop with velocity feed-forward)."""

    def __init__(self, period: float) -> None:
        self.period = float(period)
        self.target: float | None = None    # the row's angle at the last SYNC's target (rad)
        self.target_time = 0.0
        self.pending: float | None = None   # the set point sent, taken at the next SYNC
        self.start = -math.inf              # the segment the drive interpolates: its start,
        self.first = self.last = 0.0        # from, to (rad)

    def setpoint(self, t: float) -> float:
        share = min(max((t - self.start) / self.period, 0.0), 1.0)
        return self.first + (self.last - self.first) * share

    def sync(self, t: float) -> None:
        """A SYNC at `t`: the drive starts the segment to the target sent since the last."""
        if self.pending is not None:
            self.first, self.last = self.setpoint(t), self.pending
            self.start = t
            self.pending = None

    def send(self, law: PhaseLock, command: float, theta: float, t: float) -> None:
        """After the SYNC at `t`: the row's target for the next one (the shaft at `theta`)."""
        from planter_ros.control.row_loop import cam_csp_target, csp_setpoint
        ahead = 0.0
        if self.target is None:
            self.target = theta
            self.first = self.last = theta
        else:
            step = max(t - self.target_time, 0.0)
            self.target += command * step
            on_cam = cam_csp_target(law, self.target, t + self.period, step)
            if on_cam is not None:
                self.target, ahead = on_cam, self.period
        self.target_time = t
        self.pending = csp_setpoint(self.target, command, self.period, ahead)

    def speed(self, theta: float, time_constant: float, t: float) -> float:
        """The speed the drive's position loop asks for at `t` (rad/s)."""
        moving = t - self.start < self.period
        feed = (self.last - self.first) / self.period if moving else 0.0
        return feed + (self.setpoint(t) - theta) / time_constant


@dataclass
class RowRun:
    """One row of a simulated machine (arrays on the simulation's time grid)."""

    lateral_offset: float    # m, + left
    t: np.ndarray            # s
    distance: np.ndarray     # the row's own true travelled distance (m)
    angle: np.ndarray        # mechanism angle (rad)
    command: np.ndarray      # speed command (rad/s)
    speed: np.ndarray        # mechanism speed (rad/s)


def simulate_rows(offsets: Sequence[float], profile: FieldProfile, duration: float,
                  spacing: float, plants_per_revolution: int = 1,
                  config: PhaseLockConfig | None = None, compensation: bool = True,
                  drive: DriveModel = DriveModel(), dt: float = 0.001,
                  sample_period: float = 0.05, feedback_period: float = 0.01,
                  noise: float = 0.005, yaw_noise: float = 0.005, seed: int = 0,
                  switches: Sequence[tuple[float, int, bool]] = (),
                  planting: PlantingAngles | None = None,
                  sensor: Callable[[float, float, float], tuple[float, float] | None] | None
                  = None,
                  drive_changes: Sequence[tuple[float, int, DriveModel]] = (),
                  cams: Sequence[Any] | None = None,
                  designs: Sequence[tuple[float, float, Sequence[Any] | None]] = ()
                  ) -> list[RowRun]:
    """Run a machine with rows at `offsets` (m) along `profile` (a FieldProfile: speed and yaw
    rate) for `duration` s; the sensor adds Gaussian `noise` (m/s) and `yaw_noise` (rad/s).
    Commands are computed on every sample and every feedback period, as the sync node does.
    `switches`: (t, row index, on) section-control events; `planting`: the mechanism's
    PlantingAngles (where it plants, for the section stops). `sensor(t, v, ω_z)`, if given,
    turns the true speed and yaw rate into the reading (v, ω_z), or None for a sample that
    never arrives, instead of the Gaussian noise. `drive_changes`: (t, row index, DriveModel)
    events, that row's drive from t on (a stall and its end). `cams`: each row's cam profile
    (`speed_profile: cam`, control.cam_law.plan_row_cam; None: constant speed), or None: a cam
    row runs a CSP drive as the command process drives it (`CspDrive`). `designs`: (t, spacing,
    cams) events, a design arriving at t (each row takes it at its next planting instant).
    Returns one RowRun per row."""
    rng = np.random.default_rng(seed)
    machine = Machine(offsets, config or PhaseLockConfig(),
                      turn=TurnConfig(turn_compensation=compensation))
    machine.set_design(spacing, plants_per_revolution, 0.0, planting, cams)
    csp = [CspDrive(feedback_period) if cam is not None else None
           for cam in (cams or [None] * len(machine.laws))]
    positioned = {r: drive for r, drive in enumerate(csp) if drive is not None}
    switches = sorted(switches)
    changes = sorted(drive_changes, key=lambda c: (c[0], c[1]))
    designs = sorted(designs, key=lambda c: c[0])
    rows = len(machine.laws)
    tau, amax, scale = (np.full(rows, float(getattr(drive, k))) for k in
                        ('time_constant', 'max_acceleration', 'speed_scale'))
    steps = int(round(duration / dt))
    t_out = np.arange(steps + 1, dtype=np.float64) * dt
    angle, command, speed = (np.empty((rows, steps + 1)) for _ in range(3))
    theta = np.zeros(rows)
    omega = np.zeros(rows)
    cmd = np.zeros(rows)
    next_sample = next_feedback = 0.0
    for i in range(steps + 1):
        t = i * dt
        fresh = False
        while switches and t >= switches[0][0]:
            _, row, on = switches.pop(0)
            machine.laws[row].switch(on, t)
        while designs and t >= designs[0][0]:
            _, d, row_cams = designs.pop(0)
            machine.set_design(d, plants_per_revolution, t, planting, row_cams, since=t)
        while changes and t >= changes[0][0]:
            _, row, model = changes.pop(0)
            tau[row], amax[row], scale[row] = (model.time_constant, model.max_acceleration,
                                               model.speed_scale)
        sync = t >= next_feedback - 1e-12
        if sync:
            for csp_drive in positioned.values():
                csp_drive.sync(t)
            for r, law in enumerate(machine.laws):
                law.feedback(theta[r], omega[r], t)
            fresh = True
            next_feedback += feedback_period
        if t >= next_sample - 1e-12:
            v = profile(t)
            if sensor is not None:
                reading = sensor(t, v, profile.yaw_rate(t))
            else:
                reading = (v + rng.normal(0.0, noise) if v > 0.0 else 0.0,
                           profile.yaw_rate(t) + rng.normal(0.0, yaw_noise))
            if reading is not None:
                machine.sample(reading[0], reading[1], t)
                fresh = True
            next_sample += sample_period
        if fresh:
            for r, law in enumerate(machine.laws):
                cmd[r] = law.command(t)
            for r, csp_drive in positioned.items() if sync else ():
                csp_drive.send(machine.laws[r], cmd[r], theta[r], t)
        angle[:, i], command[:, i], speed[:, i] = theta, cmd, omega
        step = (scale * cmd - omega) * np.minimum(dt / tau, 1.0)
        for r, csp_drive in positioned.items():
            # a speed loop lags its command; a position loop asks for its speed at once
            step[r] = scale[r] * csp_drive.speed(theta[r], tau[r], t) - omega[r]
        lim = amax * dt
        omega = omega + np.clip(step, -lim, lim)
        theta = theta + omega * dt
    return [RowRun(y, t_out, np.asarray(profile.row_distance(t_out, y)), angle[r], command[r],
                   speed[r])
            for r, y in enumerate(machine.offsets)]


class CurveFigure(TypedDict):
    """One curve's figures for one row (m; None: no plant or no speed there)."""

    radius: float
    plants: int
    rms_spacing_error: float | None
    mean_spacing_error: float | None
    uncompensated_bias: float
    median_speed_ratio: float | None


class RowCurveFigures(TypedDict):
    lateral_offset: float
    curves: list[CurveFigure]
    rms_spacing_error: float | None      # over every curve's plants


def curve_figures(run: RowRun, profile: FieldProfile, spacing: float,
                  plants_per_revolution: int = 1) -> RowCurveFigures:
    """Per curve of `profile`, through its steady part: the row's plants there, their spacing
    error against d along the row's own travelled distance (RMS and mean, m), the bias a
    machine without turn compensation shows there (−y·d/R, m), and the median of the measured
    mechanism speed over 2πv_i/(n·d); then `rms_spacing_error` over every curve's plants."""
    pitch = TWO_PI / plants_per_revolution
    release = 0.5 * pitch                           # the arm starts at the top
    times = plant_positions(run.angle, run.t, pitch, release=release)
    error = np.diff(plant_positions(run.angle, run.distance, pitch, release=release)) - spacing
    curves: list[CurveFigure] = []
    every: list[NDArray[np.float64]] = []
    for curve in profile.curves:
        a, b = curve.start + curve.ease, curve.end - curve.ease
        # a spacing counts when both of its plants are set in the steady turn
        mine = error[(times[:-1] >= a) & (times[1:] <= b)]
        every.append(mine)
        steady = (run.t >= a) & (run.t <= b)
        v_row = np.array([profile(t) for t in run.t[steady]]) * (
            1.0 - run.lateral_offset / curve.radius)
        expected = TWO_PI * v_row / (plants_per_revolution * spacing)
        moving = expected > 0.1
        curves.append({
            'radius': curve.radius, 'plants': int(mine.size),
            'rms_spacing_error': float(np.sqrt(np.mean(mine ** 2))) if mine.size else None,
            'mean_spacing_error': float(np.mean(mine)) if mine.size else None,
            'uncompensated_bias': -run.lateral_offset * spacing / curve.radius,
            'median_speed_ratio': float(np.median(run.speed[steady][moving] / expected[moving]))
            if moving.any() else None})
    joined = np.concatenate(every) if every else np.zeros(0)
    return {'lateral_offset': run.lateral_offset, 'curves': curves,
            'rms_spacing_error': float(np.sqrt(np.mean(joined ** 2))) if joined.size else None}


MACHINE_ROWS = (0.75, 0.25, -0.25, -0.75)       # the 4-row scene's lateral offsets (m)


def curve_comparison(offsets: Sequence[float] = MACHINE_ROWS, spacing: float = 0.2,
                     cruise: float = 0.2, duration: float = 30.0, radius: float = 10.0,
                     seed: int = 0, dt: float = 0.001) -> dict[str, list[RowCurveFigures]]:
    """`curve_figures` of every row, with and without turn compensation (tomato, the demo's
    30 s run with a left and a right turn of `radius`)."""
    profile = field_profile(duration, cruise, curves=demo_curves(duration, radius))
    out: dict[str, list[RowCurveFigures]] = {}
    for mode, on in (('compensated', True), ('uncompensated', False)):
        runs = simulate_rows(offsets, profile, duration, spacing, compensation=on, seed=seed,
                             dt=dt)
        out[mode] = [curve_figures(run, profile, spacing) for run in runs]
    return out


class _Scenario(TypedDict, total=False):
    """run_comparison's drive arguments of a scenario."""

    drive: DriveModel
    drive_change: tuple[float, DriveModel]


SCENARIOS: dict[str, _Scenario] = {
    'nominal drive (lag 0.05 s)': dict(drive=DriveModel()),
    'drive lag 0.05 -> 0.2 s at 12 s': dict(drive_change=(12.0, DriveModel(
        time_constant=0.2, max_acceleration=15.0))),
    'drive 3 % slow (speed scale 0.97)': dict(drive=DriveModel(speed_scale=0.97)),
}


NOISES = (0.0, 0.01)          # m/s of ground-speed sensor noise


def spacing_rows() -> list[tuple[float, str, SpacingStats, SpacingStats]]:
    """[(noise m/s, scenario, phase-locked SpacingStats, speed-only SpacingStats)] of the
    tomato scene (30 s field run: 0.2 m/s, +50 % at 13.5 s, stop); deterministic."""
    out: list[tuple[float, str, SpacingStats, SpacingStats]] = []
    for noise in NOISES:
        for name, kwargs in SCENARIOS.items():
            r = run_comparison(PhaseLockConfig(), 0.2, 1, 0.2, noise=noise, **kwargs)
            out.append((noise, name, r['phase_locked'], r['speed_only']))
    return out


def spacing_markdown() -> str:
    """The table doc/node_graph.md shows (`--markdown`): max |drift from grid| / max |gap − d|
    in mm per drive and sensor noise, phase-locked against speed-only."""
    lines = ['| drive | sensor noise | phase-locked | speed-only |', '|---|---|---|---|']
    for noise, name, a, b in spacing_rows():
        lines.append(f'| {name} | {noise * 1e3:g} mm/s | {a.max_abs_drift * 1e3:.1f} / '
                     f'{a.max_abs_spacing_error * 1e3:.1f} | {b.max_abs_drift * 1e3:.1f} / '
                     f'{b.max_abs_spacing_error * 1e3:.1f} |')
    return '\n'.join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Print phase-locked vs speed-only spacing for the tomato scene (30 s field run:
    0.2 m/s, +50 % at 13.5 s, stop), noise-free and with 10 mm/s sensor noise; and the 4-row
    machine through turns."""
    import argparse
    parser = argparse.ArgumentParser(description=main.__doc__, allow_abbrev=False)
    parser.add_argument('--markdown', action='store_true',
                        help="print only the spacing table of doc/node_graph.md")
    args = parser.parse_args(argv)
    if args.markdown:
        print(spacing_markdown())
        return 0
    print('tomato five-bar, d = 200 mm; max |drift from grid| / max |gap - d| in mm')
    for noise, name, a, b in spacing_rows():
        print(f'  noise {noise * 1e3:4.0f} mm/s  {name:34s} phase-locked '
              f'{a.max_abs_drift * 1e3:6.1f} / {a.max_abs_spacing_error * 1e3:5.1f}   '
              f'speed-only {b.max_abs_drift * 1e3:6.1f} / {b.max_abs_spacing_error * 1e3:5.1f}')
    print('4 rows through a left and a right 10 m turn (tomato, d = 200 mm, 5 mm/s and '
          '5 mrad/s noise): spacing error in the curves, RMS / mean, mm; speed ratio median')
    result = curve_comparison()
    for on, off in zip(result['compensated'], result['uncompensated']):
        for c, u in zip(on['curves'], off['curves']):
            print(f"  y = {on['lateral_offset']:+.2f} m, R = {c['radius']:+5.1f} m  compensated "
                  f"{_mm(c['rms_spacing_error'])} / {_mm(c['mean_spacing_error'], '+6.2f')}, "
                  f"ratio {c['median_speed_ratio']:.4f}   uncompensated "
                  f"{_mm(u['rms_spacing_error'])} / {_mm(u['mean_spacing_error'], '+6.2f')} "
                  f"(-y·d/R {u['uncompensated_bias'] * 1e3:+6.2f})")
    return 0


def _mm(value: float | None, spec: str = '5.2f') -> str:
    """A length in mm for the table (n/a without plants)."""
    return 'n/a' if value is None else format(value * 1e3, spec)


if __name__ == '__main__':
    raise SystemExit(main())
