"""The as-planted map: each plant on the earth (WGS 84) from GNSS fixes and the machine's motion.

Interpolating the fixes alone is not enough: an RTK fix scatters by about 2 cm per axis, 10 % of
a 0.2 m plant spacing, so two neighbours would be misplaced against each other by that much.
The machine's own motion (ground speed and yaw rate, dead-reckoned) is precise from one plant to
the next but drifts over a field. So each plant is placed on the dead-reckoned path, and the
fixes hold that path on the earth:

* Dead reckoning: the machine's reference point (x, y) and heading ψ, integrated (trapezoid)
  from the motion samples the rows use (sensing.row_speed: the speed accepted, the yaw rate
  accepted or held); the heading turns only while the machine moves forward.
* Fixes: a fix is usable when it has a position (status at least STATUS_FIX, finite latitude
  and longitude) and, when its covariance is known, a horizontal σ of at most `max_fix_sigma`.
  Usable fixes go into a local east/north frame (geo.LocalFrame, anchored at the first usable
  fix), each paired with where the dead-reckoned antenna (the scene's `antenna_position` on the
  machine) was at that instant.
* At each usable fix: the rotation φ and translation T that best map the dead-reckoned antenna
  onto the usable fixes of the last `track_length` metres of path (and at most `fix_window`
  seconds; least squares, weights 1/σ²). Once those fixes span half the track length the
  rotation is the heading from the track; where they span less (standing, creeping) the last
  rotation is kept and the heading follows the yaw rate between fixes.
* A plant at t is placed with the transform of the last usable fix at or before t, at most
  `max_fix_age` before it: east/north = R(φ)·p + T, p its row's nozzle on the dead-reckoned
  machine (the row's lateral offset to the left of the reference point, on the line of the
  planting points). If that fix came before the track gave any heading (the first metres of a
  run), the first fix with a heading places it, if it comes within `fix_window`. Otherwise the
  plant has no map position (NaN).

Which fixes place a plant depends on their stamps only, so the live monitor (`PlantPlacer`,
which holds a plant until a fix stamped after it has arrived, or the first heading) and replay
(`place_plants`) place every plant alike. Pure numpy, and pyproj through planter_ros.geo: no ROS.
"""

from bisect import bisect_right
from collections.abc import Mapping, Sequence
from collections import deque
from dataclasses import dataclass
import math
from typing import Generic, NamedTuple, Protocol, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from planter_ros.config import check, setting
from planter_ros.geo import LocalFrame, on_machine

STATUS_FIX = 0                    # sensor_msgs/NavSatStatus: NO_FIX = -1, FIX = 0, SBAS, GBAS
COVARIANCE_TYPE_UNKNOWN = 0       # sensor_msgs/NavSatFix.position_covariance_type
MIN_SIGMA = 1e-3                  # m: a reported σ below this weighs like 1 mm


@dataclass(frozen=True)
class MapSettings:
    """How the monitor places plants on the earth (parameters of the monitor, recorded in its
    bags with the prediction settings and read back by replay)."""

    track_length: float = setting(3.0, 'each fix holds the dead-reckoned path on the earth with '
                                  'the fixes of this much path before it; they give a heading '
                                  'once they span half of it', unit='m', range=(0.2, 1000.0))
    fix_window: float = setting(60.0, 'and with fixes of at most this long before it (standing '
                                'still, the heading is then kept and turned with the yaw rate)',
                                unit='s', range=(1.0, 3600.0))
    max_fix_sigma: float = setting(0.5, 'a fix whose covariance reports a larger horizontal '
                                   'standard deviation is not used; a fix of unknown '
                                   'covariance is used and weighted as this', unit='m',
                                   range=(0.001, 100.0))
    max_fix_age: float = setting(2.0, 'a plant more than this after the last usable fix has no '
                                 'map position', unit='s', range=(0.05, 600.0))

    def __post_init__(self):
        check(self)


_V = TypeVar('_V')


class GnssFix(NamedTuple, Generic[_V]):
    """GNSS fixes as sensor_msgs/NavSatFix gives them: one fix (GnssFix[float]) or a
    recording's in arrival order (GnssFix of arrays)."""

    t: _V                   # s, the stamp
    status: _V              # NavSatStatus.status (STATUS_FIX and above: a position)
    latitude: _V            # deg
    longitude: _V           # deg
    var_east: _V            # m², position_covariance[0]
    var_north: _V           # m², position_covariance[4]
    cov_type: _V            # position_covariance_type


