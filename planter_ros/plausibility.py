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
* **the highest speed**: the same speed checks at the scene's `top_ground_speed` (0: 1.5 ×
  the nominal speed, the demo's field run);
* **the drive train**: a row's encoder through its gear ratio coarser than
  `MIN_COUNTS_PER_TURN` counts per mechanism turn; a row's drive on the master's own node id;
* **bus load**: the worst-case CAN load of the enabled rows over 70 % of the bit rate
  (drive.bus_load, the sync node's own rule; `bus_rows` for a command that builds rows);
* **reach**: a three-arm planting deeper than its gearbox clears (the gearbox in the soil);
* **spacing / depth**: a spacing or a depth the mechanism cannot reach (no five-bar exists:
  k·D ≥ d or l1 ≤ 0; a three-arm design the model refuses) — the design model's own refusal;
* **the cam** (speed_profile: cam): its plan at the scene's top ground speed for the scene's
  spacing and each spacing of its schedule, and each change between them, within the drive's
  limits (control.cam_law, cam.track: the same planning the sync node's shell does);

warned (the scene runs; the value is unusual, the warning names the typical range):

* a value a design is made from that the scene leaves out (`DESIGN_KEYS`): its default named;
* ground speed, depth and spacing outside what transplanters usually plant at (`TYPICAL`),
  more rows than a planter of this kind carries, rows on top of each other or closer than
  `ROW_GAP_MIN`, a machine wider than `MACHINE_WIDTH_MAX`, a CAN bit rate no CiA 301 table
  lists, an
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
import sys
from typing import Any

from planter_ros.config import ConfigError, from_mapping, spec_of
from planter_ros.control.phase_lock import PhaseLockConfig
from planter_ros.kinematics.design_inputs import DesignInputs, top_ground_speed
from planter_ros.kinematics.mechanisms import PLANTS_PER_REVOLUTION
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits

# The design command (`planter design five-bar --speed`) loads this module for its speed checks
# but none of the drive, rows, design or cam modules of the checks it does not run (the bus,
# the rows, a scene's design, the cam: drive.config 29 ms, drive.bus_load 26 ms, rows 8 ms,
# cam 69 ms measured with python -X importtime; test_skip_what_a_scene_does_not_need holds
# the design command to its modules): those are imported inside their checks, `# lazy:`.

__all__ = ['PlausibilityError', 'RowLimits', 'TYPICAL', 'TRACTOR_ACCELERATION', 'Verdict',
           'bus_rows', 'check', 'check_law', 'judge', 'unusual']

RPM = 60.0 / (2.0 * math.pi)              # r/min per rad/s

# what transplanters usually work at (SI): outside, a warning naming the range
TYPICAL = {
    'nominal_ground_speed': (0.05, 1.5, 'm/s'),   # walking pace; riding rice planters ~1.5
    'planting_depth': (0.01, 0.15, 'm'),
    'plant_spacing': (0.1, 1.0, 'm'),
}
TYPICAL_ROWS = 8                          # a planter of this kind carries 1..8 units
# the narrowest row gap seedlings are planted at (rice: 0.2-0.3 m, vegetables 0.3 m and more)
# and the widest transplanter (12 rows at 0.75 m is 9 m; none spans more than about 12 m)
ROW_GAP_MIN = 0.15                        # m
MACHINE_WIDTH_MAX = 12.0                  # m
# the coarsest position a CSP drive and the monitor can work from: a count per 0.1 degree
# of the mechanism (at 0.5 m spacing a count is then 0.14 mm of the row)
MIN_COUNTS_PER_TURN = 3600
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
    encoder_counts: int = 0               # counts per motor turn (0: not given)


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


@dataclass(frozen=True)
class _Limits:
    """What the rows must keep within while following the tractor: the sync law's limits
    (a PhaseLockConfig), the ground speeds it accepts (GroundSpeedLimits), a machine file's
    row limits and the tractor's acceleration to follow."""

    law: PhaseLockConfig
    ground: GroundSpeedLimits
    rows: Sequence[RowLimits] = ()
    tractor_acceleration: float = TRACTOR_ACCELERATION


@dataclass(frozen=True)
class _Shaft:
    """The shaft a speed check is about: its name, its rad per metre travelled (2π/(n·d)) and
    the plant spacing d (m)."""

    name: str
    per_metre: float
    spacing: float


@dataclass(frozen=True)
class _Limit:
    """One limit checked: its value, its name and where it is set."""

    value: float
    name: str
    where: str


def _shaft(mechanism: str, n: int, d: float) -> _Shaft:
    return _Shaft('sun bar' if mechanism == 'five_bar' else 'carrier', 2.0 * math.pi / (n * d),
                  d)


def judge(params: Mapping[str, Any], row_limits: Sequence[RowLimits] = (),
          tractor_acceleration: float = TRACTOR_ACCELERATION, motion: bool = True,
          machine: bool = True, design: bool = True) -> Verdict:
    """Every check on a flat scene dict (the design node's and the sync node's parameters
    together; absent values take their defaults) and a machine file's row limits. `motion`
    False: the mechanism alone (no speed or acceleration check), for a design asked without a
    ground speed; `machine` False: no bus, rows or bit-rate check (a design at the command
    line); `design` False: the caller builds the design itself."""
    out = Verdict()
    try:
        scene = from_mapping(DesignInputs, {**params, 'nozzle_width': params.get(
            'nozzle_width', 0.0)})
        law = from_mapping(PhaseLockConfig, params)
        ground = from_mapping(GroundSpeedLimits, params)
        if design:
            out.warnings += _defaults(params, scene.mechanism)
            _design(params, out)
            if not out.refused and law.speed_profile == 'cam':
                _cam(params, law, out)
        if motion:
            _motion(out, params, scene,
                    _Limits(law, ground, row_limits, tractor_acceleration))
        if machine:
            _machine(out, params)
    except ConfigError as exc:             # a value outside its own range: the range says it
        out.refused.append(str(exc))
        return out
    out.warnings += unusual(scene)
    return out


# the values a design is made from that no default fits every crop: a scene that leaves one
# out is told which default it got (no silent input)
DESIGN_KEYS = ('mechanism', 'planting_depth', 'plant_spacing', 'nominal_ground_speed')
FIVE_BAR_KEYS = ('hole_ratio',)


def _defaults(params, mechanism):
    keys = DESIGN_KEYS + (FIVE_BAR_KEYS if mechanism == 'five_bar' else ())
    out = []
    for name in keys:
        if name not in params:
            spec = spec_of(DesignInputs, name)
            unit = f' {spec.unit}' if spec.unit else ''
            out.append(f'{name} is not set: the design uses the default {spec.default:g}'
                       f'{unit}; set it for the crop and machine' if spec.kind is float else
                       f'{name} is not set: the design uses the default {spec.default}')
    return out


def unusual(scene) -> list[str]:
    """The warnings of a scene's (kinematics.design_inputs.DesignInputs) values outside what
    transplanters typically work at, each naming the typical range."""
    out = []
    for name, (low, high, unit) in TYPICAL.items():
        value = getattr(scene, name, None)
        if value is not None and not low <= value <= high:
            out.append(f'{name} = {_g(value)} {unit} is unusual: transplanters typically work '
                       f'at {_g(low)}..{_g(high)} {unit}')
    return out


def _motion(out, params, scene, limits):
    n = PLANTS_PER_REVOLUTION[scene.mechanism]
    shaft = _shaft(scene.mechanism, n, scene.plant_spacing)
    _motion_of(out, limits, shaft, scene.nominal_ground_speed, 'max_ground_speed' in params)
    top = top_ground_speed(scene.nominal_ground_speed, scene.top_ground_speed)
    if not out.refused and top > scene.nominal_ground_speed:
        # the highest speed the scene plants at, through the same limits
        name = 'top_ground_speed' if scene.top_ground_speed else \
            'top_ground_speed (0: 1.5 × nominal_ground_speed)'
        _motion_of(out, limits, shaft, top, False, speed_name=name)
    _resolution(out, scene, n, limits.rows)


def _resolution(out, scene, n, row_limits):
    """Each row's encoder through its gear ratio against MIN_COUNTS_PER_TURN."""
    for row in row_limits:
        if not row.encoder_counts:
            continue
        counts = row.encoder_counts * row.gear_ratio
        if counts < MIN_COUNTS_PER_TURN:
            where = f'row {row.name or "(implicit)"} of the machine file'
            shaft = 'sun bar' if scene.mechanism == 'five_bar' else 'carrier'
            out.refused.append(
                f'encoder_counts = {row.encoder_counts} per motor turn through gear_ratio = '
                f'{row.gear_ratio:g} is {counts:g} counts per {shaft} turn '
                f'({360.0 / counts:.3g} deg, {scene.plant_spacing / (n * counts) * 1000:.3g} '
                f'mm of the row) on {where}: allowed >= {MIN_COUNTS_PER_TURN} counts per '
                f'{shaft} turn (encoder_counts >= '
                f'{math.ceil(MIN_COUNTS_PER_TURN / row.gear_ratio)})')


def check_law(design, law, ground, row_limits: Sequence[RowLimits] = (),
              tractor_acceleration: float = TRACTOR_ACCELERATION) -> list[str]:
    """The sync node's run-time limits (`law` a PhaseLockConfig, `ground` its
    GroundSpeedLimits) against the design in force (planter_ros.design: its mechanism, spacing,
    plants per revolution and nominal ground speed) and the machine file's `row_limits`: the
    same speed and acceleration checks as a scene's. PlausibilityError (the reason and the
    limit) for a refusal; the warnings."""
    out = Verdict()
    _motion_of(out, _Limits(law, ground, row_limits, tractor_acceleration),
               _shaft(design.mechanism, design.plants_per_revolution, design.plant_spacing),
               design.nominal_ground_speed, True)
    if out.refused:
        raise PlausibilityError(out.refused[0])
    return out.warnings


def _motion_of(out, limits, shaft, v, ground_limit_given, speed_name='nominal_ground_speed'):
    """The speed and acceleration checks of `shaft` (_Shaft) at ground speed `v` (m/s, its
    name `speed_name`) against `limits` (_Limits)."""
    law, ground, tractor = limits.law, limits.ground, limits.tractor_acceleration
    per_metre, d = shaft.per_metre, shaft.spacing    # shaft rad per metre travelled
    if v is None:                          # a design without a nominal speed: no speed check
        v = 0.0
    _speed(out, shaft, v, _Limit(law.max_speed, 'max_speed', 'the sync law'), speed_name)
    _acceleration(out, shaft, tractor,
                  _Limit(law.max_acceleration, 'max_acceleration', 'the sync law'))
    for row in limits.rows:
        where = f'row {row.name or "(implicit)"} of the machine file'
        if row.max_speed:
            _speed(out, shaft, v, _Limit(row.max_speed, 'max_speed', where), speed_name)
        if row.motor_max_speed:
            motor = _Shaft(f'motor ({row.gear_ratio:g} turns per {shaft.name} turn)',
                           per_metre * row.gear_ratio, d)
            _speed(out, motor, v, _Limit(row.motor_max_speed, 'motor_max_speed', where),
                   speed_name)
        if row.max_acceleration:
            _acceleration(out, shaft, tractor,
                          _Limit(row.max_acceleration, 'max_acceleration', where))
    if ground_limit_given and per_metre * ground.max_ground_speed > law.max_speed:
        out.warnings.append(
            f'max_ground_speed = {_g(ground.max_ground_speed)} m/s is accepted, but above '
            f'{_g(law.max_speed / per_metre)} m/s the {shaft.name} is held at max_speed = '
            f'{_g(law.max_speed)} rad/s and plants land farther apart than {_g(d)} m')


def _machine(out, params):
    """The bus, the rows and the bit rate (ConfigError for a value out of its range)."""
    from planter_ros.control.loop_timing import SyncLoopConfig  # lazy: bus checks only
    from planter_ros.drive.config import DriveConfig  # lazy: bus checks only (29 ms)
    from planter_ros.rows import rows_from_scene  # lazy: row checks only (8 ms)
    drive = from_mapping(DriveConfig, params)
    loop = from_mapping(SyncLoopConfig, params)
    rows = rows_from_scene(params, drive.drive_node_id)
    for row in rows:
        if row.drive_node_id == drive.master_node_id:
            out.refused.append(
                f'{row.name + "." if row.name else ""}drive_node_id = {row.drive_node_id} is '
                f'the master\'s own node id (master_node_id = {drive.master_node_id}): allowed '
                f'1..127 except {drive.master_node_id}')
    _bus(out, rows, drive, loop)
    _layout(out, rows)
    if len(rows) > TYPICAL_ROWS:
        out.warnings.append(f'rows: {len(rows)} planting units is unusual: a transplanter of '
                            f'this kind typically carries 1..{TYPICAL_ROWS}')
    if drive.can_bitrate not in STANDARD_BITRATES:
        out.warnings.append(
            f'can_bitrate = {drive.can_bitrate} bit/s is not a CiA 301 bit rate: typically '
            + ', '.join(f'{b // 1000}k' for b in STANDARD_BITRATES) + ' bit/s')


def _layout(out, rows):
    """Rows on top of each other or closer than seedlings are planted, a machine wider than
    any transplanter: warned (a row's offset may be measured wrong, not impossible)."""
    placed = sorted((row.lateral_offset, row.name) for row in rows if row.name)
    for (y0, a), (y1, b) in zip(placed, placed[1:]):
        if y1 - y0 < 1e-9:
            out.warnings.append(f'rows {a} and {b} have the same lateral_offset = {_g(y0)} m: '
                                'they plant into one row; typically rows are at least '
                                f'{_g(ROW_GAP_MIN)} m apart')
        elif y1 - y0 < ROW_GAP_MIN:
            out.warnings.append(f'rows {a} and {b} are {_g(y1 - y0)} m apart (lateral_offset '
                                f'{_g(y0)} and {_g(y1)} m): unusual, seedling rows are '
                                f'typically at least {_g(ROW_GAP_MIN)} m apart')
    if len(placed) > 1 and placed[-1][0] - placed[0][0] > MACHINE_WIDTH_MAX:
        out.warnings.append(f'the rows span {_g(placed[-1][0] - placed[0][0])} m '
                            f'({placed[0][1]} to {placed[-1][1]}): unusual, transplanters are '
                            f'typically at most {_g(MACHINE_WIDTH_MAX)} m wide')


def bus_rows(count, params=None):
    """The refusal (one line) of `count` rows on the bus `params` set (defaults: the sync
    node's: 500 kbit/s, ...), or '' when they fit: a command that builds rows checks them as
    the sync node would."""
    from planter_ros.control.loop_timing import SyncLoopConfig  # lazy: bus checks only
    # lazy: only a bus check needs it (26 ms)
    from planter_ros.drive.bus_load import BusTiming, bus_load, check_bus_load
    from planter_ros.drive.config import DriveConfig  # lazy: bus checks only (29 ms)
    from planter_ros.drive.errors import DriveConfigError  # lazy: bus checks only
    params = params or {}
    drive = from_mapping(DriveConfig, params)
    loop = from_mapping(SyncLoopConfig, params)
    timing = BusTiming.of(drive, loop.control_period, loop.ground_speed_rate)
    try:
        check_bus_load(bus_load(count, drive.can_bitrate, timing), [], timing)
    except DriveConfigError as exc:
        return str(exc)
    return ''


def _design(params, out):
    from planter_ros.design import design_for_scene  # lazy: a scene's design check only
    try:
        design = design_for_scene({**params, 'nozzle_width': params.get('nozzle_width', 0.0)})
    except ConfigError as exc:
        out.refused.append(f'no mechanism reaches this spacing and depth: {exc}')
        return
    _reach(out, design, params.get('arm_length'))


def _reach(out, design, arm):
    """A three-arm's depth beyond its reach: the gearbox would turn in the soil."""
    goals = {goal.name: goal for goal in getattr(design, 'goals', None) or ()}
    clearance = goals.get('gearbox_clearance')
    if clearance is None or clearance.value >= 0.0:
        return
    depth = design.planting_depth
    out.refused.append(
        f'planting_depth = {_g(depth)} m is beyond the three-arm\'s reach: its gearbox would '
        f'turn {_g(-clearance.value)} m deep in the soil'
        + (f' (arm_length = {_g(arm)} m)' if arm else '')
        + f'; allowed planting_depth <= {_g(depth + clearance.value)} m')


def _cam(params, law, out):
    """A cam scene (speed_profile: cam): its cam planned as the sync node's shell plans it
    (control.cam_law, at the scene's top ground speed) for its plant_spacing and every
    spacing of its spacing_schedule in turn, each change checked as the rows would make it:
    a plan or change over the drive's limits, or a design the cam cannot run, refused."""
    from planter_ros.cam import CamError  # lazy: a cam scene's check only (69 ms)
    from planter_ros.control.cam_law import plan_for_design  # lazy: a cam scene's check only
    from planter_ros.design import design_for_scene  # lazy: a scene's design check only
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


def _speed(out: Verdict, shaft: _Shaft, v: float, limit: _Limit,
           speed_name: str = 'nominal_ground_speed') -> None:
    """`shaft` at ground speed `v` (m/s) against a speed `limit` (rad/s)."""
    per_metre, top = shaft.per_metre, limit.value
    omega = per_metre * v
    if omega > top:
        short = speed_name.split(' ')[0]
        out.refused.append(
            f'{speed_name} = {_g(v)} m/s needs the {shaft.name} at {_g(omega)} rad/s '
            f'({omega * RPM:.0f} r/min) for plant_spacing = {_g(shaft.spacing)} m: over '
            f'{limit.name} = {_g(top)} rad/s ({top * RPM:.0f} r/min) of {limit.where}; '
            f'allowed {short} <= {_g(top / per_metre)} m/s at this spacing')


def _acceleration(out: Verdict, shaft: _Shaft, tractor: float, limit: _Limit) -> None:
    """`shaft` following a tractor speeding up at `tractor` (m/s²) against an acceleration
    `limit` (rad/s²)."""
    per_metre, top = shaft.per_metre, limit.value
    alpha = per_metre * tractor
    if alpha > top:
        shortest = per_metre * shaft.spacing * tractor / top     # α = 2πa/(n·d) <= limit
        out.refused.append(
            f'following a tractor speeding up at {_g(tractor)} m/s² needs the {shaft.name} to '
            f'accelerate at {_g(alpha)} rad/s²: over {limit.name} = {_g(top)} rad/s² of '
            f'{limit.where}; allowed plant_spacing >= {_g(shortest)} m at this limit')


def _bus(out, rows, drive, loop):
    # lazy: only a bus check needs it (26 ms)
    from planter_ros.drive.bus_load import BusTiming, bus_load, check_bus_load
    from planter_ros.drive.errors import DriveConfigError  # lazy: bus checks only
    enabled = [row for row in rows if row.enabled]
    timing = BusTiming.of(drive, loop.control_period, loop.ground_speed_rate)
    load = bus_load(len(enabled), drive.can_bitrate, timing)
    try:
        check_bus_load(load, [row.label for row in enabled], timing)
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
    given = {'planting_depth': depth, 'plant_spacing': spacing, 'hole_ratio': hole_ratio}
    if speed is not None:
        given['nominal_ground_speed'] = speed
    verdict = judge(given, motion=speed is not None, machine=False, design=False)
    if verdict.refused:
        raise PlausibilityError(verdict.refused[0])
    for warning in verdict.warnings:
        print(f'{program}: warning: {warning}', file=sys.stderr)
