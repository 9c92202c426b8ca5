"""A season of simulated runs: realistic bags in the exact layout the monitor records, written
far faster than real time and without DDS (`planter simulate`).

Each run is drawn from a seed and its number in the season (`draw_plan`): its speed (cruise, a
speed change, stops), a curve, ground-speed sensor glitches (a spike, a NaN reading, a drop-out
longer than the monitor's gap rule allows), now and then a drive stall on one row, and where
the field lies (GNSS). The machine is the sync node's own law for every row against the drive
model (sim.closed_loop.simulate_rows); what its sensors, drives and sync node reported goes
into the bag as the monitor would have received it: stamped when measured, logged a little
later, every topic of interfaces.RECORDED with the monitor's QoS, its settings and rows
records, chunks closed every second of log time. The monitor's own outputs (plants,
uprightness_rate) come from the monitor's own pipeline (prediction.pipeline.MonitorPipeline,
the one monitor_node runs) fed sample by sample in log-time order, and its messages are built
where the node builds them (recording.monitor_topics), so the bag carries what the node would
have published and replaying it reproduces them.
Every row with a seedling sensor (all rows, or those a scene declares with one: its
`seedling_sensor`, `<row>.seedling_sensor`) is fed by a simulated tray (`tray_readings`, sim.tray:
a cell empty with `empty_rate`, two seedlings with `double_rate`): one `seedlings` reading per
planting cycle, half a cycle before the planting angle; the monitor's model accounts every
instant by it (prediction.seedlings), a row without one as unknown.
The bag has no /diagnostics, sections, spacing_quality or plant_markers messages (the channels are
there): replay derives the indices and the map from the plants and fixes.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
import math
from pathlib import Path
from typing import Any, TypedDict

import numpy as np
from numpy.typing import ArrayLike, NDArray

from builtin_interfaces.msg import Time
from geometry_msgs.msg import TwistStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, String

from planter_ros import interfaces
from planter_ros.config import as_dict
from planter_ros.control.cam_law import plan_row_cam
from planter_ros.control.phase_lock import PhaseLockConfig, planting_angles
from planter_ros.design import Design, from_json, to_json
from planter_ros.geo import AntennaSettings
from planter_ros.prediction import (
    AcceptanceLimits, PredictionSettings, planting_model_from_design)
from planter_ros.prediction.pipeline import MonitorPipeline, Placed
from planter_ros.recording.monitor_topics import plants_message
from planter_ros.recording.recorder import BagLayout, Recorder
from planter_ros.recording.replay import map_record
from planter_ros.rows import Row, implicit_row, rows_record
from planter_ros.sensing.plant_map import GnssFix, MapSettings

from .closed_loop import (
    DriveModel, LoopTiming, MotionSensor, RowDesign, RowEvents, RowRun, SimMachine, simulate_rows)
from .field import Curve, FieldProfile, Stop
from .gnss import SimulatedGnss, fix_positions, navsatfix
from .runs import SIM_EPOCH, five_bar_design_message
from .tray import FULL_TRAY, Tray, TrayShares, sense_angle


ROW_PITCH = 0.5            # m between neighbouring simulated rows
SAMPLE_PERIOD = 0.05       # s, ground-speed sensor (20 Hz)
FEEDBACK_PERIOD = 0.01     # s, drive feedback and speed commands (100 Hz)
GNSS_PERIOD = 0.1          # s, GNSS fixes (10 Hz)
STEP = 0.0025              # s, integration step of the closed loop
ENCODER_COUNTS = 4096      # per mechanism revolution
RUN_PERIOD = 3600.0        # s of simulated clock between the starts of two runs of a season


def bag_name(seed: int, index: int) -> str:
    """The file name of run `index` of the season of `seed`."""
    return f'run_{seed}_{index:05d}.mcap'


@dataclass(frozen=True)
class Stall:
    """Row `row`'s drive reaches only `level` of its command from `start` for `length` s."""

    row: int
    start: float
    length: float
    level: float


