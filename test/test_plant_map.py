"""The as-planted map (sensing.plant_map) against the simulated truth: plants placed on the
ellipsoid from noisy fixes and the machine's motion, live and in replay alike."""
import math

import numpy as np
import pytest

from planter_ros.geo import geodesic_distance
from planter_ros.prediction import PLANT_FIELDS, Plants
from planter_ros.sensing.plant_map import (
    GnssFix, MapSettings, PlantPlacer, PlantSpots, fix_sigma, place_plants)
from planter_ros.sensing.row_speed import motion_samples
from planter_ros.sim.field import FieldProfile, demo_curves
from planter_ros.sim.gnss import SimulatedGnss, fix_positions

D = 0.2
EXACT = SimulatedGnss(noise=0.0)
RTK = SimulatedGnss()                  # 2 cm per axis
MAP = MapSettings()


def field_run(duration=30.0, seed=0, antenna=(2.5, 0.3), gnss=RTK, offsets=(0.75,),
              curves=None, profile=None, fix_rate=10.0):
    """Motion samples (20 Hz, noisy speed and yaw rate), fixes (noisy) and the true plant
    instants every d of each row's own path, with their true positions."""
    rng = np.random.default_rng(seed)
    profile = profile or FieldProfile(duration, 0.2, curves=demo_curves(duration)
                                      if curves is None else curves)
    t = np.arange(0.0, duration, 0.05)
    v = np.array([profile(x) for x in t])
    v_meas = np.where(v > 0, v + rng.normal(0.0, 0.005, t.size), 0.0)
    w_meas = np.array([profile.yaw_rate(x) for x in t]) + rng.normal(0.0, 0.005, t.size)
    tf = np.arange(0.0, duration, 1.0 / fix_rate)
    lat, lon, _ = fix_positions(profile, tf, gnss, antenna, rng)
    var = np.full(tf.size, gnss.noise ** 2)
    fixes = (tf, np.zeros(tf.size), lat, lon, var, var, np.full(tf.size, 2.0))
    grid = np.linspace(0.0, duration, 200_001)
    plants = []
    for row, y in enumerate(offsets):
        distance = profile.row_distance(grid, y)
        tp = np.interp(np.arange(0.5 * D, distance[-1], D), distance, grid)
        true_lat, true_lon, _ = fix_positions(profile, tp, EXACT, (0.0, y))
        plants.append((row, y, tp, true_lat, true_lon))
    return (t, v_meas, w_meas), fixes, plants


def as_plants(times, rows):
    n = len(times)
    table = np.full((n, len(PLANT_FIELDS)), np.nan)
    table[:, PLANT_FIELDS.index('time')] = times
    table[:, PLANT_FIELDS.index('row')] = rows
    table[:, PLANT_FIELDS.index('index')] = np.arange(n)
    return Plants.from_table(table)


def placed(motion, fixes, plants, settings=MAP, antenna=(2.5, 0.3)):
    offsets = [y for _, y, _, _, _ in plants]
    mt = motion_samples(motion, offsets, yaw=True)
    t = np.concatenate([tp for _, _, tp, _, _ in plants])
    y = np.concatenate([np.full(tp.size, y) for _, y, tp, _, _ in plants])
    return place_plants(PlantSpots(t, y), mt, fixes, settings, antenna)


def test_plants_land_where_the_simulated_machine_set_them_and_d_apart():
    motion, fixes, plants = field_run(offsets=(0.75, -0.75))
    result = placed(motion, fixes, plants)
    start = 0
    for _, _, tp, true_lat, true_lon in plants:
        lat = result.latitude[start:start + tp.size]
        lon = result.longitude[start:start + tp.size]
        start += tp.size
        assert np.all(np.isfinite(lat))                 # the first metres too
        off = geodesic_distance(lon, lat, true_lon, true_lat)
        assert np.sqrt(np.mean(off ** 2)) < 0.02        # within an RTK fix's noise
        step = geodesic_distance(lon[:-1], lat[:-1], lon[1:], lat[1:])
        true_step = geodesic_distance(true_lon[:-1], true_lat[:-1], true_lon[1:], true_lat[1:])
        # neighbours are d apart (a chord of a 10 m turn is d to 1e-4 of it) within 2 % RMS,
        # though each fix scatters by 2 cm (10 % of d)
        assert np.sqrt(np.mean((step - D) ** 2)) < 0.02 * D
        assert np.sqrt(np.mean((step - true_step) ** 2)) < 0.015 * D


