"""Plausibility before work: is a scene (crop, mechanism, machine) one the machine can run?

Each value is already checked against its own range (config.setting). This module checks what
no single range can see, the values together with the drive:

refused (PlausibilityError, one line naming the value, the reason and the limit):

* **speed**: the mechanism speed ω = 2πv/(n·d) at the scene's ground speed v
  (`nominal_ground_speed`) over the sync law's `max_speed`, or the motor speed ω·gear ratio over
  the motor's top speed (a machine file's row limits);
* **acceleration**: keeping the phase while the tractor speeds up at `TRACTOR_ACCELERATION`
  needs α = 2π·a/(n·d); over the law's `max_acceleration` (or a machine file's row limit) the
  rows fall behind at every start and speed change;
* **bus load**: the worst-case CAN load of the enabled rows over 70 % of the bit rate
  (drive.bus_load, the sync node's own rule);
* **spacing / depth**: a spacing or a depth the mechanism cannot reach (no five-bar exists:
  k·D ≥ d or l1 ≤ 0; a three-arm design the model refuses) — the design model's own refusal;
* **the cam** (speed_profile: cam): its plan at the scene's top ground speed for the scene's
  spacing and each spacing of its schedule, and each change between them, within the drive's
  limits (control.cam_law, cam.track: the same planning the sync node's shell does);

warned (the scene runs; the value is unusual, the warning names the typical range):

* ground speed, depth and spacing outside what transplanters usually plant at (`TYPICAL`),
  more rows than a planter of this kind carries, a CAN bit rate no CiA 301 table lists, an
  accepted top ground speed (`max_ground_speed`, when the scene sets it) at which the rows can
  no longer keep up.

The same `check()` serves the command line, the scene loader (scene.open_scene) and the design
node's parameter callback; `check_law()` the same speed and acceleration checks for the sync
node's run-time limits against the design in force. Pure: no ROS, no bus. A design asked at
the command line loads only what its checks need (the law's limits; no scene files, no bus
model, no second design).
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
import math
from typing import Any

from planter_ros.config import ConfigError, from_mapping

__all__ = ['PlausibilityError', 'RowLimits', 'TYPICAL', 'TRACTOR_ACCELERATION', 'Verdict',
           'check', 'check_law', 'judge', 'unusual']

RPM = 60.0 / (2.0 * math.pi)              # r/min per rad/s

# what transplanters usually work at (SI): outside, a warning naming the range
TYPICAL = {
    'nominal_ground_speed': (0.05, 1.5, 'm/s'),   # walking pace; riding rice planters ~1.5
    'planting_depth': (0.01, 0.15, 'm'),
    'plant_spacing': (0.1, 1.0, 'm'),
}
TYPICAL_ROWS = 8                          # a planter of this kind carries 1..8 units
# a tractor's start or speed change the rows must follow while keeping their phase (a start
# from rest to 1 m/s in 2 s); an assumption of the check, not a measured figure
TRACTOR_ACCELERATION = 0.5                # m/s²
# CiA 301's bit-rate table (the rates CANopen devices support)
STANDARD_BITRATES = (10_000, 20_000, 50_000, 125_000, 250_000, 500_000, 800_000, 1_000_000)


class PlausibilityError(ConfigError):
    """A scene the machine cannot run; one line naming the value, the reason and the limit."""


@dataclass(frozen=True)
class RowLimits:
    """One drive's limits as a machine file gives them (SI, at the mechanism's shaft unless
    named motor): 0 = not given."""

    name: str
    max_speed: float = 0.0                # rad/s of the shaft
    max_acceleration: float = 0.0         # rad/s² of the shaft
    motor_max_speed: float = 0.0          # rad/s of the motor
    gear_ratio: float = 1.0               # motor turns per shaft turn


@dataclass
class Verdict:
    """What the checks found: refusals first (any one stops the work), then warnings."""

    refused: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.refused


def _g(x: float) -> str:
    return f'{x:.3g}'


def judge(params: Mapping[str, Any], row_limits: Sequence[RowLimits] = (),
          tractor_acceleration: float = TRACTOR_ACCELERATION, motion: bool = True,
          machine: bool = True, design: bool = True) -> Verdict:
    """Every check on a flat scene dict (the design node's and the sync node's parameters
    together; absent values take their defaults) and a machine file's row limits. `motion`
    False: the mechanism alone (no speed or acceleration check), for a design asked without a
    ground speed; `machine` False: no bus, rows or bit-rate check (a design at the command
    line); `design` False: the caller builds the design itself."""
    from planter_ros.control.phase_lock import PhaseLockConfig
    from planter_ros.kinematics.scene_settings import SceneSettings
    from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits

    out = Verdict()
    try:
        scene = from_mapping(SceneSettings, {**params, 'nozzle_width': params.get(
            'nozzle_width', 0.0)})
        law = from_mapping(PhaseLockConfig, params)
        ground = from_mapping(GroundSpeedLimits, params)
        if design:
            _design(params, out)
            if not out.refused and law.speed_profile == 'cam':
                _cam(params, law, out)
        if motion:
            _motion(out, params, scene, law, ground, row_limits, tractor_acceleration)
        if machine:
            _machine(out, params)
    except ConfigError as exc:             # a value outside its own range: the range says it
        out.refused.append(str(exc))
        return out
    out.warnings += unusual(scene)
    return out


def unusual(scene) -> list[str]:
    """The warnings of a scene's (kinematics.scene_settings.SceneSettings) values outside what
    transplanters typically work at, each naming the typical range."""
    out = []
    for name, (low, high, unit) in TYPICAL.items():
        value = getattr(scene, name, None)
        if value is not None and not low <= value <= high:
            out.append(f'{name} = {_g(value)} {unit} is unusual: transplanters typically work '
                       f'at {_g(low)}..{_g(high)} {unit}')
    return out


def _motion(out, params, scene, law, ground, row_limits, tractor_acceleration):
    from planter_ros.kinematics.mechanisms import PLANTS_PER_REVOLUTION
    _motion_of(out, scene.mechanism, PLANTS_PER_REVOLUTION[scene.mechanism],
               scene.plant_spacing, scene.nominal_ground_speed, law, ground, row_limits,
               tractor_acceleration, 'max_ground_speed' in params)


def check_law(design, law, ground, row_limits: Sequence[RowLimits] = (),
              tractor_acceleration: float = TRACTOR_ACCELERATION) -> list[str]:
    """The sync node's run-time limits (`law` a PhaseLockConfig, `ground` its
    GroundSpeedLimits) against the design in force (planter_ros.design: its mechanism, spacing,
    plants per revolution and nominal ground speed) and the machine file's `row_limits`: the
    same speed and acceleration checks as a scene's. PlausibilityError (the reason and the
    limit) for a refusal; the warnings."""
    out = Verdict()
    _motion_of(out, design.mechanism, design.plants_per_revolution, design.plant_spacing,
               design.nominal_ground_speed, law, ground, row_limits, tractor_acceleration,
               True)
    if out.refused:
        raise PlausibilityError(out.refused[0])
    return out.warnings


def _motion_of(out, mechanism, n, d, v, law, ground, row_limits, tractor_acceleration,
               ground_limit_given):
    shaft = 'sun bar' if mechanism == 'five_bar' else 'carrier'
    per_metre = 2.0 * math.pi / (n * d)   # shaft rad per metre travelled
    if v is None:                          # a design without a nominal speed: no speed check
        v = 0.0
    _speed(out, shaft, per_metre, d, v, law.max_speed, 'max_speed', 'the sync law')
    _acceleration(out, shaft, per_metre, d, tractor_acceleration, law.max_acceleration,
                  'max_acceleration', 'the sync law')
    for row in row_limits:
        where = f'row {row.name or "(implicit)"} of the machine file'
        if row.max_speed:
            _speed(out, shaft, per_metre, d, v, row.max_speed, 'max_speed', where)
        if row.motor_max_speed:
            _speed(out, f'motor ({row.gear_ratio:g} turns per {shaft} turn)',
                   per_metre * row.gear_ratio, d, v, row.motor_max_speed, 'motor_max_speed',
                   where)
        if row.max_acceleration:
            _acceleration(out, shaft, per_metre, d, tractor_acceleration, row.max_acceleration,
                          'max_acceleration', where)
    if ground_limit_given and per_metre * ground.max_ground_speed > law.max_speed:
        out.warnings.append(
            f'max_ground_speed = {_g(ground.max_ground_speed)} m/s is accepted, but above '
            f'{_g(law.max_speed / per_metre)} m/s the {shaft} is held at max_speed = '
            f'{_g(law.max_speed)} rad/s and plants land farther apart than {_g(d)} m')


def _machine(out, params):
    """The bus, the rows and the bit rate (ConfigError for a value out of its range)."""
    from planter_ros.control.loop_timing import SyncLoopConfig
    from planter_ros.drive.config import DriveConfig
    from planter_ros.rows import rows_from_scene
    drive = from_mapping(DriveConfig, params)
    loop = from_mapping(SyncLoopConfig, params)
    rows = rows_from_scene(params, drive.drive_node_id)
    _bus(out, rows, drive, loop)
    if len(rows) > TYPICAL_ROWS:
        out.warnings.append(f'rows: {len(rows)} planting units is unusual: a transplanter of '
                            f'this kind typically carries 1..{TYPICAL_ROWS}')
    if drive.can_bitrate not in STANDARD_BITRATES:
        out.warnings.append(
            f'can_bitrate = {drive.can_bitrate} bit/s is not a CiA 301 bit rate: typically '
            + ', '.join(f'{b // 1000}k' for b in STANDARD_BITRATES) + ' bit/s')


def _design(params, out):
    from planter_ros.design import design_for_scene
    try:
        design_for_scene({**params, 'nozzle_width': params.get('nozzle_width', 0.0)})
    except ConfigError as exc:
        out.refused.append(f'no mechanism reaches this spacing and depth: {exc}')


def _cam(params, law, out):
    """A cam scene (speed_profile: cam): its cam planned as the sync node's shell plans it
    (control.cam_law, at the scene's top ground speed) for its plant_spacing and every
    spacing of its spacing_schedule in turn, each change checked as the rows would make it:
    a plan or change over the drive's limits, or a design the cam cannot run, refused."""
    from planter_ros.cam import CamError
    from planter_ros.control.cam_law import plan_for_design
    from planter_ros.design import design_for_scene
    flat = params.get('spacing_schedule') or []
    spacings = [params.get('plant_spacing')] + list(flat[1::2])
    previous, last = None, None
    for spacing in spacings:
        if spacing is None or spacing == last:
            continue
        last = spacing
        where = '' if previous is None else f' (spacing_schedule, to {spacing:g} m)'
        try:
            design = design_for_scene({**params, 'plant_spacing': spacing,
                                       'nozzle_width': params.get('nozzle_width', 0.0)})
            profile, why = plan_for_design(design, law.cam_rule, previous)
        except (ConfigError, CamError) as exc:
            out.refused.append(f'speed_profile = cam cannot run{where}: {exc}')
            return
        if profile is None:
            why = why.removesuffix(': constant speed')
            out.refused.append(f'speed_profile = cam cannot run{where}: {why}; allowed a '
                               'five-bar the cam can plan, or speed_profile: constant')
            return
        previous = profile


def _speed(out, shaft, per_metre, d, v, limit, limit_name, where):
    omega = per_metre * v
    if omega > limit:
        out.refused.append(
            f'nominal_ground_speed = {_g(v)} m/s needs the {shaft} at {_g(omega)} rad/s '
            f'({omega * RPM:.0f} r/min) for plant_spacing = {_g(d)} m: over {limit_name} = '
            f'{_g(limit)} rad/s ({limit * RPM:.0f} r/min) of {where}; allowed '
            f'nominal_ground_speed <= {_g(limit / per_metre)} m/s at this spacing')


def _acceleration(out, shaft, per_metre, d, tractor, limit, limit_name, where):
    alpha = per_metre * tractor
    if alpha > limit:
        shortest = per_metre * d * tractor / limit       # α = 2πa/(n·d) <= limit
        out.refused.append(
            f'following a tractor speeding up at {_g(tractor)} m/s² needs the {shaft} to '
            f'accelerate at {_g(alpha)} rad/s²: over {limit_name} = {_g(limit)} rad/s² of '
            f'{where}; allowed plant_spacing >= {_g(shortest)} m at this limit')


def _bus(out, rows, drive, loop):
    from planter_ros.drive.bus_load import bus_load, check_bus_load
    from planter_ros.drive.errors import DriveConfigError
    enabled = [row for row in rows if row.enabled]
    load = bus_load(len(enabled), drive.can_bitrate, loop.control_period, loop.ground_speed_rate,
                    drive.feedback_period, drive.drive_heartbeat_period, drive.heartbeat_period)
    try:
        check_bus_load(load, [row.label for row in enabled], loop.control_period,
                       loop.ground_speed_rate, drive.feedback_period,
                       drive.drive_heartbeat_period, drive.heartbeat_period)
    except DriveConfigError as exc:
        out.refused.append(str(exc))


def check(params: Mapping[str, Any], row_limits: Sequence[RowLimits] = (),
          where: str = '', motion: bool = True) -> list[str]:
    """The warnings of a scene the machine can run; PlausibilityError (the first refusal, one
    line, prefixed with `where`) for one it cannot."""
    verdict = judge(params, row_limits, motion=motion)
    if verdict.refused:
        raise PlausibilityError(f'{where}{verdict.refused[0]}')
    return verdict.warnings


def check_design_query(program: str, depth: float, spacing: float, hole_ratio: float,
                       speed: float | None) -> None:
    """The command line's five-bar design (`planter design five-bar`): its depth, spacing,
    hole ratio and ground speed (None: not given) checked, each warning printed on stderr as
    `program: warning: ...`; PlausibilityError for a refusal. Without a ground speed only the
    mechanism is checked."""
    import sys
    given = {'planting_depth': depth, 'plant_spacing': spacing, 'hole_ratio': hole_ratio}
    if speed is not None:
        given['nominal_ground_speed'] = speed
    verdict = judge(given, motion=speed is not None, machine=False, design=False)
    if verdict.refused:
        raise PlausibilityError(verdict.refused[0])
    for warning in verdict.warnings:
        print(f'{program}: warning: {warning}', file=sys.stderr)
