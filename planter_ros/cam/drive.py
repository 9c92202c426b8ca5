"""The drive that turns the sun bar, its limits, and the load a cam puts on it.

The cam is θ(s); at ground speed v (m/s, steady) the sun bar turns at ω = v·θ′, accelerates at
α = v²·θ″ and jerks at v³·θ‴ (a changing ground speed adds a·θ′ to α; the figures here are at
steady speed, the field's usual case).

Load model (SI, at the sun bar A):

* the nozzle (tip C, mass m) on the ellipse x = a sin θ, y = L cos θ: inertia
  J_C(θ) = m (a² cos² θ + L² sin² θ) about A, plus the bars lumped as a constant J_b;
* Lagrange: T_A = J(θ)·α + ½ J′(θ)·ω² + m g L·(−sin θ), J = J_b + J_C;
* motor torque through a gearbox of ratio N and efficiency η (taken as a loss in both
  directions, the safe side): T_m = (J_rotor + J_gearbox)·N·α + T_A / (N η).

Default drive: a 750 W AC servo with a planetary gearbox. Motor figures from the Yaskawa Σ-7
SGM7J-08A (200 V, 750 W, no brake), Σ-7-Series Rotary Servomotor Product Manual (Yaskawa,
SIEP S800001 36), ratings table: rated torque 2.39 N·m, instantaneous maximum torque 8.36 N·m,
rated speed 3000 min⁻¹, maximum speed 6000 min⁻¹, rotor moment of inertia 1.59 × 10⁻⁴ kg·m².
Gearbox: a two-stage planetary of ratio 20 (the middle of 15–30:1), efficiency 0.94 (about 3 % per
stage) and 0.3 × 10⁻⁴ kg·m² at its input (catalogue values of 60–90 mm two-stage planetaries
lie at 0.1–0.5 × 10⁻⁴ kg·m²): typical values, not one product's. The mechanism's tip mass and
bar inertia are assumptions (a duckbill nozzle of 1.5 kg; 0.02 kg·m² of bars about A):
weigh the machine and override them.

Servo datasheets rate no jerk; the default jerk limit lets the acceleration rise from zero to
the torque-limited acceleration in `jerk_ramp_time` = 40 ms, about one period of a 25 Hz first
torsional mode of a geared arm (an assumption: measure the machine's and override it).
"""

from collections.abc import Callable, Sequence
from dataclasses import dataclass
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planter_ros.config import check, setting, spec_of
from planter_ros.kinematics.arrays import FloatArray
from planter_ros.kinematics.errors import DesignError

from .errors import CamInputError
from .mechanism import CamMechanism
from .piecewise import Piecewise, State

__all__ = ['DriveLimits', 'EffectiveLimits', 'LoadFigures', 'LoadSamples', 'LIMIT_NAMES',
           'DRIVE_SOURCE', 'GRAVITY', 'sun_bar_motion']

GRAVITY = 9.80665
# the least acceleration and jerk limits a cam is planned against (below them the linear
# programme's numbers span more than a double holds; no drive is that gentle)
MIN_ACCELERATION = 0.1            # rad/s²
MIN_JERK = 1.0                    # rad/s³
RPM = 2.0 * math.pi / 60.0

DRIVE_SOURCE = ('motor: Yaskawa Σ-7 SGM7J-08A, 750 W (Σ-7-Series Rotary Servomotor Product '
                'Manual, SIEP S800001 36, ratings table); gearbox: typical two-stage planetary, '
                'ratio 20; tip mass, bar inertia and jerk ramp time: assumptions, override them')

# utilisation names, in the order tables show them
LIMIT_NAMES = ('speed', 'acceleration', 'jerk', 'torque', 'rms torque')

# per angle θ: (k_α, k_ω, g) of the motor torque T_m = k_α·α + k_ω·ω² + g
TorqueTerms = tuple[FloatArray, FloatArray, FloatArray]