@dataclass(frozen=True)
class Glitch:
    """A ground-speed sensor glitch: 'spike' (one reading `factor` times the truth), 'nan' (one
    NaN reading) or 'dropout' (no reading for `length` s)."""

    kind: str
    start: float
    length: float = 0.0
    factor: float = 1.0


@dataclass(frozen=True)
class RunPlan:
    """What happens in one simulated run (SI units, times in s from the run's start)."""

    index: int                    # the run's number in the season
    seed: int                     # the season's seed
    duration: float
    rows: tuple[Row, ...]
    cruise: float                 # m/s
    change: float                 # speed factor after the change at 45 % of the run
    stops: tuple[Stop, ...] = ()
    curves: tuple[Curve, ...] = ()
    glitches: tuple[Glitch, ...] = ()
    stall: Stall | None = None
    drive_lag: float = 0.05       # s, the drives' velocity time constant
    gnss: SimulatedGnss = field(default_factory=SimulatedGnss)
    empty_rate: float = 0.0       # the tray: share of empty cells, of cells with two seedlings
    double_rate: float = 0.0
    seedling_sensor: bool = True  # each row's cup sensor reads every cycle (topic seedlings)
    # a scene's spacing schedule: (t s from the run's start, Design) the design node publishes
    designs: tuple[tuple[float, Design], ...] = ()

    @property
    def start_time(self) -> float:
        """The run's start on the simulated clock (s since the epoch)."""
        return SIM_EPOCH + self.index * RUN_PERIOD

    def profile(self) -> FieldProfile:
        return FieldProfile(self.duration, self.cruise, change=self.change, curves=self.curves,
                            stops=self.stops)

    def events(self) -> dict[str, object]:
        """The plan for people and JSON (SI)."""
        return {'cruise': self.cruise, 'speed_change': self.change,
                'stops': [{'start': s.start, 'hold': s.hold} for s in self.stops],
                'curves': [{'start': c.start, 'end': c.end, 'radius': c.radius}
                           for c in self.curves],
                'glitches': [{'kind': g.kind, 'start': g.start, 'length': g.length}
                             for g in self.glitches],
                'spacing_changes': [{'start': t, 'spacing': d.plant_spacing}
                                    for t, d in self.designs],
                'stall': None if self.stall is None else {
                    'row': self.stall.row, 'start': self.stall.start,
                    'length': self.stall.length, 'level': self.stall.level}}


def machine_rows(count: int) -> tuple[Row, ...]:
    """`count` rows ROW_PITCH apart, centred on the machine, left first; one row is a machine
    without rows (the implicit row, as a scene without `rows`)."""
    if count == 1:
        return (implicit_row(),)
    return tuple(Row(i, f'row_{i + 1}', ROW_PITCH * (0.5 * (count - 1) - i), i + 1, True)
                 for i in range(count))


# a run's speed change, as a factor of its cruise speed (drawn)
SPEED_CHANGE_MIN, SPEED_CHANGE_MAX = 0.75, 1.35


