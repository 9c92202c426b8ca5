"""Ground speed and yaw rate from the sensors a tractor has, as pure adapters (no ROS, no bus):
each turns one sensor's reading into a `SpeedSample` (m/s, + forward, stamped), and
`SourceSelector` picks the source to believe, falling back when one goes quiet.

Sources:

* **GNSS velocity** (`gnss_speed`): the receiver's velocity as common ROS drivers publish it
  (nmea_navsat_driver's `vel`: geometry_msgs/TwistWithCovarianceStamped or TwistStamped, linear
  x east and y north in m/s): speed = |v|; the course over ground atan2(v_n, v_e) gives the yaw
  rate (`CourseYawRate`) while the machine moves fast enough for the course to mean something.
  GNSS velocity has no sign: a reversing machine reads forward (the fix's status says nothing
  of it); the sync law treats the speed as forward.
* **ISOBUS** (`IsobusSpeedDecoder`): the tractor's ISO 11783-7 speed messages on a second CAN
  channel: ground-based speed (PGN 65097, radar), wheel-based speed (PGN 65096) and machine
  selected speed (PGN 61474, the tractor's own choice), decoded with cantools from the DBC
  shipped in config/isobus_speed.dbc (matched by PGN from any source address). Reverse gives a
  negative speed; a raw value of 0xFB00 or more (error or not available) and a direction "error"
  give no sample.
* **Pulse count** (`PulseSpeed`): a wheel or radar sensor counting pulses (pulses per metre
  calibrated), the counter read now and then: speed = Δcount / (pulses per metre · Δt), with
  the counter's wrap-around.
* **Yaw rate from an IMU** (`imu_yaw_rate`): sensor_msgs/Imu angular_velocity.z (REP 103: z up,
  + counter-clockwise), NaN when the IMU reports no angular velocity (covariance[0] = −1).

`SourceSelector` keeps the sources in the user's order of preference; the first one heard from
within its `timeout` is used. A source that goes quiet for longer hands over to the next one at
the next sample of any source (so within timeout + one sample period), and every switch is an
`event` for the diagnostics ("isobus_ground lost (no sample for 0.3 s): using gnss").

Standstill is standstill (`Standstill`, every source): a speed sensor at rest does not read 0.
GNSS velocity is a magnitude: with 0.02 m/s of noise per axis it reads 0.025 m/s on average at
rest, and the phase-locked law turned a five-bar 46 rad in a minute on it, 7.4 plants into one
spot. Below `standstill_speed` a source's reading is 0 (the machine stands still); it reads
again once its magnitude reaches twice that (hysteresis: noise crossing the threshold now and
then does not start the rows; with 0.02 m/s per axis a sample reaches 0.1 m/s once in about
270 000). Each source keeps its own state, and the direction is the source's where it has one
(ISOBUS: reverse is negative); GNSS and a pulse count have none (forward). What it costs at a
start from rest: the distance up to twice the threshold, v²/2a (1 cm at 0.5 m/s²), is not
counted. Applied here, before the speed is published, so the sync node, the monitor and its
recording all see the same speeds.

A reading that is not a finite number (a GNSS velocity of 1.7e308 per axis has an infinite
magnitude; a pulse scale of 1e-300 an infinite speed) gives no sample.
"""

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
import math

from planter_ros.config import ConfigError, check, choice, name_list, setting
from planter_ros.shipped import shipped_file

__all__ = ['CourseYawRate', 'GroundSpeedSourceConfig', 'IsobusSpeedDecoder', 'PGNS',
           'PulseSpeed', 'SOURCES', 'SourceSelector', 'SpeedSample', 'Standstill', 'gnss_speed',
           'imu_yaw_rate']

# PGN -> (source name, DBC message name, speed signal, direction signal)
PGNS = {
    65097: ('isobus_ground', 'GBSD', 'GroundBasedMachineSpeed', 'GroundBasedMachineDirection'),
    65096: ('isobus_wheel', 'WBSD', 'WheelBasedMachineSpeed', 'WheelBasedMachineDirection'),
    61474: ('isobus_selected', 'MSS', 'MachineSelectedSpeed', 'MachineSelectedDirection'),
}
SOURCES = ('isobus_selected', 'isobus_ground', 'isobus_wheel', 'gnss', 'pulses')
RAW_VALID_MAX = 0xFAFF              # 16-bit J1939 values above are error / not available
REVERSE, FORWARD, DIRECTION_ERROR, NOT_AVAILABLE = 0, 1, 2, 3
MIN_PULSES_PER_METRE = 0.01         # one pulse per 100 m: no coarser sensor measures speed


