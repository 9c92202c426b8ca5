"""The monitor's 3D view (Foxglove, RViz): visualization_msgs/MarkerArray of the planted plants
and of each row's nozzle tip path, in the `field` frame; and for map and plot views, each plant
as a NavSatFix (`plant_fixes`) and as a Vector3Stamped keyed by its row (`plant_rows`).

The `field` frame is the as-planted map's local frame (sensing.plant_map): x east, y north, z up,
metres, origin at the first usable GNSS fix, the soil surface at z = 0. Only plants with a map
position are drawn.

* A plant is a stem (LINE_LIST, two points): from its root ball at the planting depth below its
  map position, STEM_LENGTH long, leaning by its predicted tilt along the direction of travel
  (+ forward). Red: not upright. Upright: green for a spacing on d, shading to orange at half a
  spacing off (a multiple or a miss). Namespace `plants/<row>`, id = the row's plant count
  (never reused, so no plant replaces another); stamped at its planting instant; kept forever.
* The tip path (LINE_STRIP, namespace `tip_path/<row>`, id 0: each row's newest replaces its
  last): one nozzle tip over a whole shaft revolution relative to the soil, at the advance v/ω
  of the row's newest plant and through its root ball: the loop that cut the hole.
"""

import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Vector3Stamped
import numpy as np
from sensor_msgs.msg import NavSatFix, NavSatStatus
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

FRAME = 'field'
STEM_LENGTH = 0.2          # m drawn from the root ball: the seedling, for the eye only
STEM_WIDTH = 0.012         # m
PATH_WIDTH = 0.004         # m
PATH_SAMPLES = 121         # points of a tip path over one revolution

UPRIGHT = (0.15, 0.75, 0.2)
OFF_SPACING = (1.0, 0.6, 0.0)
FALLEN = (0.9, 0.1, 0.1)
PATH = (0.2, 0.4, 0.9)


def plant_colour(upright, spacing_error, spacing):
    """(r, g, b) of a plant: FALLEN if not upright, else UPRIGHT shading to OFF_SPACING as
    |spacing error| reaches half the design spacing (no spacing: UPRIGHT)."""
    if not upright:
        return FALLEN
    share = abs(spacing_error) / (0.5 * spacing) if math.isfinite(spacing_error) else 0.0
    share = min(max(share, 0.0), 1.0)
    return tuple(a + share * (b - a) for a, b in zip(UPRIGHT, OFF_SPACING))


def stem(east, north, heading, tilt, depth):
    """Root ball and top (x, y, z) of a stem in the field frame."""
    root = (east, north, -depth)
    along = STEM_LENGTH * math.sin(tilt)
    top = (east + along * math.cos(heading), north + along * math.sin(heading),
           -depth + STEM_LENGTH * math.cos(tilt))
    return root, top


def tip_path(model, east, north, heading, advance):
    """(n, 3) points of one tip over a revolution relative to the soil, through the root ball
    of a plant at (east, north) planted heading `heading` at advance v/ω (m/rad)."""
    phi = np.linspace(-math.pi, math.pi, PATH_SAMPLES)
    x, y = model.tip_path(phi)
    along = np.asarray(x) + (advance if math.isfinite(advance) else 0.0) * phi
    return np.column_stack((east + along * math.cos(heading), north + along * math.sin(heading),
                            np.asarray(y) - model.depth))


def marker_array(plants, placement, model, labels, counts):
    """MarkerArray of a batch of placed plants (prediction.Plants with its
    sensing.plant_map.Placement): a stem per plant with a map position, the tip path of each
    row at its newest one. `labels`: row index -> name; `counts`: row index -> plants drawn so
    far (updated)."""
    def header(marker, t):
        sec = math.floor(t)
        marker.header.frame_id = FRAME
        marker.header.stamp = Time(sec=int(sec), nanosec=min(int(round((t - sec) * 1e9)),
                                                               999_999_999))
        marker.pose.orientation.w = 1.0

    out = MarkerArray()
    newest = {}
    for i in np.flatnonzero(np.isfinite(placement.east)).tolist():
        row = int(plants.row[i])
        label = labels.get(row, f'row{row}')
        marker = Marker(ns=f'plants/{label}', id=counts.get(row, 0), type=Marker.LINE_LIST,
                        action=Marker.ADD)
        counts[row] = marker.id + 1
        header(marker, float(plants.time[i]))
        marker.scale.x = STEM_WIDTH
        r, g, b = plant_colour(plants.upright[i], float(plants.spacing_error[i]),
                               model.spacing)
        marker.color = ColorRGBA(r=r, g=g, b=b, a=1.0)
        tilt = float(plants.tilt[i])            # NaN in an input gap: drawn upright
        root, top = stem(float(placement.east[i]), float(placement.north[i]),
                         float(placement.heading[i]), tilt if math.isfinite(tilt) else 0.0,
                         model.depth)
        marker.points = [Point(x=root[0], y=root[1], z=root[2]),
                         Point(x=top[0], y=top[1], z=top[2])]
        out.markers.append(marker)
        newest[row] = i
    for row, i in newest.items():
        marker = Marker(ns=f'tip_path/{labels.get(row, f"row{row}")}', id=0,
                        type=Marker.LINE_STRIP, action=Marker.ADD)
        header(marker, float(plants.time[i]))
        marker.scale.x = PATH_WIDTH
        marker.color = ColorRGBA(r=PATH[0], g=PATH[1], b=PATH[2], a=0.8)
        advance = float(plants.ground_speed[i]) / float(plants.shaft_speed[i]) \
            if plants.shaft_speed[i] > 0 else math.nan
        points = tip_path(model, float(placement.east[i]), float(placement.north[i]),
                          float(placement.heading[i]), advance)
        marker.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in points]
        out.markers.append(marker)
    return out


def _stamp(t):
    sec = math.floor(t)
    return Time(sec=int(sec), nanosec=min(int(round((t - sec) * 1e9)), 999_999_999))


def plant_fixes(plants, placement, labels):
    """NavSatFix of each plant of a batch with a map position (interfaces.PLANT_FIXES)."""
    out = []
    for i in np.flatnonzero(np.isfinite(placement.latitude)).tolist():
        fix = NavSatFix(latitude=float(placement.latitude[i]),
                        longitude=float(placement.longitude[i]), altitude=math.nan,
                        position_covariance_type=NavSatFix.COVARIANCE_TYPE_UNKNOWN)
        fix.status.status = NavSatStatus.STATUS_FIX
        fix.header.stamp = _stamp(float(plants.time[i]))
        fix.header.frame_id = labels.get(int(plants.row[i]), '')
        out.append(fix)
    return out


def plant_rows(plants, labels):
    """Vector3Stamped of each plant of a batch, keyed by its row (interfaces.PLANT_ROWS)."""
    out = []
    for i in range(len(plants)):
        msg = Vector3Stamped()
        msg.header.stamp = _stamp(float(plants.time[i]))
        msg.header.frame_id = labels.get(int(plants.row[i]), '')
        msg.vector.x = float(plants.spacing_error[i])
        msg.vector.y = float(plants.speed_ratio[i])
        msg.vector.z = float(plants.tilt[i])
        out.append(msg)
    return out