def draw_plan(seed: int, index: int, duration: float, rows: int | Iterable[Row],
              cruise: tuple[float, float] = (0.15, 0.4), tray: TrayShares = FULL_TRAY
              ) -> RunPlan:
    """Run `index` of the season of `seed`: the same arguments give the same run. `rows`: a
    count (machine_rows) or the machine's rows (a scene's); `cruise`: the range (m/s) its
    cruise speed is drawn from; `tray`: its tray's empty and double shares."""
    machine = machine_rows(rows) if isinstance(rows, int) else tuple(rows)
    count = len(machine)
    rng = np.random.default_rng([int(seed), int(index)])
    d = float(duration)
    stops: list[Stop] = []
    if d >= 30.0:
        for _ in range(int(rng.choice(3, p=(0.4, 0.4, 0.2)))):
            stops.append(Stop(float(rng.uniform(0.1, 0.75) * d), float(rng.uniform(1.0, 4.0))))
    curves: list[Curve] = []
    if rng.random() < 0.75:
        length = float(rng.uniform(4.0, max(4.0, min(12.0, 0.3 * d))))
        start = float(rng.uniform(0.1 * d, max(0.1 * d, 0.85 * d - length)))
        radius = float(rng.uniform(6.0, 25.0)) * (1.0 if rng.random() < 0.5 else -1.0)
        curves.append(Curve(start, min(start + length, d - 3.0), radius))
    glitches: list[Glitch] = []
    for _ in range(min(int(rng.poisson(1.5)), 4)):
        kind = str(rng.choice(('spike', 'nan', 'dropout'), p=(0.4, 0.3, 0.3)))
        glitches.append(Glitch(kind, float(rng.uniform(3.0, d - 4.0)),
                               length=float(rng.uniform(0.6, 1.5)) if kind == 'dropout' else 0.0,
                               factor=float(rng.uniform(2.0, 4.0))))
    stall = None
    if rng.random() < 0.3:
        stall = Stall(int(rng.integers(count)), float(rng.uniform(0.15, 0.8) * d),
                      float(rng.uniform(0.5, 3.0)), float(rng.uniform(0.05, 0.3)))
    gnss = SimulatedGnss(origin_latitude=52.0 + float(rng.uniform(-0.05, 0.05)),
                         origin_longitude=5.0 + float(rng.uniform(-0.08, 0.08)),
                         origin_heading=float(rng.uniform(-math.pi, math.pi)))
    return RunPlan(index=int(index), seed=int(seed), duration=d, rows=machine,
                   cruise=float(rng.uniform(*cruise)),
                   change=float(rng.uniform(SPEED_CHANGE_MIN, SPEED_CHANGE_MAX)),
                   stops=tuple(sorted(stops, key=lambda s: s.start)), curves=tuple(curves),
                   glitches=tuple(sorted(glitches, key=lambda g: g.start)), stall=stall,
                   drive_lag=float(rng.uniform(0.03, 0.1)), gnss=gnss,
                   empty_rate=float(tray.empty_rate), double_rate=float(tray.double_rate))


@lru_cache(maxsize=1)
def season_design() -> Design:
    """The design of every simulated run (tomato, geared five-bar)."""
    return five_bar_design_message()


@dataclass
class MachineRun:
    """What the machine's sensors, drives and sync node reported in one run (times in s from
    its start)."""

    plan: RunPlan
    speed_t: np.ndarray           # ground-speed readings: times, v (m/s), yaw rate (rad/s)
    speed_v: np.ndarray
    speed_w: np.ndarray
    joint_t: np.ndarray           # drive feedback times
    joint_pos: np.ndarray         # (rows, n) measured shaft angle (rad, encoder-quantised)
    joint_vel: np.ndarray         # (rows, n) measured shaft speed (rad/s)
    command: np.ndarray           # (rows, n) speed command at the feedback times (rad/s)
    gnss_t: np.ndarray
    latitude: np.ndarray
    longitude: np.ndarray
    altitude: np.ndarray
    # the rows' seedling sensor readings: (row position in plan.rows, time s, count), in time
    # order; the count is what the tray put in that cycle's cup (0 empty, 1, 2 double)
    seedlings: tuple[tuple[int, float, int], ...] = ()


@lru_cache(maxsize=4)
def _cam(design_json: str, rule: str) -> Any:        # a control.cam_law row cam
    return plan_row_cam(from_json(design_json), rule)


def machine_cam(design: Design, law: PhaseLockConfig | None) -> Any:
    """The cam profile every row of the sync law `law` (a PhaseLockConfig) follows with
    `design` (control.cam_law.plan_row_cam, as the sync node plans it), or None: constant
    speed. A design the cam cannot run raises ValueError or CamError (one line): the sync node
    would fall back to constant speed with a warning; `planter simulate` refuses the scene."""
    if law is None or law.speed_profile != 'cam':
        return None
    return _cam(to_json(design), law.cam_rule)