@dataclass(frozen=True)
class GroundSpeedSourceConfig:
    """The ground-speed node's sources (its parameters; fixed while it runs)."""

    sources: list[str] = name_list(['isobus_selected', 'isobus_ground', 'gnss'], 'ground-speed '
                                   'sources in order of preference: isobus_selected, '
                                   'isobus_ground, isobus_wheel, gnss, pulses; the first heard '
                                   'from within source_timeout is used', read_only=True)
    source_timeout: float = setting(0.3, 'a source silent for longer hands over to the next '
                                    '(ISOBUS sends every 100 ms)', unit='s', range=(0.05, 5.0),
                                    read_only=True)
    isobus_interface: str = setting('socketcan', "python-can interface of the tractor's ISOBUS "
                                    "('virtual' in tests)", read_only=True)
    isobus_channel: str = setting('', "the tractor's ISOBUS CAN channel (e.g. can1, brought up "
                                  'at 250 kbit/s); empty: no ISOBUS', read_only=True)
    yaw_rate_source: str = choice('gnss', 'yaw rate (twist.angular.z) from the GNSS course, an '
                                  'IMU (imu/data) or none (0: straight)',
                                  ('gnss', 'imu', 'none'), read_only=True)
    min_course_speed: float = setting(0.3, 'below this speed the GNSS course gives no yaw rate',
                                      unit='m/s', range=(0.01, 10.0), read_only=True)
    pulses_per_metre: float = setting(0.0, 'wheel or radar pulses per metre travelled '
                                      '(wheel_pulses); 0: no pulse sensor', unit='1/m',
                                      range=(0.0, 1e6), read_only=True)
    standstill_speed: float = setting(0.05, 'a reading below this speed is 0 (the machine '
                                      'stands still: the sensor\'s noise at rest, GNSS about '
                                      '0.02 m/s per axis); it reads again from twice this; 0: '
                                      'none', unit='m/s', range=(0.0, 0.5), read_only=True)

    def __post_init__(self):
        check(self)
        bad = [s for s in self.sources if s not in SOURCES]
        if bad or not self.sources or len(set(self.sources)) != len(self.sources):
            raise ConfigError(f'sources = {self.sources} is out of range: allowed a list of '
                              f'{", ".join(SOURCES)}, each once, at least one')
        if 'pulses' in self.sources and not self.pulses_per_metre:
            raise ConfigError('pulses_per_metre = 0 is out of range: allowed > 0 when sources '
                              'lists pulses')
        if 0.0 < self.pulses_per_metre < MIN_PULSES_PER_METRE:
            raise ConfigError(f'pulses_per_metre = {self.pulses_per_metre:.6g} is out of '
                              f'range: allowed 0 (no pulse sensor) or '
                              f'{MIN_PULSES_PER_METRE:g}..1000000 1/m')


@dataclass(frozen=True)
class SpeedSample:
    """One ground-speed reading: `t` (s), `speed` (m/s, + forward), `source` (SOURCES)."""

    t: float
    speed: float
    source: str


# --------------------------------------------------------------------------------- GNSS

def gnss_speed(t, east, north, source='gnss'):
    """The sample of a GNSS velocity (m/s east and north), None if not finite (its magnitude
    included: two components of 1.7e308 are finite, their magnitude is not)."""
    if not (math.isfinite(east) and math.isfinite(north)):
        return None
    speed = math.hypot(east, north)
    if not math.isfinite(speed):
        return None
    return SpeedSample(float(t), speed, source)


class CourseYawRate:
    """Yaw rate (rad/s, + counter-clockwise) from successive courses over ground, only while
    the speed is at least `min_speed` (m/s) on both samples (a slow machine's course is noise)
    and the samples are at most `max_gap` s apart."""

    def __init__(self, min_speed=0.3, max_gap=1.0):
        self.min_speed, self.max_gap = min_speed, max_gap
        self._last = None           # (t, course)

    def update(self, t, east, north):
        """The yaw rate since the last velocity, or None (too slow, first, or a gap)."""
        if not (math.isfinite(east) and math.isfinite(north)) \
                or math.hypot(east, north) < self.min_speed:
            self._last = None
            return None
        course = math.atan2(north, east)
        last, self._last = self._last, (float(t), course)
        if last is None or not 0.0 < t - last[0] <= self.max_gap:
            return None
        turn = math.remainder(course - last[1], 2.0 * math.pi)
        return turn / (t - last[0])


def imu_yaw_rate(angular_velocity_z, covariance0=0.0):
    """Yaw rate (rad/s) of a sensor_msgs/Imu; NaN when it reports none (covariance[0] −1)."""
    if covariance0 == -1.0 or not math.isfinite(angular_velocity_z):
        return math.nan
    return float(angular_velocity_z)


# ------------------------------------------------------------------------------- ISOBUS

@lru_cache(maxsize=4)
def _database(path):
    # lazy: cantools costs 93 ms and only an ISOBUS speed source decodes frames (the twist
    # and odometry sources do not)
    import cantools
    return cantools.database.load_file(path)


def default_dbc():
    return str(shipped_file('isobus_speed.dbc'))


