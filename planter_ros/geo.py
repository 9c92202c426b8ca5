"""Where on the earth: WGS 84 positions and a local metric frame around a field origin.

The as-planted map needs plant positions a few centimetres apart on the ellipsoid; pyproj does
the geodesy (no hand-written formulas). `LocalFrame` is an azimuthal equidistant projection
centred on the field's origin: east and north in metres, exact in distance from the origin and
within a few µm per metre for the extent of a field (a few km).

The machine's frame follows REP 103: x forward, y left of its reference point (the point the
rows' lateral offsets are measured from); headings are counter-clockwise from east (ENU).
"""

from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planter_ros.config import ConfigError, check, setting

FloatArray = NDArray[np.float64]
Floats = float | NDArray[np.float64]         # a number, or an array of them


@dataclass(frozen=True)
class AntennaSettings:
    """Where the GNSS antenna sits on the machine (a scene value of the monitor)."""

    antenna_position: list[float] = setting(
        [0.0, 0.0], "GNSS antenna on the machine: x forward, y left of the machine's reference "
        "point (the point the rows' lateral offsets are measured from, on the line of the "
        'planting points)', unit='m', range=(-50.0, 50.0), read_only=True)

    def __post_init__(self) -> None:
        check(self)
        if len(self.antenna_position) != 2:
            raise ConfigError(f'antenna_position = {self.antenna_position} is out of range: '
                              'allowed two numbers [x, y] (m)')


class LocalFrame:
    """East/north metres around (latitude, longitude) on WGS 84, both ways."""

    def __init__(self, latitude: float, longitude: float) -> None:
        # lazy: pyproj costs 60 ms, needed only where a fix is placed; AntennaSettings and
        # on_machine serve the sync node and the scene checks without it
        from pyproj import Transformer
        if not (math.isfinite(latitude) and -89.0 <= latitude <= 89.0
                and math.isfinite(longitude) and -180.0 <= longitude <= 180.0):
            raise ValueError(f'origin ({latitude}, {longitude}) is out of range: allowed '
                             'latitude -89..89°, longitude -180..180°')
        self.latitude, self.longitude = float(latitude), float(longitude)
        # the projection of WGS 84 longitude/latitude straight from its PROJ string: no CRS
        # database look-up (a Transformer from EPSG:4326 takes some 30-50 ms) and no CRS parsed
        # at all (pyproj's Proj parses one, a tenth of a millisecond per bag in replay, and
        # writes the origin back with 15 digits: this frame is centred on the origin as given)
        self._proj = Transformer.from_pipeline(
            f'+proj=aeqd +lat_0={self.latitude!r} +lon_0={self.longitude!r} +ellps=WGS84 '
            '+units=m +no_defs')

    def to_lonlat(self, east: ArrayLike, north: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(longitude, latitude) in degrees of local east/north metres (arrays)."""
        lon, lat = self._proj.transform(np.asarray(east, dtype=float),
                                        np.asarray(north, dtype=float), direction='INVERSE')
        return np.asarray(lon), np.asarray(lat)

    def to_east_north(self, longitude: ArrayLike,
                      latitude: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Local (east, north) metres of WGS 84 longitudes/latitudes in degrees (arrays)."""
        east, north = self._proj.transform(np.asarray(longitude, dtype=float),
                                           np.asarray(latitude, dtype=float))
        return np.asarray(east), np.asarray(north)


def geodesic_distance(lon1: ArrayLike, lat1: ArrayLike, lon2: ArrayLike,
                      lat2: ArrayLike) -> FloatArray:
    """Distance (m) on the WGS 84 ellipsoid between points in degrees (arrays)."""
    from pyproj import Geod  # lazy: pyproj costs 60 ms (see LocalFrame)
    _, _, dist = Geod(ellps='WGS84').inv(lon1, lat1, lon2, lat2)
    return np.asarray(dist)


def on_machine(x: Floats, y: Floats, heading: Floats, forward: Floats,
               left: Floats) -> tuple[Floats, Floats]:
    """A point of the machine (`forward`, `left` in its frame) in the frame where the machine's
    reference point is at (x, y) with `heading` (rad, counter-clockwise from the +x axis)."""
    c, s = np.cos(heading), np.sin(heading)
    return x + c * forward - s * left, y + s * forward + c * left