class PlantBatch(Protocol):
    """What the placer needs of a batch of plants (prediction.Plants, a layer above): each
    plant's instant (s) and row index, and its latitude and longitude to set (deg)."""

    time: np.ndarray
    row: np.ndarray
    latitude: np.ndarray
    longitude: np.ndarray

    def __len__(self) -> int: ...


_P = TypeVar('_P', bound=PlantBatch)


class PlantSpots(NamedTuple):
    """Plants to place: each one's instant (s) and its row's lever arms from the machine's
    reference point (m; `forward` None: 0, on its line)."""

    t: ArrayLike
    lateral: ArrayLike
    forward: ArrayLike | None = None


def fix_sigma(fixes, max_sigma):
    """Horizontal σ (m) of each fix of `fixes` (GnssFix of arrays), NaN where the fix is not
    usable: no position (status below STATUS_FIX or NaN, latitude or longitude not finite or
    out of range) or a known covariance with σ above `max_sigma`. Unknown covariance:
    `max_sigma`."""
    status, lat, lon, ce, cn, kind = (np.asarray(a, dtype=float) for a in fixes[1:])
    with np.errstate(invalid='ignore'):
        usable = ((status >= STATUS_FIX) & np.isfinite(lat) & np.isfinite(lon)
                  & (np.abs(lat) <= 90.0) & (np.abs(lon) <= 180.0))
        sigma = np.where(kind == COVARIANCE_TYPE_UNKNOWN, max_sigma,
                         np.sqrt(0.5 * (ce + cn)))
        usable &= np.isfinite(sigma) & (sigma <= max_sigma)
    return np.where(usable, np.maximum(sigma, MIN_SIGMA), np.nan)


# ----------------------------------------------------------------------------- dead reckoning

def dead_reckoning(t, v, w):
    """The machine's reference point (x, y, m) and heading ψ (rad) at the motion samples
    (t s increasing, v m/s, ω_z rad/s), from (0, 0, 0) at the first: trapezoid integration,
    the heading turning only while v > 0. The same arithmetic as `DeadReckoning`."""
    t, v, w = (np.asarray(a, dtype=float) for a in (t, v, w))
    if not t.size:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    dt = np.diff(t)
    turn = np.where(v > 0.0, w, 0.0)
    psi = np.concatenate(([0.0], np.cumsum(0.5 * (turn[:-1] + turn[1:]) * dt)))
    vx, vy = v * np.cos(psi), v * np.sin(psi)
    x = np.concatenate(([0.0], np.cumsum(0.5 * (vx[:-1] + vx[1:]) * dt)))
    y = np.concatenate(([0.0], np.cumsum(0.5 * (vy[:-1] + vy[1:]) * dt)))
    return x, y, psi


class DeadReckoning:
    """`dead_reckoning` one sample at a time, keeping the last `keep` seconds."""

    def __init__(self, keep):
        self.keep = keep
        self.t, self.x, self.y, self.psi = [], [], [], []
        # (v cos ψ, v sin ψ, turn rate) of the last sample (read only once there is one)
        self._last = (0.0, 0.0, 0.0)

    def add(self, t, v, w):
        t, v = float(t), float(v)
        turn = float(w) if v > 0.0 else 0.0
        if not self.t:
            x = y = psi = 0.0
        else:
            if not t > self.t[-1]:
                return
            dt = t - self.t[-1]
            vx0, vy0, turn0 = self._last
            psi = self.psi[-1] + 0.5 * (turn0 + turn) * dt
        vx, vy = (v * np.cos(np.float64(psi)), v * np.sin(np.float64(psi)))
        if self.t:
            x = self.x[-1] + 0.5 * (vx0 + vx) * dt
            y = self.y[-1] + 0.5 * (vy0 + vy) * dt
        for series, value in ((self.t, t), (self.x, x), (self.y, y), (self.psi, psi)):
            series.append(float(value))
        self._last = (float(vx), float(vy), turn)
        if self.t[0] < t - 2.0 * self.keep and len(self.t) > 2:
            cut = bisect_right(self.t, t - self.keep) - 1
            if cut > 0:
                for series in (self.t, self.x, self.y, self.psi):
                    del series[:cut]

    def covers(self, t):
        return bool(self.t) and self.t[0] <= t <= self.t[-1]

    def pose(self, t):
        return _pose(np.asarray(self.t), np.asarray(self.x), np.asarray(self.y),
                     np.asarray(self.psi), t)