class IsobusSpeedDecoder:
    """ISO 11783-7 speed frames -> SpeedSample, through the DBC (cantools). `decode` returns
    the sample, or None for a frame that is not a speed message (`ignored`) or a value the
    tractor marks as an error or not available (`rejected`, counted by reason)."""

    def __init__(self, dbc_path=None):
        import cantools.j1939  # lazy: cantools, as in _database
        self._j1939 = cantools.j1939
        db = _database(dbc_path or default_dbc())
        self._messages = {pgn: db.get_message_by_name(name)
                          for pgn, (_, name, _, _) in PGNS.items()}
        self.rejected = {'not_available': 0, 'direction_error': 0, 'short_frame': 0}
        self.ignored = 0

    def pgn(self, arbitration_id, is_extended_id=True):
        if not is_extended_id:
            return None
        return self._j1939.pgn_from_frame_id(arbitration_id & 0x1FFFFFFF)

    def decode(self, t, arbitration_id, data, is_extended_id=True):
        pgn = self.pgn(arbitration_id, is_extended_id)
        if pgn not in PGNS:
            self.ignored += 1
            return None
        source, _, speed_name, direction_name = PGNS[pgn]
        if len(data) < 8:
            self.rejected['short_frame'] += 1
            return None
        message = self._messages[pgn]
        raw = message.decode(bytes(data), decode_choices=False, scaling=False)
        if raw[speed_name] > RAW_VALID_MAX:
            self.rejected['not_available'] += 1
            return None
        direction = raw[direction_name]
        if direction == DIRECTION_ERROR:
            self.rejected['direction_error'] += 1
            return None
        speed = message.decode(bytes(data), decode_choices=False)[speed_name]
        return SpeedSample(float(t), -speed if direction == REVERSE else float(speed), source)


# ------------------------------------------------------------------------------ pulses

class PulseSpeed:
    """Speed from a pulse counter of `bits` bits (wraps), `pulses_per_metre` calibrated."""

    def __init__(self, pulses_per_metre, bits=32, source='pulses'):
        if not (math.isfinite(pulses_per_metre) and pulses_per_metre >= MIN_PULSES_PER_METRE):
            raise ValueError(f'pulses_per_metre = {pulses_per_metre} is out of range: '
                             f'allowed {MIN_PULSES_PER_METRE:g}..1000000 1/m')
        self.per_metre, self.modulo, self.source = pulses_per_metre, 1 << bits, source
        self._last = None

    def update(self, t, count):
        """The speed since the last reading (None for the first, or time not advancing)."""
        last, self._last = self._last, (float(t), int(count))
        if last is None or not t > last[0]:
            return None
        pulses = (int(count) - last[1]) % self.modulo
        speed = pulses / self.per_metre / (t - last[0])
        if not math.isfinite(speed):
            return None
        return SpeedSample(float(t), speed, self.source)


# --------------------------------------------------------------------------- standstill

class Standstill:
    """Standstill is standstill (module doc): each source's reading below `threshold` (m/s)
    is 0 until its magnitude reaches twice that. `apply(sample)` gives the sample to use;
    `standing` the sources standing still now."""

    def __init__(self, threshold):
        if not (math.isfinite(threshold) and threshold >= 0.0):
            raise ValueError(f'standstill_speed = {threshold} is out of range: allowed >= 0')
        self.threshold = float(threshold)
        self._standing = {}                 # source -> standing still (True before a sample)

    def apply(self, sample):
        if self.threshold <= 0.0:
            return sample
        size = abs(sample.speed)
        standing = self._standing.get(sample.source, True)
        if size < self.threshold:
            standing = True
        elif size >= 2.0 * self.threshold:
            standing = False
        self._standing[sample.source] = standing
        if standing and sample.speed != 0.0:
            return SpeedSample(sample.t, 0.0, sample.source)
        return sample

    @property
    def standing(self):
        return sorted(source for source, still in self._standing.items() if still)


# ----------------------------------------------------------------------------- selector

class SourceSelector:
    """Which source to believe (see the module doc). `offer(sample)` returns the sample if it
    comes from the source in use (publish it), else None; `events` lists the switches as
    (t, text) for the diagnostics; `active` is the source in use (None before any)."""

    def __init__(self, preference: Sequence[str], timeout: float = 0.3):
        unknown = [s for s in preference if s not in SOURCES]
        if unknown or not preference:
            raise ValueError(f'ground speed sources = {list(preference)} is out of range: '
                             f'allowed a list of {", ".join(SOURCES)}')
        self.preference = list(preference)
        self.timeout = timeout
        self.last_heard: dict[str, float] = {}      # source -> t of its last sample
        self.active: str | None = None
        self.events: list[tuple[float, str]] = []

    def _fresh(self, source, now):
        heard = self.last_heard.get(source)
        return heard is not None and now - heard <= self.timeout

    def choose(self, now):
        """The preferred source heard from within the timeout at `now` (None: none is)."""
        chosen = next((s for s in self.preference if self._fresh(s, now)), None)
        if chosen != self.active:
            if self.active is not None and chosen is not None:
                quiet = now - self.last_heard.get(self.active, -math.inf)
                why = (f'{self.active} lost (no sample for {quiet:.2f} s)'
                       if quiet > self.timeout else f'{chosen} back')
                self.events.append((now, f'{why}: using {chosen}'))
            elif chosen is not None:
                self.events.append((now, f'using {chosen}'))
            else:
                self.events.append((now, f'{self.active} lost: no ground speed source'))
            self.active = chosen
        return chosen

    def offer(self, sample):
        if sample.source not in self.preference:
            return None
        self.last_heard[sample.source] = sample.t
        return sample if self.choose(sample.t) == sample.source else None
