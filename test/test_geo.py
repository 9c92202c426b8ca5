"""Geodesy of the as-planted map and the simulated GNSS receiver (pyproj underneath)."""
import math

import numpy as np
import pytest

from planter_ros.config import ConfigError
from planter_ros.geo import AntennaSettings, LocalFrame, geodesic_distance, on_machine
from planter_ros.sim.field import Curve, FieldProfile
from planter_ros.sim.gnss import SimulatedGnss, fix_positions


def test_local_frame_round_trip_and_distances_agree_with_the_ellipsoid():
    frame = LocalFrame(52.0, 5.0)
    east = np.array([0.0, 0.2, 150.0, -800.0])
    north = np.array([0.0, 0.0, -60.0, 1200.0])
    lon, lat = frame.to_lonlat(east, north)
    back_e, back_n = frame.to_east_north(lon, lat)
    np.testing.assert_allclose(back_e, east, atol=1e-6)
    np.testing.assert_allclose(back_n, north, atol=1e-6)
    # metres in the frame are metres on the ellipsoid, to < 1e-5 relative over a field
    d = geodesic_distance(lon[:-1], lat[:-1], lon[1:], lat[1:])
    planar = np.hypot(np.diff(east), np.diff(north))
    np.testing.assert_allclose(d, planar, rtol=1e-5)


def test_a_point_on_the_machine_turns_with_its_heading():
    x, y = on_machine(10.0, 5.0, math.pi / 2, 1.0, 0.5)        # heading north: forward = +y
    assert x == pytest.approx(9.5) and y == pytest.approx(6.0)


def test_fixes_follow_the_path_the_speed_and_yaw_rate_describe():
    profile = FieldProfile(40.0, 0.5, curves=(Curve(10.0, 25.0, 10.0),))
    t = np.linspace(0.0, 40.0, 401)
    gnss = SimulatedGnss(origin_heading=math.radians(30.0), noise=0.0)
    lat, lon, _ = fix_positions(profile, t, gnss)
    step = geodesic_distance(lon[:-1], lat[:-1], lon[1:], lat[1:])
    travelled = np.diff(profile.distance(t))
    # chords of a 10 m turn are shorter than the arc by < 1e-4 m at these steps
    np.testing.assert_allclose(step, travelled, atol=2e-4)
    # at the start the machine heads 30° north of east
    frame = LocalFrame(gnss.origin_latitude, gnss.origin_longitude)
    e, n = frame.to_east_north(lon[:40], lat[:40])
    assert math.degrees(math.atan2(n[-1] - n[0], e[-1] - e[0])) == pytest.approx(30.0, abs=0.1)


def test_the_antenna_offset_moves_every_fix_by_its_length():
    profile = FieldProfile(20.0, 0.4)
    t = np.linspace(1.0, 19.0, 50)
    gnss = SimulatedGnss(noise=0.0)
    a = fix_positions(profile, t, gnss, (0.0, 0.0))
    b = fix_positions(profile, t, gnss, (1.5, -2.0))
    np.testing.assert_allclose(geodesic_distance(a[1], a[0], b[1], b[0]), 2.5, atol=1e-6)


@pytest.mark.parametrize('position', [[0.0], [0.0, 1.0, 2.0], [math.nan, 0.0], [100.0, 0.0]])
def test_a_bad_antenna_position_is_one_line(position):
    with pytest.raises(ConfigError) as err:
        AntennaSettings(antenna_position=position)
    assert 'antenna_position' in str(err.value) and '\n' not in str(err.value)