def _pose(t_dr, x, y, psi, t):
    """(x, y, ψ) interpolated at times t (inside the samples' span)."""
    return np.interp(t, t_dr, x), np.interp(t, t_dr, y), np.interp(t, t_dr, psi)


# ----------------------------------------------------------------------------- the track

class FixTrack:
    """Usable fixes in order, each giving the transform dead-reckoned path -> local east/north
    (see the module doc). `add` takes a fix whose instant the dead reckoning covers.

    The least-squares fit of each fix needs only weighted sums over its window, so the track
    keeps running sums (rebased at the window's start now and then) in plain floats: a fix
    costs a few microseconds whatever the window holds, and the live placer and replay, both
    calling `add`, compute every transform with the same arithmetic."""

    REBASE = 256                  # fixes before the running sums restart at the window

    def __init__(self, settings, antenna, keep_all=False):
        """`keep_all`: keep every fix's transform (replay places plants after all fixes);
        otherwise those too old to place a plant still to come are dropped."""
        self.settings = settings
        self.keep_all = keep_all
        self.antenna = (float(antenna[0]), float(antenna[1]))
        self.frame = None
        # the fixes from just before the window on: instant, antenna path length (m) and the
        # running sums after each (w, w·ax, w·ay, w·e, w·n, w·|a|², w·a·b, w·a×b; a the
        # dead-reckoned antenna, b the fix in east/north, w = 1/σ²)
        self._t, self._path, self._sums = [], [], []
        self._first = 0               # index in those lists of the window's first fix
        self._antenna_at = None       # the last fix's dead-reckoned antenna (x, y)
        self._phi = None
        self.times = []               # each usable fix's instant, with its transform:
        self.transforms = []          # (φ, Tx, Ty), or None before a heading is known
        self.first_heading = None     # (instant, transform) of the first fix with a heading
        self.fixes = 0                # usable fixes taken

    def anchor(self, latitude, longitude) -> LocalFrame:
        """The local frame, made at the first fix."""
        if self.frame is None:
            self.frame = LocalFrame(latitude, longitude)
        return self.frame

    def add(self, t, latitude, longitude, sigma, pose, east_north=None):
        """A usable fix at t (s) with its σ (m) and the dead-reckoned pose (x, y, ψ) at t;
        `east_north`: the fix already in the local frame (replay converts all at once)."""
        settings = self.settings
        t = float(t)
        frame = self.anchor(latitude, longitude)
        if east_north is None:
            east_north = frame.to_east_north(longitude, latitude)
        e, n = float(east_north[0]), float(east_north[1])
        ax, ay = on_machine(pose[0], pose[1], pose[2], *self.antenna)
        ax, ay = float(ax), float(ay)
        path = 0.0
        if self._antenna_at is not None:
            path = self._path[-1] + math.hypot(ax - self._antenna_at[0],
                                               ay - self._antenna_at[1])
        self._antenna_at = (ax, ay)
        w = 1.0 / float(sigma) ** 2
        last = self._sums[-1] if self._sums else (0.0,) * 8
        self._t.append(t)
        self._path.append(path)
        self._sums.append((last[0] + w, last[1] + w * ax, last[2] + w * ay, last[3] + w * e,
                           last[4] + w * n, last[5] + w * (ax * ax + ay * ay),
                           last[6] + w * (ax * e + ay * n), last[7] + w * (ax * n - ay * e)))
        # the window: the fixes of the last track_length of path (and the one just before it),
        # at most fix_window old
        end, first = len(self._t) - 1, self._first
        while first < end and (self._path[first + 1] <= path - settings.track_length
                               or self._t[first] < t - settings.fix_window):
            first += 1
        if first > self.REBASE:
            self._rebase(first)
            end, first = len(self._t) - 1, 1
        self._first = first
        before = self._sums[first - 1] if first > 0 else (0.0,) * 8
        transform = self._fit([a - b for a, b in zip(self._sums[end], before)])
        self.fixes += 1
        self.times.append(t)
        self.transforms.append(transform)
        if transform is not None and self.first_heading is None:
            self.first_heading = (t, transform)
        horizon = t - settings.fix_window - 2.0 * settings.max_fix_age - 1.0
        if not self.keep_all and len(self.times) > 2 and self.times[1] < horizon:
            cut = bisect_right(self.times, horizon) - 1
            del self.times[:cut], self.transforms[:cut]

    def add_all(self, t, sigma, pose, east_north):
        """`add` of every usable fix of a recording at once, on a new track that keeps every
        transform (replay), anchored (`anchor`): arrays of the fixes' instants (increasing), σ,
        the dead-reckoned poses (x, y, ψ arrays) and the fixes in the local frame (east,
        north arrays). The same
        arithmetic as one `add` after the other, sum for sum and rebase for rebase: the
        running sums are accumulated in order (numpy's accumulate adds one after the other),
        the windows found with searchsorted (path and time only grow), and the angles, the
        path steps and the weights taken from `math` and Python floats as `add` takes them."""
        if not self.keep_all or self._t or self.frame is None:
            raise ValueError('FixTrack.add_all: only on a new anchored track keeping every '
                             'transform')
        t = np.asarray(t, dtype=float)
        m = t.size
        if not m:
            return
        settings = self.settings
        ax, ay = on_machine(np.asarray(pose[0], dtype=float), np.asarray(pose[1], dtype=float),
                            np.asarray(pose[2], dtype=float), *self.antenna)
        ax, ay = np.asarray(ax, dtype=float), np.asarray(ay, dtype=float)
        e, n = (np.asarray(a, dtype=float) for a in east_north)
        xs, ys = ax.tolist(), ay.tolist()
        steps = [math.hypot(xs[k] - xs[k - 1], ys[k] - ys[k - 1]) for k in range(1, m)]
        path = np.add.accumulate(np.concatenate(([0.0], steps)))
        w = np.array([1.0 / float(s) ** 2 for s in np.asarray(sigma, dtype=float).tolist()])
        increments = np.column_stack((w, w * ax, w * ay, w * e, w * n,
                                      w * (ax * ax + ay * ay), w * (ax * e + ay * n),
                                      w * (ax * n - ay * e)))
        # each fix's window: the first fix not past its track length nor its time window
        past = np.maximum(np.searchsorted(path[1:], path - settings.track_length, side='right'),
                          np.searchsorted(t, t - settings.fix_window, side='left'))
        first = np.maximum.accumulate(np.minimum(past, np.arange(m)))
        # where the running sums restart (add's rebase) and what each fit subtracts
        sums = np.zeros((m, 8))
        fits = np.zeros((m, 8))
        offset, done = 0, 0
        events = []
        for k, f in enumerate(first.tolist()):
            if f - offset > self.REBASE:
                events.append(k)
                offset = f - 1
        previous = np.zeros(8)
        for stop in sorted(set(events) | {m - 1}):
            block = np.add.accumulate(np.vstack((previous, increments[done:stop + 1])))[1:]
            sums[done:stop + 1] = block
            if stop in events:
                # fits before the rebase at `stop` see the sums as they were
                self._fit_inputs(sums, first, done, stop, fits)
                base = sums[first[stop] - 1].copy()
                sums[first[stop] - 1:stop + 1] -= base
                self._fit_inputs(sums, first, stop, stop + 1, fits)
            else:
                self._fit_inputs(sums, first, done, stop + 1, fits)
            previous = sums[stop]
            done = stop + 1
        transforms = self._fit_all(fits)
        self._t, self._path = t[offset:].tolist(), path[offset:].tolist()
        self._sums = [tuple(row) for row in sums[offset:].tolist()]
        self._first = int(first[-1]) - offset
        self._antenna_at = (xs[-1], ys[-1])
        self.fixes += m
        self.times += t.tolist()
        self.transforms += transforms
        for k, transform in enumerate(transforms):
            if transform is not None:
                self.first_heading = (float(t[k]), transform)
                break

    @staticmethod
    def _fit_inputs(sums, first, lo, hi, out):
        """The window sums of fixes lo..hi-1 (each fix's sums less those before its window) as
        `add` forms them; `first`: each fix's window start (absolute index)."""
        if hi <= lo:
            return
        k = np.arange(lo, hi)
        before = np.where((first[k] > 0)[:, None], sums[np.maximum(first[k] - 1, 0)], 0.0)
        out[lo:hi] = sums[lo:hi] - before

    def _fit_all(self, fits):
        """`_fit` of every row of window sums, in order (the rotation kept where the window
        gives no heading)."""
        total, sax, say, sbx, sby, saa, sab, sacb = fits.T
        amx, amy, bmx, bmy = sax / total, say / total, sbx / total, sby / total
        spread = saa - total * (amx * amx + amy * amy)
        spread = np.where(0.0 > spread, 0.0, spread)          # max(spread, 0.0), NaN kept
        extent = np.sqrt(12.0 * spread / total)
        heading = extent >= 0.5 * self.settings.track_length
        cross = sacb - total * (amx * bmy - amy * bmx)
        dot = sab - total * (amx * bmx + amy * bmy)
        out: list[tuple[float, float, float] | None] = []
        phi = self._phi
        for has, y, x, mx, my, bx, by in zip(
                heading.tolist(), cross.tolist(), dot.tolist(), amx.tolist(), amy.tolist(),
                bmx.tolist(), bmy.tolist()):
            if has:
                phi = math.atan2(y, x)
            if phi is None:
                out.append(None)
                continue
            c, s = math.cos(phi), math.sin(phi)
            out.append((phi, bx - (c * mx - s * my), by - (s * mx + c * my)))
        self._phi = phi
        return out

    def _rebase(self, first):
        """Drop the fixes before the one preceding the window's first and restart the running
        sums there (they stay of the window's size: no precision lost over a long run)."""
        base = self._sums[first - 1]
        del self._t[:first - 1], self._path[:first - 1], self._sums[:first - 1]
        self._sums = [tuple(a - b for a, b in zip(sums, base)) for sums in self._sums]

    def _fit(self, sums):
        """(φ, Tx, Ty) mapping the window's dead-reckoned antenna onto its fixes, from its
        weighted sums (see `add`)."""
        total, sax, say, sbx, sby, saa, sab, sacb = sums
        amx, amy, bmx, bmy = sax / total, say / total, sbx / total, sby / total
        # Σw|a − ā|²: the path's extent as the length of a straight stretch of that spread
        spread = max(saa - total * (amx * amx + amy * amy), 0.0)
        extent = math.sqrt(12.0 * spread / total)
        if extent >= 0.5 * self.settings.track_length:
            cross = sacb - total * (amx * bmy - amy * bmx)
            dot = sab - total * (amx * bmx + amy * bmy)
            self._phi = math.atan2(cross, dot)
        if self._phi is None:
            return None
        c, s = math.cos(self._phi), math.sin(self._phi)
        return (self._phi, bmx - (c * amx - s * amy), bmy - (s * amx + c * amy))

    def transform_for(self, t):
        """The transform that places a plant at t: that of the last usable fix at or before
        t, at most max_fix_age before it; if that fix came before any heading, the first fix
        with a heading, at most fix_window after t. None: no map position."""
        k = bisect_right(self.times, t) - 1
        if k < 0 or t - self.times[k] > self.settings.max_fix_age:
            return None
        if self.transforms[k] is not None:
            return self.transforms[k]
        first = self.first_heading
        if first is not None and first[0] - t <= self.settings.fix_window:
            return first[1]
        return None

    def decided(self, t, fix_seen, motion_seen):
        """Are all the fixes that could place a plant at t in (live: fixes arrive in order)?"""
        age, window = self.settings.max_fix_age, self.settings.fix_window
        if not (fix_seen > t or motion_seen > t + age or fix_seen < t - age):
            return False
        k = bisect_right(self.times, t) - 1
        if k < 0 or t - self.times[k] > age or self.transforms[k] is not None:
            return True
        # before the first heading: wait for it, as long as it may still place this plant
        return (self.first_heading is not None or self.times[-1] > t + window
                or motion_seen > t + window + age)

    def place(self, t, lateral_offset, pose, forward_offset=None):
        """(east, north, heading) in the local frame of plants at times t (array) on rows at
        `lateral_offset` and `forward_offset` (arrays, m from the machine's reference point;
        forward None: on its line), the machine's dead-reckoned pose at t given; NaN where no
        transform applies (`transform_for`, for all plants at once)."""
        t = np.asarray(t, dtype=float)
        lateral_offset = np.asarray(lateral_offset, dtype=float)
        forward_offset = (np.zeros(t.size) if forward_offset is None
                          else np.asarray(forward_offset, dtype=float))
        out = np.full((3, t.size), np.nan)
        if not self.times or not t.size:
            return out
        settings = self.settings
        times = np.asarray(self.times, dtype=float)
        k = np.searchsorted(times, t, side='right') - 1
        at = np.maximum(k, 0)
        recent = (k >= 0) & ~(t - times[at] > settings.max_fix_age)
        # each fix's transform; None: not yet a heading
        transforms = self.transforms
        own = np.array([tr is not None for tr in transforms])
        which = np.where(recent & own[at], at, -1)
        first = self.first_heading
        if first is not None:
            transforms = [*transforms, first[1]]
            late = recent & ~own[at] & (first[0] - t <= settings.fix_window)
            which = np.where(late, len(self.transforms), which)
        placed = (which >= 0) & np.isfinite(pose[0])
        if not placed.any():
            return out
        # the transforms that place a plant, cos and sin as `math` gives them
        used, where = np.unique(which[placed], return_inverse=True)
        values = np.array([(tr[0], math.cos(tr[0]), math.sin(tr[0]), tr[1], tr[2])
                           for tr in (transforms[k] for k in used.tolist())]).reshape(-1, 5)
        phi, c, s, tx, ty = values[where.reshape(-1)].T
        x, y, heading = (np.asarray(p, dtype=float)[placed] for p in pose[:3])
        px, py = on_machine(x, y, heading, forward_offset[placed], lateral_offset[placed])
        out[:, placed] = (c * px - s * py + tx, s * px + c * py + ty, heading + phi)
        return out