def sun_bar_motion(derivatives: State, ground_speed: float,
                   ground_acceleration: float = 0.0) -> tuple[float, float, float]:
    """(θ, ω, α) of the sun bar from the cam's (θ, θ′, θ″) at the row's distance, its ground
    speed v (m/s) and acceleration a (m/s²): ω = v θ′, α = v² θ″ + a θ′ (rad, rad/s, rad/s²)."""
    theta, d1, d2 = derivatives
    v = ground_speed
    return theta, v * d1, v * v * d2 + ground_acceleration * d1


def _error(text: str) -> DesignError:
    return CamInputError.from_message(text)


@dataclass(frozen=True, kw_only=True)
class DriveLimits:
    """The sun bar's drive: servo, gearbox, mechanism inertia and the limits (SI)."""

    motor_peak_torque: float = setting(8.36, "servo's instantaneous maximum torque",
                                       unit='N m', range=(0.001, 1e4))
    motor_rated_torque: float = setting(2.39, "servo's rated (continuous) torque, the limit "
                                        'of the RMS torque over a plant', unit='N m',
                                        range=(0.001, 1e4))
    motor_max_speed: float = setting(6000.0 * RPM, "servo's maximum speed", unit='rad/s',
                                     range=(1.0, 1e4))
    rotor_inertia: float = setting(1.59e-4, "servo rotor's moment of inertia",
                                   unit='kg m^2', range=(0.0, 10.0))
    gear_ratio: float = setting(20.0, 'gearbox reduction N: motor turns per sun-bar turn',
                                range=(1.0, 1000.0))
    gearbox_efficiency: float = setting(0.94, 'gearbox efficiency η', range=(0.1, 1.0))
    gearbox_inertia: float = setting(0.3e-4, "gearbox's moment of inertia at its input",
                                     unit='kg m^2', range=(0.0, 10.0))
    tip_mass: float = setting(1.5, 'mass of the nozzle at the tip C (assumed; weigh it)',
                              unit='kg', range=(0.0, 100.0))
    bar_inertia: float = setting(0.02, 'moment of inertia of the bars about A (assumed)',
                                 unit='kg m^2', range=(0.0, 100.0))
    max_speed: float = setting(0.0, 'sun-bar speed limit; 0: motor_max_speed / gear_ratio',
                               unit='rad/s', range=(0.0, 1e4))
    max_acceleration: float = setting(0.0, 'sun-bar acceleration limit; 0: only the torque '
                                      'limits it', unit='rad/s^2', range=(0.0, 1e7))
    max_jerk: float = setting(0.0, 'sun-bar jerk limit; 0: the torque-limited acceleration '
                              'over jerk_ramp_time', unit='rad/s^3', range=(0.0, 1e10))
    jerk_ramp_time: float = setting(0.04, 'shortest time for the acceleration to rise from 0 to '
                                    'its limit (sets the default jerk limit)', unit='s',
                                    range=(0.001, 10.0))
    thermal_window: float = setting(10.0, 'time over which the RMS torque is held to the rated '
                                    'torque around a run-time change (a thermal limit: a '
                                    "servo's thermal time constant is minutes; assumed)",
                                    unit='s', range=(0.1, 3600.0))

    def __post_init__(self) -> None:
        check(self, _error)
        if self.motor_rated_torque > self.motor_peak_torque:
            raise CamInputError('motor_rated_torque', self.motor_rated_torque,
                                f'<= motor_peak_torque = {self.motor_peak_torque:g} N m (a '
                                "servo's continuous torque is below its peak)")
        for name, least, unit in (('max_acceleration', MIN_ACCELERATION, 'rad/s^2'),
                                  ('max_jerk', MIN_JERK, 'rad/s^3')):
            value = getattr(self, name)
            if 0.0 < value < least:
                high = spec_of(DriveLimits, name).high
                raise CamInputError(name, value, f'0 (derived) or {least:g}..{high:g} {unit} '
                                    '(below it no out-of-soil arc can be planned)')

    def effective(self, mech: CamMechanism) -> 'EffectiveLimits':
        """The limits in force for mechanism `mech` (derived ones filled in)."""
        n, eta = self.gear_ratio, self.gearbox_efficiency
        speed = self.max_speed or self.motor_max_speed / n
        reflected = (self.rotor_inertia + self.gearbox_inertia) * n * n * eta
        worst = reflected + self.bar_inertia + self.tip_mass * max(mech.a, mech.total) ** 2
        torque_acceleration = self.motor_peak_torque * n * eta / worst
        ramp = min(torque_acceleration, self.max_acceleration or math.inf)
        jerk = self.max_jerk or ramp / self.jerk_ramp_time
        return EffectiveLimits(speed=speed, acceleration=self.max_acceleration, jerk=jerk,
                               torque=self.motor_peak_torque,
                               rms_torque=self.motor_rated_torque,
                               torque_acceleration=torque_acceleration)

    def _load(self, mech: CamMechanism, theta: FloatArray) -> TorqueTerms:
        """(J(θ), ½J′(θ), weight term) at the sun bar for angles θ (array)."""
        m, a, big = self.tip_mass, mech.a, mech.total
        c, s = np.cos(theta), np.sin(theta)
        inertia = self.bar_inertia + m * (a * a * c * c + big * big * s * s)
        return inertia, m * (big * big - a * a) * s * c, -m * GRAVITY * big * s

    def torque_terms(self, mech: CamMechanism, theta: FloatArray) -> TorqueTerms:
        """Per angle θ (array): (k_α, k_ω, g) with motor torque T_m = k_α·α + k_ω·ω² + g."""
        through = self.gear_ratio * self.gearbox_efficiency
        inertia, half_slope, weight = self._load(mech, theta)
        k_alpha = (self.rotor_inertia + self.gearbox_inertia) * self.gear_ratio \
            + inertia / through
        return k_alpha, half_slope / through, weight / through

    def sun_bar_torque(self, mech: CamMechanism, theta: FloatArray, omega: FloatArray,
                       alpha: FloatArray) -> FloatArray:
        """Torque at the sun bar (the gearbox output), N·m."""
        inertia, half_slope, weight = self._load(mech, theta)
        return inertia * alpha + half_slope * omega ** 2 + weight