def _row_cams(design: Design, law: PhaseLockConfig | None,
              rows: Sequence[Row]) -> list[Any] | None:
    cam = machine_cam(design, law)
    return None if cam is None else [cam] * len(rows)


def simulate_plan(plan: RunPlan, design: Design | None = None,
                  law: PhaseLockConfig | None = None) -> MachineRun:
    """Run the machine of `plan` in closed loop (no ROS): a MachineRun. `law`: the sync law's
    PhaseLockConfig (a scene's; default the defaults); with `speed_profile: cam` every row
    follows the cam planned for `design` (`machine_cam`) on a CSP drive, and for each design of
    `plan.designs` from its time on (the law takes it at the row's next planting instant)."""

    design = design or season_design()
    law = law or PhaseLockConfig()
    rng = np.random.default_rng([plan.seed, plan.index, 1])
    profile = plan.profile()
    readings: list[tuple[float, float, float]] = []

    def sensor(t: float, v: float, w: float) -> tuple[float, float] | None:
        for g in plan.glitches:
            if g.kind == 'dropout' and g.start <= t < g.start + g.length:
                return None
        # a standing wheel or radar reads 0; the gyro is noisy always
        v_read = v + rng.normal(0.0, 0.005) if v > 0.0 else 0.0
        w_read = w + rng.normal(0.0, 0.005)
        for g in plan.glitches:
            if g.start <= t < g.start + SAMPLE_PERIOD:
                if g.kind == 'spike':
                    v_read = g.factor * v + 0.3
                elif g.kind == 'nan':
                    v_read = math.nan
        readings.append((t, v_read, w_read))
        return v_read, w_read

    # the drive does what the law may ask of it (a cam scene's law: its out-of-soil arc)
    acceleration = max(DriveModel.max_acceleration, law.max_acceleration)
    nominal = DriveModel(time_constant=plan.drive_lag, max_acceleration=acceleration)
    changes: list[tuple[float, int, DriveModel]] = []
    if plan.stall is not None:
        s = plan.stall
        changes = [(s.start, s.row, DriveModel(time_constant=plan.drive_lag,
                                               max_acceleration=acceleration,
                                               speed_scale=s.level)),
                   (s.start + s.length, s.row, nominal)]
    machine = SimMachine([row.lateral_offset for row in plan.rows], law, drive=nominal,
                         timing=LoopTiming(STEP, SAMPLE_PERIOD, FEEDBACK_PERIOD))
    runs = simulate_rows(machine, profile, plan.duration,
                         RowDesign(design.plant_spacing, design.plants_per_revolution,
                                   planting_angles(design), _row_cams(design, law, plan.rows)),
                         MotionSensor(seed=plan.index, read=sensor),
                         RowEvents(drive_changes=changes,
                                   designs=[(t, d.plant_spacing, _row_cams(d, law, plan.rows))
                                            for t, d in plan.designs]))
    every = int(round(FEEDBACK_PERIOD / STEP))
    t = runs[0].t[::every]
    quantum = 2.0 * math.pi / ENCODER_COUNTS
    joint_pos = np.round(np.array([r.angle[::every] for r in runs]) / quantum) * quantum
    speed = np.array([r.speed[::every] for r in runs])
    joint_vel = speed + rng.normal(0.0, 0.02, speed.shape)
    command = np.array([r.command[::every] for r in runs])
    speed_t, speed_v, speed_w = (np.array(c) for c in zip(*readings)) if readings else \
        (np.zeros(0),) * 3
    gnss_t = np.arange(0.0, plan.duration, GNSS_PERIOD)
    lat, lon, alt = fix_positions(profile, gnss_t, plan.gnss, rng=rng)
    seedlings = tray_readings(plan, design, runs) if plan.seedling_sensor else ()
    return MachineRun(plan, speed_t, speed_v, speed_w, t, joint_pos, joint_vel, command,
                      gnss_t, lat, lon, alt, seedlings)