def test_the_antenna_anywhere_on_the_machine_gives_the_same_map():
    a = placed(*field_run(antenna=(0.0, 0.0), seed=3)[:3], antenna=(0.0, 0.0))
    b = placed(*field_run(antenna=(3.0, -1.0), seed=3)[:3], antenna=(3.0, -1.0))
    assert np.all(np.isfinite(a.latitude)) and np.all(np.isfinite(b.latitude))
    # the same noise draws, the antenna elsewhere: the plants stay within the noise's effect
    assert np.max(geodesic_distance(a.longitude, a.latitude, b.longitude, b.latitude)) < 0.03
    # an antenna the map is not told about shifts every plant by its offset
    c = placed(*field_run(antenna=(3.0, -1.0), seed=3)[:3], antenna=(0.0, 0.0))
    shift = geodesic_distance(a.longitude, a.latitude, c.longitude, c.latitude)
    assert np.median(shift) == pytest.approx(math.hypot(3.0, 1.0), rel=0.05)


def test_unusable_fixes_are_not_used_and_without_fixes_there_is_no_map():
    nan = math.nan
    sigma = fix_sigma(GnssFix(np.arange(7.0), [-1, 0, 0, 0, 0, 1, nan],
                              [52, 52, nan, 52, 52, 52, 52], [5, 5, 5, 5, 5, 5, 5],
                              [0, 1e-4, 0, 4.0, 0, 0, 0], [0, 1e-4, 0, 4.0, 0, 0, 0],
                              [2, 2, 2, 2, 0, 1, 2]), 0.5)
    # no fix; 1 cm; no position; σ 2 m > 0.5 m; unknown covariance: weighted as 0.5 m;
    # SBAS fix with a 0 covariance: 1 mm; NaN status
    assert np.isnan(sigma[[0, 2, 3, 6]]).all()
    assert sigma[1] == pytest.approx(0.01) and sigma[4] == 0.5 and sigma[5] == 1e-3
    motion, fixes, plants = field_run(duration=20.0)
    empty = tuple(np.zeros(0) for _ in range(7))
    none = placed(motion, empty, plants)
    assert np.all(np.isnan(none.latitude)) and none.origin is None
    # every fix NO_FIX: the same
    no_fix = (fixes[0], np.full(fixes[0].size, -1.0)) + fixes[2:]
    assert np.all(np.isnan(placed(motion, no_fix, plants).latitude))
    # fixes lost from 8 s to 14 s: plants more than max_fix_age after the last one have none
    t = fixes[0]
    keep = (t < 8.0) | (t > 14.0)
    gap = placed(motion, tuple(a[keep] for a in fixes), plants)
    tp = plants[0][2]
    lost = (tp > 8.0 + MapSettings().max_fix_age) & (tp < 14.0)
    assert lost.any() and np.all(np.isnan(gap.latitude[lost]))
    assert np.all(np.isfinite(gap.latitude[~lost]))


class StopAndGo:
    """A run with a left turn (R = 8 m, 4-12 s) and a standstill from 19 s to 30 s: speed,
    yaw rate and pose(t) integrated on a fine grid, like sim.field.FieldProfile."""

    def __init__(self, dt=1e-3):
        self.grid = np.arange(0.0, 40.0 + dt, dt)
        g = self.grid
        self.v = np.where(g < 19.0, 0.25 * np.clip(np.minimum(g, 19.0 - g), 0.0, 1.0),
                          0.25 * np.clip(g - 30.0, 0.0, 1.0))
        self.w = self.v * np.where((g > 4.0) & (g < 12.0), 1.0 / 8.0, 0.0)

        def integral(f):
            return np.concatenate(([0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * dt)))
        self.s = integral(self.v)
        self.heading = integral(self.w)
        self.x = integral(self.v * np.cos(self.heading))
        self.y = integral(self.v * np.sin(self.heading))

    def __call__(self, t):
        return float(np.interp(t, self.grid, self.v))

    def yaw_rate(self, t):
        return float(np.interp(t, self.grid, self.w))

    def pose(self, t):
        return (np.interp(t, self.grid, self.x), np.interp(t, self.grid, self.y),
                np.interp(t, self.grid, self.heading))