@dataclass(frozen=True)
class EffectiveLimits:
    """Limits in force (SI, at the sun bar except the motor torques); acceleration 0 = only
    the torque limits it."""

    speed: float
    acceleration: float
    jerk: float
    torque: float
    rms_torque: float
    torque_acceleration: float      # α the peak torque gives at the largest inertia

    def as_dict(self) -> dict[str, float | None]:
        return {'sun_bar_speed': self.speed, 'sun_bar_acceleration': self.acceleration or None,
                'sun_bar_jerk': self.jerk, 'motor_peak_torque': self.torque,
                'motor_rms_torque': self.rms_torque,
                'torque_limited_acceleration': self.torque_acceleration}


@dataclass(frozen=True)
class LoadFigures:
    """Peaks of one plant's motion at ground speed v, and each limit's utilisation (peak over
    limit: ≤ 1 is within it)."""

    ground_speed: float
    peak_speed: float               # rad/s, sun bar
    peak_acceleration: float        # rad/s², sun bar
    peak_jerk: float                # rad/s³, sun bar
    peak_torque: float              # N·m, motor
    rms_torque: float               # N·m, motor, over one plant
    peak_sun_bar_torque: float      # N·m, gearbox output
    utilisation: dict[str, float]   # limit (LIMIT_NAMES) -> peak / limit

    @property
    def feasible(self) -> bool:
        return all(u <= 1.0 + 1e-9 for u in self.utilisation.values())

    @property
    def binding(self) -> str:
        """The limit closest to (or furthest beyond) its value."""
        return max(self.utilisation, key=lambda name: self.utilisation[name])

    @property
    def exceeded(self) -> list[str]:
        return [k for k in LIMIT_NAMES if self.utilisation.get(k, 0.0) > 1.0 + 1e-9]

    def limit_text(self, name: str | None = None) -> str:
        """One limit's figure against the limit in words, e.g. 'sun-bar speed 37.7 rad/s over
        its limit 31.4 rad/s (120 %)' (default: the binding limit)."""
        name = name or self.binding
        words, peak, unit = {
            'speed': ('sun-bar speed', self.peak_speed, 'rad/s'),
            'acceleration': ('sun-bar acceleration', self.peak_acceleration, 'rad/s²'),
            'jerk': ('sun-bar jerk', self.peak_jerk, 'rad/s³'),
            'torque': ('peak motor torque', self.peak_torque, 'N·m'),
            'rms torque': ('RMS motor torque over a plant', self.rms_torque, 'N·m')}[name]
        used = self.utilisation[name]
        limit = peak / used if used > 0 else math.inf
        side = 'over' if used > 1.0 + 1e-9 else 'within'
        return (f'{words} {peak:.4g} {unit} {side} its limit {limit:.4g} {unit} '
                f'({used * 100:.1f} %) at {self.ground_speed:.3g} m/s')

    def over_text(self) -> str:
        """Every exceeded limit's `limit_text`, joined ('' when within every limit)."""
        return '; '.join(self.limit_text(name) for name in self.exceeded)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (numbers, the utilisations by limit, the binding limit's name)."""
        return {'ground_speed': self.ground_speed, 'peak_sun_bar_speed': self.peak_speed,
                'peak_sun_bar_acceleration': self.peak_acceleration,
                'peak_sun_bar_jerk': self.peak_jerk, 'peak_motor_torque': self.peak_torque,
                'rms_motor_torque': self.rms_torque,
                'peak_sun_bar_torque': self.peak_sun_bar_torque,
                'utilisation': dict(self.utilisation), 'feasible': self.feasible,
                'binding': self.binding}


SAMPLES_PER_PIECE = 33            # odd: Simpson's rule for the RMS, a bracket for each peak
REFINE_STEPS = 30                 # golden-section steps per peak: the bracket shrinks 0.618^30
#                                   (1e-6 of it: the value, flat at its maximum, to ~1e-12)
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
PEAK_MARGIN = 0.05                # pieces refined: sampled peak within 5 % of the largest


_FACTORS = [np.array([1., 1., 1., 1., 1., 1.]), np.array([1., 2., 3., 4., 5.]),
            np.array([2., 6., 12., 20.]), np.array([6., 24., 60.])]


def _derivative(coeffs: FloatArray, x: FloatArray, order: int) -> FloatArray:
    """The `order`-th derivative of degree-5 pieces `coeffs` (rows) at local abscissae x."""
    c = coeffs[:, order:] * _FACTORS[order]
    out: FloatArray = c[:, -1].copy()
    for j in range(c.shape[1] - 2, -1, -1):
        out = out * x + c[:, j]
    return out


def _derivatives(coeffs: FloatArray,
                 x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """θ, θ′, θ″, θ‴ of degree-5 pieces `coeffs` (rows) at local abscissae x (same length)."""
    return (_derivative(coeffs, x, 0), _derivative(coeffs, x, 1), _derivative(coeffs, x, 2),
            _derivative(coeffs, x, 3))


class LoadSamples:
    """θ and its derivatives sampled densely over a stretch of cam (both ends of every piece,
    so a jump in θ‴ is seen from both sides); the loads at any steady speed follow.

    The peaks are the continuous maxima of each piece, not the samples': around the best
    sample of every piece a golden-section search (`REFINE_STEPS`, vectorised over the
    pieces) finds the maximum of |ω|, |α|, |jerk| and |T| to round-off. The RMS torque is over
    one plant: the whole stretch (`spacing` long, a periodic profile's period) or, with
    `windows` ((start, end) pairs of r), the largest over those plants (a transition)."""

    def __init__(self, period: Piecewise, spacing: float, mech: CamMechanism,
                 drive: 'DriveLimits',
                 windows: Sequence[tuple[float, float]] | None = None) -> None:
        n = SAMPLES_PER_PIECE
        t = np.linspace(0.0, 1.0, n)
        b = period.breaks
        h = b[1:] - b[:-1]
        pieces = b.size - 1
        x = (h[:, None] * t[None, :]).ravel()
        piece = np.repeat(np.arange(pieces), n)
        self.r = b[piece] + x
        self.theta, self.d1, self.d2, self.d3 = _derivatives(period.coeffs[piece], x)
        # Simpson's weights along r within each piece (exact for cubics): the RMS over a plant
        simpson = np.ones(n)
        simpson[1:-1:2], simpson[2:-1:2] = 4.0, 2.0
        self.weights = (simpson[None, :] * (h / (3.0 * (n - 1)))[:, None]).ravel()
        self.coeffs, self.h, self.pieces = period.coeffs, h, pieces
        self.spacing = spacing
        self.windows = None if windows is None else [(float(a), float(e)) for a, e in windows]
        self.mech = mech
        self.drive = drive
        self.limits = drive.effective(mech)
        self.k_alpha, self.k_omega, self.gravity = drive.torque_terms(mech, self.theta)

    def torque(self, v: float) -> FloatArray:
        return v * v * (self.k_alpha * self.d2 + self.k_omega * self.d1 ** 2) + self.gravity

    def _rms(self, torque: FloatArray) -> float:
        """The RMS of the torque samples over one plant (the largest of the windows)."""
        square = torque * torque
        if self.windows is None:
            return math.sqrt(float(np.dot(self.weights, square)) / self.spacing)
        # running integral of T² at the samples (trapezoids), read at the windows' ends
        steps = 0.5 * (square[1:] + square[:-1]) * np.diff(self.r)
        running = np.concatenate(([0.0], np.cumsum(steps)))
        ends = np.interp([e for w in self.windows for e in w], self.r, running)
        return max(math.sqrt(max(e - a, 0.0) / (w1 - w0))
                   for (a, e), (w0, w1) in zip(zip(ends[::2], ends[1::2]), self.windows))

    def _peak(self, sampled: FloatArray,
              value: Callable[[NDArray[np.intp], FloatArray], FloatArray]) -> float:
        """The continuous maximum of |value(piece, x)| over every piece, from the samples'
        |values| `sampled`: each piece's best sample bracketed by its neighbours, then a
        golden-section search in the bracket (all pieces at once)."""
        n = SAMPLES_PER_PIECE
        grid = np.abs(sampled).reshape(self.pieces, n)
        piece_max = np.max(grid, axis=1)
        top = float(np.max(piece_max))
        # only the pieces whose samples come near the largest can hold the maximum: between
        # two of 33 samples a smooth piece rises far less than this margin
        index = np.flatnonzero(piece_max >= (1.0 - PEAK_MARGIN) * top)
        best = np.argmax(grid[index], axis=1)
        step = self.h[index] / (n - 1)
        lo = np.maximum(best - 1, 0) * step
        hi = np.minimum(best + 1, n - 1) * step
        x1 = hi - _GOLDEN * (hi - lo)
        x2 = lo + _GOLDEN * (hi - lo)
        f1, f2 = np.abs(value(index, x1)), np.abs(value(index, x2))
        for _ in range(REFINE_STEPS):
            right = f1 < f2                 # the maximum lies in [x1, hi]
            lo = np.where(right, x1, lo)
            hi = np.where(right, hi, x2)
            x1, x2 = np.where(right, x2, hi - _GOLDEN * (hi - lo)), \
                np.where(right, lo + _GOLDEN * (hi - lo), x1)
            f_new = np.abs(value(index, np.where(right, x2, x1)))
            f1, f2 = np.where(right, f2, f_new), np.where(right, f_new, f1)
        return float(max(top, np.max(f1), np.max(f2)))

    def figures(self, v: float) -> LoadFigures:
        lim = self.limits
        omega, alpha = v * self.d1, v * v * self.d2
        torque = self.torque(v)
        rms = self._rms(torque)
        drive, mech = self.drive, self.mech

        def motor_torque(index: NDArray[np.intp], x: FloatArray) -> FloatArray:
            th, d1, d2 = (_derivative(c[index], x, k) for k in range(3))
            k_alpha, k_omega, gravity = drive.torque_terms(mech, th)
            return v * v * (k_alpha * d2 + k_omega * d1 ** 2) + gravity

        def sun_torque(index: NDArray[np.intp], x: FloatArray) -> FloatArray:
            th, d1, d2 = (_derivative(c[index], x, k) for k in range(3))
            return drive.sun_bar_torque(mech, th, v * d1, v * v * d2)

        c = self.coeffs
        peak = {'speed': v * self._peak(self.d1, lambda i, x: _derivative(c[i], x, 1)),
                'acceleration': v * v * self._peak(self.d2, lambda i, x: _derivative(c[i], x, 2)),
                'jerk': v ** 3 * self._peak(self.d3, lambda i, x: _derivative(c[i], x, 3)),
                'torque': self._peak(torque, motor_torque), 'rms torque': rms}
        sun_peak = self._peak(drive.sun_bar_torque(mech, self.theta, omega, alpha), sun_torque)
        util = {'speed': peak['speed'] / lim.speed}
        if lim.acceleration:
            util['acceleration'] = peak['acceleration'] / lim.acceleration
        util['jerk'] = peak['jerk'] / lim.jerk
        util['torque'] = peak['torque'] / lim.torque
        util['rms torque'] = rms / lim.rms_torque
        return LoadFigures(v, peak['speed'], peak['acceleration'], peak['jerk'], peak['torque'],
                           rms, sun_peak, util)

    def top_speed(self) -> tuple[float, str]:
        """The largest steady ground speed at which this (fixed) motion meets every limit,
        with the limit that stops it: (m/s, name). 0 if even a standstill does not (the
        mechanism's weight alone over the torque limit)."""
        lim = self.limits
        speeds = {'speed': lim.speed / max(float(np.max(np.abs(self.d1))), 1e-300),
                  'jerk': (lim.jerk / max(float(np.max(np.abs(self.d3))), 1e-300)) ** (1 / 3)}
        if lim.acceleration:
            speeds['acceleration'] = math.sqrt(lim.acceleration /
                                               max(float(np.max(np.abs(self.d2))), 1e-300))
        # |A v² + g| ≤ T at every sample: A v² ≤ T − g and −A v² ≤ T + g
        big_a = self.k_alpha * self.d2 + self.k_omega * self.d1 ** 2
        g = self.gravity
        if np.any(np.abs(g) > lim.torque):
            return 0.0, 'torque'
        with np.errstate(divide='ignore'):
            room = np.where(big_a > 0, (lim.torque - g) / np.where(big_a > 0, big_a, 1.0),
                            np.where(big_a < 0, (lim.torque + g) / np.where(big_a < 0, -big_a,
                                                                             1.0), np.inf))
        speeds['torque'] = math.sqrt(float(np.min(room)))
        # RMS: mean of (A u + g)² over s, u = v², ≤ T_rated²: a quadratic in u
        w = self.weights / self.spacing
        qa, qb, qc = (float(np.dot(w, big_a * big_a)), 2.0 * float(np.dot(w, big_a * g)),
                      float(np.dot(w, g * g)) - lim.rms_torque ** 2)
        if qc > 0:
            return 0.0, 'rms torque'
        if qa > 0:
            u = (-qb + math.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa)
            speeds['rms torque'] = math.sqrt(max(u, 0.0))
        name = min(speeds, key=lambda limit: speeds[limit])
        return speeds[name], name