def tray_readings(plan: RunPlan, design: Design,
                  runs: Sequence[RowRun]) -> tuple[tuple[int, float, int], ...]:
    """The seedling sensor readings of a run: for every planting instant of every row one
    reading, half a planting cycle before the planting angle (the cup passing the sensor), of
    what the tray put in the cup: 0 with plan.empty_rate, 2 with plan.double_rate, else 1.
    A row the scene declares without a seedling sensor (Row.seedling_sensor) reads nothing."""
    model = planting_model_from_design(design)
    n = model.plants_per_revolution
    tray = Tray(plan.empty_rate, plan.double_rate,
                np.random.default_rng([plan.seed, plan.index, 3]))
    out: list[tuple[int, float, int]] = []
    for r, run in enumerate(runs):
        if plan.rows[r].seedling_sensor is False:
            continue                    # the scene declares this row without a sensor
        theta = np.maximum.accumulate(run.angle)
        first = math.ceil((theta[0] - model.planting_phase) * n / (2 * math.pi) + 0.5)
        last = math.floor((theta[-1] - model.planting_phase) * n / (2 * math.pi) + 0.5)
        ks = np.arange(first, last + 1)
        if not ks.size:
            continue
        i = np.searchsorted(theta, sense_angle(model, ks), side='left')
        i = i[i < theta.size]
        counts = tray.cells(i.size)
        out += [(r, float(run.t[k]), int(c)) for k, c in zip(i.tolist(), counts.tolist())]
    return tuple(sorted(out, key=lambda x: (x[1], x[0])))


class BagSummary(TypedDict):
    """What write_monitor_bag wrote (SI): the plan's events with the tray's counts."""

    bag: str
    run: int
    duration: float
    rows: int
    messages: int
    plants: int
    events: dict[str, Any]           # RunPlan.events() (JSON-ready) + empty_cells, double_cells


