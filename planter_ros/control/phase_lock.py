"""Phase-locked mechanism speed: keep the planting mechanism in step with the travelled distance.

Plant spacing is a *position* relation: the mechanism must have turned θ = 2π s / (n d) when
the machine has travelled s (n plants per revolution, d the spacing). Following the speed
ω = 2π v / (n d) alone (feed-forward) lets every drive lag, acceleration limit, scale error or
dropped sample shift all later plants for good. This law adds a bounded proportional correction
from the phase error e = θ_target − θ_measured, so the angle converges back to the distance:

    ω_cmd = clamp(ω_ff + clamp(k_p · e, ±max_correction), 0, max_speed), rate-limited.

Choices the papers leave open, made here on purpose:
* The command is never negative: a stopped or reversing machine does not plant backwards; a
  mechanism ahead of its target waits.
* Ground-speed samples pass the same plausibility rule as the monitor's
  (`planter_ros.sensing.ground_speed_filter`): NaN/inf, too fast and spikes are rejected and
  counted; a plausible negative sample (reversing, or noise around standstill) is counted and
  read as "not moving forward": the feed-forward is 0 and distance is not integrated backwards.
* No accepted sample for `ground_speed_timeout`: the travelled distance stops growing, the
  target speed is 0, the command ramps down at the acceleration limit and then halts.
* The law never tries to make up more than one plant: when |e| exceeds one plant pitch 2π/n
  (after a drive fault or a long stale period) the target jumps by whole pitches, so later
  plants stay on the original grid and the missed ones are simply missing (counted as slips).
* Section control: switched off, the row comes to rest at the angle `stop_angle` chooses (out
  of the soil, before the next planting angle unless braking cannot stop it in front of the
  soil, which happens only when it is already there), braking along √(2·a·remaining angle)
  from the measured angle; switched on, it speeds up on feed-forward alone and a new grid is
  anchored where it reaches the row's speed (no catching up with the old grid or with the
  ramp's lag, so no plant comes too soon).
* A row of a machine on a curve gets its own speed v_i already filtered (`row_speed`); the
  filter then is the machine's (shared, so its counts are the machine's).
* A new design while the row runs on its grid takes effect at the row's next planting
  instant: the plant the mechanism sets next (the first planting angle beyond the measured
  angle when the design arrives) is still placed on the old grid, at the distance s_k where
  the old grid wants it, and from there plants follow at the new spacing: the target angle is
  continuous (no jump in phase) and the grid goes on instead of restarting wherever the
  mechanism happens to be. Without known planting angles, or with another number of plants
  per revolution (another mechanism), the design applies at once (the target still continuous
  for the former, a new grid for the latter).

* `speed_profile: cam` (doc/cam.md): a design handed in with a planned cam profile
  (`cam_law.plan_row_cam`) makes the row's target θ(s) of its own phase-locked travelled
  distance, the feed-forward θ′(s)·v, instead of the straight line 2πs/(n·d). The cam is held
  in a `CamTrack` anchored where the grid is anchored (θ there = the measured angle); a new
  cam while the row runs on its grid goes through `CamTrack.change`: it takes effect at the
  track's next planting instant with θ, θ′ and θ″ continuous, through a transition checked
  against the drive's limits; a change no transition makes within them is refused (the
  row keeps its design and cam: `check_cam`, CamLimitError). Without a profile (constant, a
  drive without CSP, another mechanism) the law is the straight line, unchanged.

Time is passed in explicitly (monotonic seconds), so the law is deterministic and testable.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import TYPE_CHECKING, Any

from planter_ros.config import ConfigError, check, choice, setting
from planter_ros.sensing.ground_speed_filter import GroundSpeedFilter, GroundSpeedLimits

from .odometer import Odometer

if TYPE_CHECKING:
    from planter_ros.cam import CamProfile, CamTrack

TWO_PI = 2.0 * math.pi
# measured angle is extrapolated with the measured speed for at most this long (s)
_MAX_FEEDBACK_EXTRAPOLATION = 0.05
# the acceleration limit never integrates over a gap longer than this (s)
_MAX_RATE_STEP = 0.1
# a row switched off is at rest once it is this close to its stop angle (rad)
PARK_TOLERANCE = 0.02
# s of the row's speed a stop may overshoot by (the drive's speed lag, the feedback delay):
# a stop that close to the soil is taken as in it
STOP_LAG = 0.05


class ControlConfigError(ConfigError):
    """A control parameter outside its allowed range; the message is one line."""


@dataclass(frozen=True)
class PhaseLockConfig:
    """Limits and gains of the law (SI; mechanism shaft speeds in rad/s): parameters of the
    sync node, changeable at run time."""

    max_speed: float = setting(20.0, 'mechanism speed limit', unit='rad/s', range=(0.1, 100.0))
    max_acceleration: float = setting(20.0, 'mechanism acceleration limit', unit='rad/s²',
                                      range=(0.1, 1000.0))
    phase_gain: float = setting(4.0, 'phase correction gain: rad/s of correction per rad of '
                                'phase error', unit='1/s', range=(0.0, 50.0))
    max_correction: float = setting(2.0, 'bound of the phase correction', unit='rad/s',
                                    range=(0.0, 50.0))
    phase_lock: bool = setting(True, 'true: phase-locked to travelled distance; false: '
                               'speed-only (feed-forward)')
    ground_speed_timeout: float = setting(0.5, 'no accepted ground-speed sample for this long '
                                          '= stale: ramp to 0, then halt (longer, the rows '
                                          'plant blind: 2 s at 1.5 m/s is 3 m)', unit='s',
                                          range=(0.05, 2.0))
    speed_profile: str = choice('constant', "the sun bar's motion within each plant: constant "
                                '(2πv/(n·d)) or cam (θ(s) of the row\'s travelled distance, '
                                'five-bar only, CSP drives only; doc/cam.md)',
                                ('constant', 'cam'), read_only=True)
    cam_rule: str = choice('design_speed', "the cam's in-soil law: design_speed (the "
                           "mechanism's own zero-speed ratio) or zero_slip",
                           ('design_speed', 'zero_slip'), read_only=True)

    def __post_init__(self) -> None:
        check(self, ControlConfigError)


@dataclass(frozen=True)
class PlantingAngles:
    """Where on the shaft a mechanism plants (rad, the joint's angle): a planting instant at
    `phase` + k·2π/n; the nozzle enters the soil `entry` before it and leaves `exit` after."""

    phase: float
    entry: float
    exit: float


def planting_angles(design: Any) -> PlantingAngles | None:
    """Where a design's mechanism plants on its shaft (its planting model's phase, soil entry
    and exit: section stops and design changes), or None when it has no planting model."""
    # lazy: `planter design` loads this module for the speed limits and not the prediction
    # package (11 modules, 31 ms: test_skip_what_a_scene_does_not_need's list)
    from planter_ros.prediction import planting_model_from_design
    try:
        model = planting_model_from_design(design)
    except (ValueError, TypeError, KeyError):    # ValueError: a ConfigError too
        return None
    return PlantingAngles(float(model.planting_phase), float(model.entry_angle),
                          float(model.exit_angle))


def stop_angle(theta: float, omega: float, max_acceleration: float, pitch: float,
               angles: PlantingAngles | None = None, lag: float = STOP_LAG) -> float:
    """Where a row switched off at shaft angle `theta` (rad), turning at `omega` (rad/s), comes
    to rest, braking at `max_acceleration` (rad/s²) through the soonest stop θ_min.

    Without planting angles: θ_min. With them, plants are θ_k = phase + k·pitch and the nozzle
    is in the soil over [θ_k − entry, θ_k + exit]: at θ_min (plus `lag`·ω of overshoot) in the
    soil, the plant in progress is set and the row parks after it; otherwise it parks in the
    middle of the out-of-soil arc if that is still ahead, else at θ_min (before the next soil
    entry): nothing more is planted.
    """
    omega = max(omega, 0.0)
    earliest = theta + omega ** 2 / (2.0 * max_acceleration)
    if angles is None or angles.entry + angles.exit >= pitch:
        return earliest
    k = math.ceil((earliest - angles.exit - angles.phase) / pitch)
    plant = angles.phase + k * pitch          # first plant whose soil arc is not behind θ_min
    half_arc = 0.5 * (pitch - angles.entry - angles.exit)
    if earliest + lag * omega >= plant - angles.entry:
        return plant + angles.exit + half_arc
    return max(earliest, plant - angles.entry - half_arc)


class PhaseLock:
    """Ground speed + measured mechanism angle -> mechanism speed command (rad/s)."""

    def __init__(self, config: PhaseLockConfig | None = None,
                 limits: GroundSpeedLimits | None = None,
                 speed_filter: GroundSpeedFilter | None = None) -> None:
        self.config = config or PhaseLockConfig()
        self.spacing: float | None = None   # d (m), None until a design is known
        self.plants_per_revolution = 1
        self.planting: PlantingAngles | None = None  # if the design gives them
        self.filter = speed_filter or GroundSpeedFilter(limits or GroundSpeedLimits())
        self.section_on = True              # section control: planting (True) or off
        self.stop_angle: float | None = None    # where a row switched off comes to rest (rad)
        self.parked = False                 # switched off and at rest at stop_angle
        self._starting = False              # switched on, not up to speed: no grid yet
        self.phase_slips = 0                # whole plant pitches given up (fault, stale gap)
        # the distance travelled, from the accepted (or negative) speed samples
        self.odometer = Odometer(self.config.ground_speed_timeout)
        self._fb: tuple[float, float, float] | None = None  # (angle rad, speed rad/s, stamp s)
        self._anchor: tuple[float, float] | None = None  # (θ at anchor, s at anchor)
        self._cmd = 0.0
        self._t_cmd: float | None = None
        self.last_error = 0.0               # phase error at the last command (rad)
        # (d, PlantingAngles, s at its planting instant)
        self._pending: tuple[float, PlantingAngles | None, float] | None = None
        self.cam: CamProfile | None = None  # in force (or next), None: constant
        self._track: CamTrack | None = None  # the grid's, once anchored with a cam
        self._cam_offset = 0.0              # whole pitches given up on the cam's grid (rad)
        self.cam_fallback = ''              # why a cam was asked for and is not run

    # ------------------------------------------------------------------ inputs
    def configure(self, config: PhaseLockConfig, limits: GroundSpeedLimits) -> None:
        """New gains, limits and sample plausibility rule (a parameter update at run time)."""
        self.config = config
        self.filter.limits = limits
        self.odometer.timeout = config.ground_speed_timeout

    def set_design(self, spacing: float, plants_per_revolution: int, now: float,
                   planting: PlantingAngles | None = None, cam: Any = None,
                   since: float | None = None) -> None:
        """Use a new spacing d (m) and plants per revolution n (and where the mechanism plants,
        `PlantingAngles`, for section stops); re-anchors the phase. `cam`: the design's planned
        cam profile (a `CamProfile` at this spacing), None for constant speed; `since`: when
        the design arrived (monotonic s; planning the cam takes a while): a cam change takes
        effect at the next planting instant after then, if its soil exit is still ahead."""
        if not (math.isfinite(spacing) and spacing > 0):
            raise ControlConfigError(f'plant_spacing = {spacing} is out of range: allowed '
                                     'finite and > 0 m')
        if plants_per_revolution not in (1, 2, 3, 4, 5, 6):
            raise ControlConfigError(f'plants_per_revolution = {plants_per_revolution} is out '
                                     'of range: allowed 1..6')
        same_kind = (cam is None) == (self.cam is None)
        if (self._anchor is None or not self.section_on or self._starting or not same_kind
                or int(plants_per_revolution) != self.plants_per_revolution):
            # no grid to continue: the design applies at once, a grid starts from here
            self._pending = None
            self.spacing = float(spacing)
            self.plants_per_revolution = int(plants_per_revolution)
            self.planting = planting
            self.cam = cam
            self._anchor = None
            self._track = None
            self._try_anchor(now)
            return
        if cam is not None and self._track is not None:
            # CamLimitError, CamInputError (one line): no change within the drive's limits;
            # the row keeps its design and cam (nothing of the change reaches the drive)
            switch_at = self._track.change(cam, self._change_from(self._track, now, since))
            self.cam = cam
            self._pending = (float(spacing), planting, switch_at)
            self._switch_design(now)
            return
        self._pending = (float(spacing), planting, self._next_planting_distance(now))
        self._switch_design(now)

    def check_cam(self, cam: Any, plants_per_revolution: int, now: float,
                  since: float | None = None) -> None:
        """Raise what `set_design` with this cam would (CamLimitError, CamInputError: the
        change from the cam in force is over the drive's limits or has no room), changing
        nothing: a machine checks every row before it changes any. The transition is planned
        (or found planned: cam.track caches it) here."""
        if (cam is None or self._track is None or self.cam is None or not self.section_on
                or self._starting or self._anchor is None
                or int(plants_per_revolution) != self.plants_per_revolution):
            return
        self._track.transition(cam, self._change_from(self._track, now, since))

    def _change_from(self, track: CamTrack, now: float, since: float | None) -> float:
        """The distance a cam change counts its next planting instant from: the row's
        distance when the design arrived, unless that plant's soil exit is behind already."""
        s_now = self.travelled(now)
        if since is None or not since < now:
            return s_now
        s_then = max(s_now - self.odometer.speed * min(now - since, self.odometer.timeout), 0.0)
        s_k, profile = track.next_plant(s_then)
        if s_k + profile.law.half_length(profile.mech) <= s_now:
            return s_now
        return s_then

    def set_planting(self, planting: PlantingAngles | None) -> None:
        """Where the design's mechanism plants (PlantingAngles or None), found after the
        design itself: the pending design's, if one waits for its planting instant."""
        if self._pending is not None:
            spacing, _, switch_at = self._pending
            self._pending = (spacing, planting, switch_at)
        else:
            self.planting = planting

    @property
    def design_pending(self) -> bool:
        """A new design waits for the row's next planting instant."""
        return self._pending is not None

    def _next_planting_distance(self, now: float) -> float:
        """Travelled distance at which the current grid sets the mechanism's next plant (the
        first planting angle beyond the measured angle); now's distance when the planting
        angles are not known."""
        theta = self.measured_angle(now)
        if self.planting is None or theta is None:
            return self.travelled(now)
        pitch = TWO_PI / self.plants_per_revolution
        k = math.floor((theta - self.planting.phase) / pitch) + 1
        theta0, s0, spacing = self._grid()
        return s0 + (self.planting.phase + k * pitch - theta0) * (
            self.plants_per_revolution * spacing) / TWO_PI

    def _switch_design(self, now: float) -> None:
        """Once the row has travelled to the pending design's planting instant s_k: the grid
        goes on from the old grid's (θ_k, s_k) at the new spacing."""
        if self._pending is None:
            return
        spacing, planting, switch_at = self._pending
        if self.travelled(now) < switch_at:
            return
        theta0, s0, old_spacing = self._grid()
        theta_k = theta0 + TWO_PI * (switch_at - s0) / (self.plants_per_revolution * old_spacing)
        self._anchor = (theta_k, switch_at)
        self.spacing = spacing
        if planting is not None or self.planting is None:
            self.planting = planting
        self._pending = None

    @property
    def rejected(self) -> dict[str, int]:
        """Rejected ground-speed samples by reason."""
        return self.filter.rejected

    @property
    def accepted(self) -> int:
        return self.filter.accepted

    def ground_speed(self, v: float, now: float) -> str | None:
        """Offer a ground-speed sample (m/s, forward > 0). Returns None or the rejection reason."""
        checked: tuple[float | None, str | None] = self.filter.check(v, now)
        used, reason = checked
        if used is None:
            return reason
        # accepted, or a plausible negative sample read as 0 (not moving forward)
        self.row_speed(used, now)
        return reason

    def row_speed(self, v: float, now: float) -> None:
        """Take a speed sample already judged plausible (m/s; ≤ 0 = not moving forward): the
        distance runs on as the trapezoid of the samples (Odometer.sample)."""
        self.odometer.sample(v, now)

    def switch(self, on: bool, now: float) -> None:
        """Section control: off = come to rest at `stop_angle` and plant nothing more; on = a
        new grid from the angle the mechanism rests at and the distance travelled now."""
        if on == self.section_on:
            return
        if self._pending is not None:        # no grid across a switch: the design applies now
            spacing, planting, _ = self._pending
            self.spacing, self._pending = spacing, None
            if planting is not None:
                self.planting = planting
        self.section_on = on
        if on:
            self.stop_angle = None
            self.parked = False
            self._anchor = None
            self._track = None
            self._starting = True           # the grid starts once up to speed (command())
            return
        theta = self.measured_angle(now)
        omega = self._fb[1] if self._fb is not None else 0.0
        if theta is None:                   # never turned: rest where it is
            self.stop_angle, self.parked = None, True
            return
        self.stop_angle = stop_angle(theta, max(omega, self._cmd), self.config.max_acceleration,
                                     TWO_PI / self.plants_per_revolution, self.planting)
        self.parked = False
    def shift_angle(self, delta: float) -> None:
        """The angle's reference moved: the same mechanism position now reads `delta` rad
        more (a machine file's phase offset placed on the design's angles). Every angle held
        follows, so nothing jumps."""
        if self._fb is not None:
            angle, speed, stamp = self._fb
            self._fb = (angle + delta, speed, stamp)
        if self._anchor is not None:
            self._anchor = (self._anchor[0] + delta, self._anchor[1])
            self._cam_offset += delta if self._track is not None else 0.0
        if self.stop_angle is not None:
            self.stop_angle += delta

    def feedback(self, angle: float, speed: float, stamp: float) -> None:
        """Measured mechanism angle (rad, unwrapped) and speed (rad/s) at time `stamp`."""
        if math.isfinite(angle) and math.isfinite(speed):
            self._fb = (float(angle), float(speed), float(stamp))
            self._try_anchor(stamp)

    # ------------------------------------------------------------------ state
    def stale(self, now: float) -> bool:
        return self.odometer.stale(now)

    def travelled(self, now: float) -> float:
        """Travelled distance s (m): accepted speeds held for at most the stale timeout."""
        return self.odometer.travelled(now)

    @property
    def ground_speed_value(self) -> float:
        return self.odometer.speed

    @property
    def anchored(self) -> bool:
        return self._anchor is not None

    @property
    def speed_profile(self) -> str:
        """'cam' while the row follows a cam, else 'constant'."""
        return 'cam' if self.cam is not None else 'constant'

    def feed_forward(self, now: float) -> float:
        if self.spacing is None or self.stale(now):
            return 0.0
        v = self.odometer.rate(now)
        if self._track is not None:
            return max(float(self._track.evaluate(self.travelled(now))[1]), 0.0) * v
        return TWO_PI * v / (self.plants_per_revolution * self.spacing)

    def target_angle(self, now: float) -> float | None:
        """θ the travelled distance asks for (rad), None until anchored."""
        if self._anchor is None:
            return None
        if self._track is not None:
            return float(self._track.evaluate(self.travelled(now))[0]) + self._cam_offset
        theta0, s0, spacing = self._grid()
        return theta0 + TWO_PI * (self.travelled(now) - s0) / (
            self.plants_per_revolution * spacing)

    def _grid(self) -> tuple[float, float, float]:
        """(θ at the anchor, s at the anchor, d) of the grid in force. Only asked once
        anchored, and an anchor needs a design (_try_anchor)."""
        assert self._anchor is not None and self.spacing is not None, 'no grid before anchor'
        return self._anchor[0], self._anchor[1], self.spacing

    def cam_target(self, now: float) -> float | None:
        """θ(s) of the cam at `now` (rad) while the row tracks its cam (on its grid, section
        on, fresh ground speed), else None: what a CSP drive's position target should be."""
        if (self._track is None or self._anchor is None or not self.section_on
                or self._starting or self.stale(now)):
            return None
        self._switch_design(now)
        return self.target_angle(now)

    def measured_angle(self, now: float) -> float | None:
        if self._fb is None:
            return None
        angle, speed, stamp = self._fb
        return angle + speed * min(max(now - stamp, 0.0), _MAX_FEEDBACK_EXTRAPOLATION)

    def phase_error(self, now: float) -> float:
        """θ_target − θ_measured (rad); 0 until anchored."""
        self._switch_design(now)
        target = self.target_angle(now)
        measured = self.measured_angle(now)
        if target is None or measured is None:
            return 0.0
        return target - measured

    def state(self, now: float) -> str:
        if self.spacing is None:
            return 'waiting for design'
        if not self.section_on:
            return 'section off (at rest)' if self.parked else 'section off (stopping)'
        if self.odometer.stamp is None:
            return 'waiting for ground speed'
        if self.stale(now):
            return 'halted (stale ground speed)' if self._cmd == 0.0 else \
                'ramping down (stale ground speed)'
        return 'tracking (new design at the next plant)' if self._pending else 'tracking'

    # ------------------------------------------------------------------ output
    def command(self, now: float) -> float:
        """Speed command (rad/s, >= 0) for time `now`, acceleration-limited from the last one."""
        cfg = self.config
        self._switch_design(now)
        target = self.feed_forward(now)
        if self.section_on:
            if self._starting:
                self._start_grid(now, target)
            error = self._wrapped_error(now)
            self.last_error = error
            if cfg.phase_lock and self._anchor is not None and not self.stale(now):
                target += min(max(cfg.phase_gain * error, -cfg.max_correction),
                              cfg.max_correction)
        else:
            target = min(target, self._braking(now))
        target = min(max(target, 0.0), cfg.max_speed)
        if self._t_cmd is None:
            step = 0.0
        else:
            step = cfg.max_acceleration * min(max(now - self._t_cmd, 0.0), _MAX_RATE_STEP)
        self._cmd = min(max(target, self._cmd - step), self._cmd + step)
        self._t_cmd = now
        return self._cmd

    def _start_grid(self, now: float, feed_forward: float) -> None:
        """Switched on: the mechanism speeds up from rest on feed-forward alone; the new grid
        is anchored once it turns at 95 % of it, so the ramp's lag shifts the grid instead of
        being made up (which would set the next plants too close)."""
        if self._fb is not None and feed_forward > 0.0 and self._fb[1] >= 0.95 * feed_forward:
            self._starting = False
            self._try_anchor(now)

    def _braking(self, now: float) -> float:
        """Switched off: the speed that still stops at stop_angle (0 once at rest there)."""
        measured = self.measured_angle(now)     # known: stop_angle is set from it (switch)
        if self.parked or self.stop_angle is None or measured is None:
            self.parked = True
            return 0.0
        remaining = self.stop_angle - measured
        if remaining <= PARK_TOLERANCE:
            self.parked = True
            return 0.0
        return math.sqrt(2.0 * self.config.max_acceleration * remaining)

    def halt(self, now: float) -> None:
        """The drive stopped (fault, disabled): the next commands ramp up again from 0."""
        self._cmd = 0.0
        self._t_cmd = now

    def _try_anchor(self, now: float) -> None:
        measured = self.measured_angle(now)
        if (self._anchor is None and not self._starting and self.spacing is not None
                and measured is not None):
            self._anchor = (measured, self.travelled(now))
            if self.cam is not None:
                # lazy: only a cam row needs the cam package (32 ms); `planter design`
                # loads this module (test_skip_what_a_scene_does_not_need's list)
                from .cam_law import anchored_track
                self._track = anchored_track(self.cam, measured, self._anchor[1])
                self._cam_offset = 0.0

    def _wrapped_error(self, now: float) -> float:

        error = self.phase_error(now)
        pitch = TWO_PI / self.plants_per_revolution
        if abs(error) > pitch:
            slips = round(error / pitch)
            theta0, s0, _ = self._grid()
            self._anchor = (theta0 - slips * pitch, s0)
            self._cam_offset -= slips * pitch
            self.phase_slips += abs(slips)
            error -= slips * pitch
        return error