def test_standing_still_keeps_the_heading_and_the_yaw_rate_turns_it():
    """A stop longer than the fix window: the fixes of a standing machine give no heading, the
    last one is kept; the plants after the stop land on the path as before."""
    path = StopAndGo()
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 40.0, 0.05)
    motion = (t, np.array([path(s) for s in t]), np.array([path.yaw_rate(s) for s in t]))
    tf = np.arange(0.0, 40.0, 0.1)
    lat, lon, _ = fix_positions(path, tf, SimulatedGnss(noise=0.02), (2.0, 0.0), rng)
    var = np.full(tf.size, 4e-4)
    fixes = (tf, np.zeros(tf.size), lat, lon, var, var, np.full(tf.size, 2.0))
    tp = np.interp(np.arange(0.1, path.s[-1], D), path.s, path.grid)
    # 8 s of fixes span 2 m at 0.25 m/s: a heading; the stop outlasts them
    settings = MapSettings(fix_window=8.0)
    result = place_plants(PlantSpots(tp, np.zeros(tp.size)),
                          motion_samples(motion, [0.0], yaw=True), fixes, settings, (2.0, 0.0))
    true_lat, true_lon, _ = fix_positions(path, tp, EXACT)
    off = geodesic_distance(result.longitude, result.latitude, true_lon, true_lat)
    after = tp > 30.0
    assert after.sum() >= 10 and np.all(np.isfinite(off))
    assert np.max(off[after]) < 0.03 and np.sqrt(np.mean(off ** 2)) < 0.02


def test_live_placement_equals_replay_in_any_arrival_order():
    """The monitor gets motion, fixes and plants interleaved (plants of a row in bursts, fixes
    at their own rate): what it publishes equals replay's map of the same recording."""
    motion, fixes, plants = field_run(duration=25.0, offsets=(0.5, -0.5), seed=7)
    mt, mv, mw = motion_samples(motion, [0.5, -0.5], yaw=True)
    events = [(t, 0, i) for i, t in enumerate(mt)] + \
        [(t + 0.03, 1, i) for i, t in enumerate(fixes[0])]       # fixes arrive 30 ms late
    # each plant is predicted when the first motion sample after it has come
    for row, _, tp, _, _ in plants:
        for t in tp:
            events.append((mt[np.searchsorted(mt, t, side='right')] + 1e-6, 2, (row, t)))
    events.sort(key=lambda e: (e[0], e[1]))
    placer = PlantPlacer(MapSettings(), (2.5, 0.3), {0: 0.5, 1: -0.5})
    out = []
    for _, kind, item in events:
        if kind == 0:
            out += placer.add_motion(mt[item], mv[item], mw[item])
        elif kind == 1:
            out += placer.add_fix(GnssFix(*(a[item] for a in fixes)))
        else:
            out += placer.add_plants(as_plants([item[1]], [item[0]]))
    out += placer.flush()
    live = Plants.concatenate([p for p, _ in out])
    total = sum(tp.size for _, _, tp, _, _ in plants)
    assert len(live) == total
    replayed = place_plants(PlantSpots(live.time, np.where(live.row == 0, 0.5, -0.5)),
                            (mt, mv, mw), fixes, MapSettings(), (2.5, 0.3))
    assert np.all(np.isfinite(live.latitude))
    np.testing.assert_allclose(live.latitude, replayed.latitude, rtol=0, atol=1e-13)
    np.testing.assert_allclose(live.longitude, replayed.longitude, rtol=0, atol=1e-13)