def write_monitor_bag(run: MachineRun, path: str | Path, machine: SceneMachine | None = None,
                      **recorder_options: Any) -> BagSummary:
    """Record `run` (a MachineRun) at `path` as monitor_node would have (see the module doc);
    the design and the monitor's settings, acceptance limits and antenna those of `machine`
    (a scene's SceneMachine; None: the season's design and the defaults); `recorder_options`
    (split_size, split_duration) as the monitor's parameters. Every message is written by
    recording.cdr.encode_message: the same run gives the same bytes. Returns a summary dict
    (SI)."""
    design = season_design() if machine is None else machine.design
    settings = PredictionSettings() if machine is None else machine.settings
    acceptance = AcceptanceLimits() if machine is None else machine.acceptance
    antenna = AntennaSettings() if machine is None else machine.antenna
    plan = run.plan
    rows = list(plan.rows)
    named = len(rows) > 1 or bool(rows[0].name)
    mechanism = design.mechanism
    joints = [row.joint(mechanism) for row in rows]
    rng = np.random.default_rng([plan.seed, plan.index, 2])
    epoch = int(round(plan.start_time * 1e9))

    def ns(t: ArrayLike) -> NDArray[np.int64]:
        return epoch + np.round(np.asarray(t, dtype=float) * 1e9).astype(np.int64)

    def stamp(value: int) -> Time:
        sec, nsec = divmod(int(value), 1_000_000_000)
        return Time(sec=sec, nanosec=nsec)

    # stamped when measured, received a little later (latencies in ns)
    speed_stamp = ns(run.speed_t)
    joint_stamp = ns(run.joint_t)
    gnss_stamp = ns(run.gnss_t)
    command_stamp = joint_stamp + 200_000             # sent after the feedback it answers
    logs = [speed_stamp + rng.integers(200_000, 3_000_000, speed_stamp.size),
            joint_stamp + rng.integers(500_000, 2_000_000, joint_stamp.size),
            command_stamp + rng.integers(200_000, 1_000_000, joint_stamp.size),
            gnss_stamp + rng.integers(5_000_000, 30_000_000, gnss_stamp.size)]
    seed_t = np.array([t for _, t, _ in run.seedlings], dtype=float)
    seedling_stamp = ns(seed_t)
    logs.append(seedling_stamp + rng.integers(200_000, 1_000_000, seedling_stamp.size))
    # the spacing schedule's designs, received 1 ms after the design node published them
    logs.append(ns([t for t, _ in plan.designs]) + 1_000_000)
    kinds = np.concatenate([np.full(a.size, k, dtype=np.int8) for k, a in enumerate(logs)])
    index = np.concatenate([np.arange(a.size) for a in logs])
    log = np.concatenate(logs)
    order = np.lexsort((index, kinds, log))

    clock = [0.0]                      # the recorder's flush clock: simulated log time
    rec = Recorder(path, BagLayout(flush_period=1.0, **recorder_options),
                   monotonic=lambda: clock[0])
    names = {topic: topic.resolved() for topic in interfaces.RECORDED}
    for topic in interfaces.RECORDED:
        rec.add_topic(names[topic], topic.type_name, topic.recording_qos())
    rec.add_metadata(interfaces.PREDICTION_SETTINGS_RECORD,
                     {k: repr(v) for k, v in as_dict(settings).items()})
    rec.add_metadata(interfaces.ROWS_RECORD, rows_record(rows))
    rec.add_metadata(interfaces.ACCEPTANCE_RECORD, {
        k: repr(v) for k, v in as_dict(acceptance).items()})
    map_settings = MapSettings()
    rec.add_metadata(interfaces.MAP_RECORD, map_record(map_settings, antenna))
    # the monitor's own pipeline, fed what it would have received, in its receive order
    monitor = MonitorPipeline(rows, settings, map_settings, antenna.antenna_position)
    start = int(log.min()) - 500_000_000 if log.size else epoch
    clock[0] = start * 1e-9
    rec.write_message(names[interfaces.DESIGN], String(data=to_json(design)), start)
    monitor.set_design(start * 1e-9, design)

    def publish(batches: Iterable[Placed], now: int) -> None:
        for batch in batches:
            rec.write_message(names[interfaces.PLANTS], plants_message(batch.plants), now, now)
            rec.write_message(names[interfaces.UPRIGHTNESS_RATE],
                              Float64(data=batch.upright_rate), now, now)

    speed_v, speed_w = run.speed_v.tolist(), run.speed_w.tolist()
    positions, velocities = run.joint_pos.T.tolist(), run.joint_vel.T.tolist()
    commands = run.command.T.tolist()
    lat, lon, alt = run.latitude.tolist(), run.longitude.tolist(), run.altitude.tolist()
    for k in order.tolist():
        kind, i, now = int(kinds[k]), int(index[k]), int(log[k])
        clock[0] = now * 1e-9
        if kind == 0:
            twist = TwistStamped()
            twist.header.stamp = stamp(speed_stamp[i])
            twist.twist.linear.x = speed_v[i]
            twist.twist.angular.z = speed_w[i]
            rec.write_message(names[interfaces.GROUND_SPEED], twist, now, int(speed_stamp[i]))
            publish(monitor.speed(int(speed_stamp[i]) * 1e-9, speed_v[i], speed_w[i]), now)
        elif kind == 1:
            state = JointState(name=joints, position=positions[i], velocity=velocities[i])
            state.header.stamp = stamp(joint_stamp[i])
            rec.write_message(names[interfaces.JOINT_STATES], state, now, int(joint_stamp[i]))
            publish(monitor.joints(int(joint_stamp[i]) * 1e-9, joints, positions[i],
                                   velocities[i]), now)
        elif kind == 2:
            if named:
                state = JointState(name=joints, velocity=commands[i])
                state.header.stamp = stamp(command_stamp[i])
                rec.write_message(names[interfaces.SPEED_COMMANDS], state, now,
                                  int(command_stamp[i]))
            else:
                rec.write_message(names[interfaces.SPEED_COMMAND], Float64(data=commands[i][0]),
                                  now, now)
        elif kind == 5:
            changed = plan.designs[i][1]
            rec.write_message(names[interfaces.DESIGN], String(data=to_json(changed)), now)
            monitor.set_design(now * 1e-9, changed)
        elif kind == 4:
            r, _, count = run.seedlings[i]
            state = JointState(name=[joints[r]], position=[float(count)])
            state.header.stamp = stamp(seedling_stamp[i])
            rec.write_message(names[interfaces.SEEDLINGS], state, now, int(seedling_stamp[i]))
            monitor.seedlings(int(seedling_stamp[i]) * 1e-9, state.name, state.position)
        else:
            msg = navsatfix(stamp(gnss_stamp[i]), lat[i], lon[i], alt[i], plan.gnss.noise)
            rec.write_message(names[interfaces.GNSS_FIX], msg, now, int(gnss_stamp[i]))
            cov = msg.position_covariance
            publish(monitor.fix(GnssFix(int(gnss_stamp[i]) * 1e-9, msg.status.status, lat[i],
                                        lon[i], cov[0], cov[4],
                                        msg.position_covariance_type)), now)
    publish(monitor.finish(), int(log.max()) if log.size else start)
    rec.close()
    counts = [c for _, _, c in run.seedlings]
    return {'bag': str(path), 'run': plan.index, 'duration': plan.duration,
            'rows': len(rows), 'messages': rec.message_count, 'plants': monitor.plants,
            'events': {**plan.events(), 'empty_cells': counts.count(0),
                       'double_cells': counts.count(2)}}


