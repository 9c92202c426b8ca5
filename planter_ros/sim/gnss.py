"""A simulated GNSS receiver on the machine: fixes along the path a field profile describes.

The machine starts at the field origin (`origin_latitude`, `origin_longitude`) heading
`origin_heading` (rad, counter-clockwise from east); its reference point then follows the
profile's pose(t) (sim.field) and the antenna sits at `antenna_position` on the machine
(geo.AntennaSettings). Each fix gets Gaussian horizontal noise of σ `noise` (m, per axis) and
reports that σ² in its covariance (type diagonal known), like an RTK receiver would.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from sensor_msgs.msg import NavSatFix, NavSatStatus

from planter_ros.config import check, setting
from planter_ros.geo import LocalFrame, on_machine
from planter_ros.kinematics.arrays import FloatArray

if TYPE_CHECKING:
    from builtin_interfaces.msg import Time

    from .field import FieldProfile


@dataclass(frozen=True)
class SimulatedGnss:
    """The simulated receiver and where the field is."""

    origin_latitude: float = setting(52.0, 'latitude of the field origin (WGS 84)', unit='deg',
                                     range=(-89.0, 89.0))
    origin_longitude: float = setting(5.0, 'longitude of the field origin (WGS 84)',
                                      unit='deg', range=(-180.0, 180.0))
    origin_altitude: float = setting(10.0, 'ellipsoidal height of the field', unit='m',
                                     range=(-500.0, 9000.0))
    origin_heading: float = setting(0.0, 'direction of travel at the start, counter-clockwise '
                                    'from east', unit='rad', range=(-7.0, 7.0))
    rate: float = setting(10.0, 'fixes per second', unit='Hz', range=(0.1, 100.0))
    noise: float = setting(0.02, 'horizontal noise, σ per axis (RTK fix: about 0.02 m)',
                           unit='m', range=(0.0, 10.0))

    def __post_init__(self) -> None:
        check(self)


def fix_positions(profile: FieldProfile, times: ArrayLike, gnss: SimulatedGnss,
                  antenna: Sequence[float] = (0.0, 0.0), rng: np.random.Generator | None = None
                  ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(latitude, longitude, altitude) in degrees, degrees, m of the antenna at `times` (s since
    the start of `profile`), with noise drawn from `rng` (none without an rng)."""
    instants = np.asarray(times, dtype=float)
    x, y, heading = profile.pose(instants)
    x, y = on_machine(x, y, heading, antenna[0], antenna[1])
    # the start frame (x forward at t = 0) turned to the origin heading: east, north
    c, s = np.cos(gnss.origin_heading), np.sin(gnss.origin_heading)
    east, north = c * x - s * y, s * x + c * y
    if rng is not None and gnss.noise > 0:
        east = east + rng.normal(0.0, gnss.noise, east.shape)
        north = north + rng.normal(0.0, gnss.noise, north.shape)
    lon, lat = _frame(gnss.origin_latitude, gnss.origin_longitude).to_lonlat(east, north)
    return lat, lon, np.full(instants.shape, gnss.origin_altitude)


@lru_cache(maxsize=8)
def _frame(latitude: float, longitude: float) -> LocalFrame:
    """The field's local frame, made once per origin (the demo asks at every fix)."""
    return LocalFrame(latitude, longitude)


def navsatfix(stamp: Time, latitude: float, longitude: float, altitude: float, noise: float,
              frame_id: str = 'gnss') -> NavSatFix:
    """A sensor_msgs/NavSatFix of one fix (status FIX, GPS service), covariance σ² diagonal."""
    msg = NavSatFix()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.status.status = NavSatStatus.STATUS_FIX
    msg.status.service = NavSatStatus.SERVICE_GPS
    msg.latitude, msg.longitude, msg.altitude = float(latitude), float(longitude), float(altitude)
    var = max(float(noise), 1e-3) ** 2
    msg.position_covariance = [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, 4.0 * var]
    msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
    return msg