@dataclass
class Placement:
    """Where plants are: local east/north (m) and heading (rad, counter-clockwise from east) in
    the map's frame (origin: the first usable fix), latitude/longitude (deg WGS 84); NaN where
    a plant has no map position."""

    east: np.ndarray
    north: np.ndarray
    heading: np.ndarray
    latitude: np.ndarray
    longitude: np.ndarray
    origin: tuple | None          # (latitude, longitude) of the local frame, None without fixes


def _placement(track, t, offsets, pose, forward=None):
    east, north, heading = track.place(t, offsets, pose, forward)
    lat = np.full(east.shape, np.nan)
    lon = np.full(east.shape, np.nan)
    ok = np.isfinite(east)
    if ok.any():
        lon[ok], lat[ok] = track.frame.to_lonlat(east[ok], north[ok])
    origin = None if track.frame is None else (track.frame.latitude, track.frame.longitude)
    return Placement(east, north, heading, lat, lon, origin)


def place_plants(plants, motion, fixes, settings, antenna):
    """Replay's map: where each plant of `plants` (PlantSpots: its row's lever arms from the
    machine's reference point, a machine file's; the antenna is the reference point) is
    (Placement), from all the recording's motion samples `motion` = (t, v, ω_z) as the rows
    used them and `fixes` (GnssFix of arrays, in arrival order), stamps in s."""
    plant_t = np.asarray(plants.t, dtype=float)
    track = FixTrack(settings, antenna, keep_all=True)
    mt, mv, mw = (np.asarray(a, dtype=float) for a in motion)
    x, y, psi = dead_reckoning(mt, mv, mw)
    fixes = GnssFix(*(np.asarray(a, dtype=float) for a in fixes))
    ft, lat, lon = fixes.t, fixes.latitude, fixes.longitude
    sigma = fix_sigma(fixes, settings.max_fix_sigma)
    # out of order or repeated stamps are dropped, as live: each fix must come after every
    # finite stamp before it
    finite = np.isfinite(ft)
    latest = np.maximum.accumulate(np.where(finite, ft, -np.inf))
    arrived = finite & (ft > np.concatenate(([-np.inf], latest[:-1])))
    usable = np.flatnonzero(arrived & np.isfinite(sigma))
    if usable.size:
        frame = track.anchor(lat[usable[0]], lon[usable[0]])
        taken = usable[(ft[usable] >= mt[0]) & (ft[usable] <= mt[-1])] if mt.size else \
            usable[:0]
        # the poses and the local frame of all fixes at once; each fix then as live
        px, py, ppsi = _pose(mt, x, y, psi, ft[taken])
        east, north = frame.to_east_north(lon[taken], lat[taken])
        track.add_all(ft[taken], sigma[taken], (px, py, ppsi), (east, north))
    forward = None if plants.forward is None else np.asarray(plants.forward, dtype=float)
    return _placement(track, plant_t, np.asarray(plants.lateral, dtype=float),
                      _pose_inside(mt, x, y, psi, plant_t), forward)


