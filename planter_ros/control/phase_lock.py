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

Time is passed in explicitly (monotonic seconds), so the law is deterministic and testable.
"""

from dataclasses import dataclass
import math

from planter_ros.config import ConfigError, check, setting
from planter_ros.sensing.ground_speed_filter import GroundSpeedFilter, GroundSpeedLimits

TWO_PI = 2.0 * math.pi
# measured angle is extrapolated with the measured speed for at most this long (s)
_MAX_FEEDBACK_EXTRAPOLATION = 0.05
# the acceleration limit never integrates over a gap longer than this (s)
_MAX_RATE_STEP = 0.1


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
                                          '= stale: ramp to 0, then halt', unit='s',
                                          range=(0.05, 10.0))

    def __post_init__(self):
        check(self, ControlConfigError)


class PhaseLock:
    """Ground speed + measured mechanism angle -> mechanism speed command (rad/s)."""

    def __init__(self, config=None, limits=None):
        self.config = config or PhaseLockConfig()
        self.spacing = None                 # d (m), None until a design is known
        self.plants_per_revolution = 1
        self.filter = GroundSpeedFilter(limits or GroundSpeedLimits())
        self.phase_slips = 0                # whole plant pitches given up (fault, stale gap)
        self._v = 0.0                       # last accepted forward speed (m/s)
        self._t_sample = None               # time of the last accepted (or negative) sample
        self._s = 0.0                       # travelled distance at _t_sample (m)
        self._fb = None                     # (angle rad, speed rad/s, stamp s)
        self._anchor = None                 # (θ at anchor, s at anchor)
        self._cmd = 0.0
        self._t_cmd = None
        self.last_error = 0.0               # phase error at the last command (rad)

    # ------------------------------------------------------------------ inputs
    def configure(self, config, limits):
        """New gains, limits and sample plausibility rule (a parameter update at run time)."""
        self.config = config
        self.filter.limits = limits

    def set_design(self, spacing, plants_per_revolution, now):
        """Use a new spacing d (m) and plants per revolution n; re-anchors the phase."""
        if not (math.isfinite(spacing) and spacing > 0):
            raise ControlConfigError(f'plant_spacing = {spacing} is out of range: allowed '
                                     'finite and > 0 m')
        if plants_per_revolution not in (1, 2, 3, 4, 5, 6):
            raise ControlConfigError(f'plants_per_revolution = {plants_per_revolution} is out '
                                     'of range: allowed 1..6')
        self.spacing = float(spacing)
        self.plants_per_revolution = int(plants_per_revolution)
        self._anchor = None
        self._try_anchor(now)

    @property
    def rejected(self):
        """Rejected ground-speed samples by reason."""
        return self.filter.rejected

    @property
    def accepted(self):
        return self.filter.accepted

    def ground_speed(self, v, now):
        """Offer a ground-speed sample (m/s, forward > 0). Returns None or the rejection reason."""
        used, reason = self.filter.check(v, now)
        if used is None:
            return reason
        # accepted, or a plausible negative sample read as 0 (not moving forward)
        self._s = self.travelled(now)
        self._v = used
        self._t_sample = now
        return reason

    def feedback(self, angle, speed, stamp):
        """Measured mechanism angle (rad, unwrapped) and speed (rad/s) at time `stamp`."""
        if math.isfinite(angle) and math.isfinite(speed):
            self._fb = (float(angle), float(speed), float(stamp))
            self._try_anchor(stamp)

    # ------------------------------------------------------------------ state
    def stale(self, now):
        return self._t_sample is None or now - self._t_sample > self.config.ground_speed_timeout

    def travelled(self, now):
        """Travelled distance s (m): accepted speeds held for at most the stale timeout."""
        if self._t_sample is None:
            return self._s
        held = min(max(now - self._t_sample, 0.0), self.config.ground_speed_timeout)
        return self._s + self._v * held

    @property
    def ground_speed_value(self):
        return self._v

    @property
    def anchored(self):
        return self._anchor is not None

    def feed_forward(self, now):
        if self.spacing is None or self.stale(now):
            return 0.0
        return TWO_PI * self._v / (self.plants_per_revolution * self.spacing)

    def target_angle(self, now):
        """θ the travelled distance asks for (rad), None until anchored."""
        if self._anchor is None:
            return None
        theta0, s0 = self._anchor
        return theta0 + TWO_PI * (self.travelled(now) - s0) / (
            self.plants_per_revolution * self.spacing)

    def measured_angle(self, now):
        if self._fb is None:
            return None
        angle, speed, stamp = self._fb
        return angle + speed * min(max(now - stamp, 0.0), _MAX_FEEDBACK_EXTRAPOLATION)

    def phase_error(self, now):
        """θ_target − θ_measured (rad); 0 until anchored."""
        target = self.target_angle(now)
        if target is None or self._fb is None:
            return 0.0
        return target - self.measured_angle(now)

    def state(self, now):
        if self.spacing is None:
            return 'waiting for design'
        if self._t_sample is None:
            return 'waiting for ground speed'
        if self.stale(now):
            return 'halted (stale ground speed)' if self._cmd == 0.0 else \
                'ramping down (stale ground speed)'
        return 'tracking'

    # ------------------------------------------------------------------ output
    def command(self, now):
        """Speed command (rad/s, >= 0) for time `now`, acceleration-limited from the last one."""
        cfg = self.config
        target = self.feed_forward(now)
        error = self._wrapped_error(now)
        self.last_error = error
        if cfg.phase_lock and self._anchor is not None and not self.stale(now):
            target += min(max(cfg.phase_gain * error, -cfg.max_correction), cfg.max_correction)
        target = min(max(target, 0.0), cfg.max_speed)
        if self._t_cmd is None:
            step = 0.0
        else:
            step = cfg.max_acceleration * min(max(now - self._t_cmd, 0.0), _MAX_RATE_STEP)
        self._cmd = min(max(target, self._cmd - step), self._cmd + step)
        self._t_cmd = now
        return self._cmd

    def halt(self, now):
        """The drive stopped (fault, disabled): the next commands ramp up again from 0."""
        self._cmd = 0.0
        self._t_cmd = now

    def _try_anchor(self, now):
        if self._anchor is None and self.spacing is not None and self._fb is not None:
            self._anchor = (self.measured_angle(now), self.travelled(now))

    def _wrapped_error(self, now):
        error = self.phase_error(now)
        pitch = TWO_PI / self.plants_per_revolution
        if abs(error) > pitch:
            slips = round(error / pitch)
            theta0, s0 = self._anchor
            self._anchor = (theta0 - slips * pitch, s0)
            self.phase_slips += abs(slips)
            error -= slips * pitch
        return error