@dataclass(frozen=True)
class SceneMachine:
    """What a scene gives a simulated run (analysis.simulate.scene_machine builds it): the
    design, the rows, the monitor's settings, the crop's acceptance limits, the GNSS antenna
    and the cruise speeds drawn (m/s, around the scene's nominal ground speed)."""

    design: Design
    rows: tuple[Row, ...]
    settings: PredictionSettings
    acceptance: AcceptanceLimits
    antenna: AntennaSettings
    cruise: tuple[float, float]
    law: PhaseLockConfig | None = None    # the sync law (speed_profile, gains)
    schedule: tuple[tuple[float, Design], ...] = ()    # (t s of the run, Design): the scene's
                                                       # spacing schedule


def simulate_bag(path: str | Path, seed: int, index: int, duration: float,
                 machine: int | SceneMachine, tray: TrayShares = FULL_TRAY) -> BagSummary:
    """Draw run `index` of the season of `seed`, simulate it and record it at `path` (a task
    of `planter simulate`): `machine` a count of rows (a machine with the season's design) or a
    SceneMachine (a scene's design, rows, monitor settings, limits and antenna), its `tray`'s
    empty and double shares. Returns write_monitor_bag's summary; a bag left unfinished by an
    error is removed."""
    if isinstance(machine, int):
        plan = draw_plan(seed, index, duration, machine, tray=tray)
    else:
        plan = draw_plan(seed, index, duration, machine.rows, cruise=machine.cruise, tray=tray)
        plan = replace(plan, designs=tuple((t, d) for t, d in machine.schedule
                                           if t < plan.duration))
    existed = Path(path).exists()          # the recorder refuses it: never removed here
    try:
        if isinstance(machine, int):
            return write_monitor_bag(simulate_plan(plan), path)
        return write_monitor_bag(simulate_plan(plan, machine.design, machine.law), path,
                                 machine)
    except BaseException:
        if not existed:
            Path(path).unlink(missing_ok=True)
        raise