def _pose_inside(t_dr, x, y, psi, t):
    """The pose at times t, NaN outside the dead reckoning's span."""
    t = np.asarray(t, dtype=float)
    if not np.size(t_dr):
        return (t * np.nan,) * 3
    inside = (t >= t_dr[0]) & (t <= t_dr[-1])
    return tuple(np.where(inside, p, np.nan) for p in _pose(t_dr, x, y, psi, t))


class PlantPlacer(Generic[_P]):
    """The live monitor's map: motion samples, fixes and plants in as they arrive; plants out,
    placed, once the fixes that place them are in (see the module doc). Every `add_*` returns
    the plants released by that input as a list of (plants, Placement), in the order the
    plants came in."""

    def __init__(self, settings: MapSettings, antenna: Sequence[float],
                 lateral_offsets: Mapping[int, float],
                 forward_offsets: Mapping[int, float] | None = None) -> None:
        # lazy: pyproj costs 60 ms, loaded with a placer (the monitor's start) rather than in
        # the callback of the first fix, and not by importing this module (replay, the sync node)
        import pyproj  # noqa: F401
        self.settings = settings
        self.offsets = dict(lateral_offsets)          # row index -> lateral offset (m)
        self.forward = dict(forward_offsets or {})    # row index -> forward offset (m)
        self.track = FixTrack(settings, antenna)
        self.dr = DeadReckoning(keep=settings.fix_window + settings.max_fix_age + 5.0)
        # usable fixes waiting for the motion: (t, latitude, longitude, σ)
        self._fixes: deque[tuple[float, float, float, float]] = deque()
        self._fix_seen = -math.inf                    # newest fix stamp received (any status)
        self._motion_seen = -math.inf
        self._pending: deque[_P] = deque()           # plants not released yet

    def add_motion(self, t: float, v: float, w: float) -> list[tuple[_P, Placement]]:
        self.dr.add(t, v, w)
        self._motion_seen = max(self._motion_seen, float(t))
        self._take_fixes()
        return self._release()

    def add_fix(self, fix: GnssFix[float]) -> list[tuple[_P, Placement]]:
        """One GNSS fix (GnssFix of numbers)."""
        t = float(fix.t)
        if not (math.isfinite(t) and t > self._fix_seen):
            return self._release()
        self._fix_seen = t
        sigma = float(fix_sigma(fix, self.settings.max_fix_sigma))
        latitude, longitude = fix.latitude, fix.longitude
        if math.isfinite(sigma):
            self.track.anchor(latitude, longitude)
            self._fixes.append((t, float(latitude), float(longitude), sigma))
            self._take_fixes()
        return self._release()

    def add_plants(self, plants: _P) -> list[tuple[_P, Placement]]:
        if len(plants):
            self._pending.append(plants)
        return self._release()

    def flush(self) -> list[tuple[_P, Placement]]:
        """Release every plant held, placed with the fixes there are (the monitor's end)."""
        return self._release(everything=True)

    def _take_fixes(self):
        while self._fixes and self.dr.t:
            t = self._fixes[0][0]
            if t < self.dr.t[0]:
                self._fixes.popleft()               # before the motion began: never placed
            elif t <= self.dr.t[-1]:
                _, lat, lon, sigma = self._fixes.popleft()
                self.track.add(t, lat, lon, sigma, self.dr.pose(t))
            else:
                break

    def _release(self, everything: bool = False) -> list[tuple[_P, Placement]]:
        out: list[tuple[_P, Placement]] = []
        while self._pending and (everything or all(
                self.track.decided(t, self._fix_seen, self._motion_seen)
                for t in self._pending[0].time.tolist())):
            plants = self._pending.popleft()
            offsets = np.array([self.offsets.get(int(r), 0.0) for r in plants.row])
            forward = np.array([self.forward.get(int(r), 0.0) for r in plants.row])
            pose = _pose_inside(np.asarray(self.dr.t), np.asarray(self.dr.x),
                                np.asarray(self.dr.y), np.asarray(self.dr.psi), plants.time)
            placement = _placement(self.track, plants.time, offsets, pose, forward)
            plants.latitude = placement.latitude
            plants.longitude = placement.longitude
            out.append((plants, placement))
        return out
