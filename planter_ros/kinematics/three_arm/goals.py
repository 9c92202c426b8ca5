"""The eight design goals of paper 2 (§4.1), each a number with bounds, a unit and pass/fail.

Definitions where the paper gives only a name (also in doc/design.md):

1. arm_clearance (m, ≥ arm_width): the smallest distance between the centre lines O3→D of any
   two arms over one carrier turn. Two arm shells of width `arm_width` touch when it falls
   below that width.
2. picking_angle (rad, −5°…15°): angle of the pusher axis (the seedling clamp) below the
   horizontal at the picking point, the highest point of the tip's trajectory in the frame
   (the seedling tray is above the mechanism). Positive = tip pointing down, regardless of
   whether it points forward or backward.
3. pushing_angle (rad, 45°…65°): the same angle at the planting point, the lowest point of
   the trajectory (the tip is at planting depth there).
4. angle_difference (rad, 50°…60°): pushing_angle − picking_angle.
5. seedling_push (m, ≤ 0.01): at the planting point the arm body (tip → planet centre O3) lies
   on one side of the seedling. From then until the tip is higher than the seedling's top
   (ground + seedling_height), with the machine advancing 3·d per carrier turn, any ground-frame
   travel of the tip towards the other side drags the arm through the planted stem. The value
   is the largest such travel; up to half a pot (10 mm; the paper's tray pitch is 20 mm) is
   tolerated as the clamp leaving the pot.
6. gearbox_clearance (m, ≥ 0.02): lowest point of the rotating gearbox above the ground over a
   turn. The gearbox is taken as the gear tip circles: sun and planets max ρ, intermediates
   a − min ρ, each plus one addendum of the smallest allowed module (2.5 mm); the housing wall
   is not modelled. The ground is `planting_depth` above the planting point.
7. trajectory_height (m, ≥ 0.26): vertical extent (highest − lowest point) of the tip's
   trajectory in the frame.
8. gear_module (m, ≥ 0.0025): the largest module whose teeth fit the pitch curves without
   undercut: a rack (α = 20°, addendum 1·m) undercuts where the pitch curve's radius of
   curvature is below m / sin²α, so m ≤ min |R| sin²α over sun (= planet) and intermediate
   curves (a concave stretch needs the same radius for the shaping cutter); then rounded down
   so that the pitch-curve length is a whole number of teeth, L = π m z.
"""

from dataclasses import asdict, dataclass
import math

import numpy as np

from planter_ros.config import specs

from ..errors import DesignError
from ..scene_settings import SceneSettings, ThreeArmSettings
from .gear_train import ARMS, ThreeArmMechanism
from .pitch_curve import TWO_PI, polar_curvature_radius

DEG = math.pi / 180.0
PRESSURE_ANGLE = 20.0 * DEG
ADDENDUM = 1.0
MIN_MODULE = 0.0025

# name: (lower, upper, unit, scale used by the optimiser to weigh a violation)
BOUNDS = {
    'arm_clearance': (None, None, 'm', 0.01),        # lower = arm_width from the scene
    'picking_angle': (-5.0 * DEG, 15.0 * DEG, 'rad', 5.0 * DEG),
    'pushing_angle': (45.0 * DEG, 65.0 * DEG, 'rad', 5.0 * DEG),
    'angle_difference': (50.0 * DEG, 60.0 * DEG, 'rad', 5.0 * DEG),
    'seedling_push': (None, 0.01, 'm', 0.01),
    'gearbox_clearance': (0.02, None, 'm', 0.01),
    'trajectory_height': (0.26, None, 'm', 0.02),
    'gear_module': (MIN_MODULE, None, 'm', 0.0005),
}
GOAL_NAMES = tuple(BOUNDS)

# scene parameters the goals need, with the scene's defaults for the ones a scene leaves out
GOAL_DEFAULTS = {spec.name: spec.default for cls in (SceneSettings, ThreeArmSettings)
                 for spec in specs(cls)
                 if spec.name in ('plant_spacing', 'planting_depth', 'seedling_height',
                                  'arm_width')}


@dataclass
class Goal:
    name: str
    value: float
    lower: float | None
    upper: float | None
    unit: str
    passed: bool

    def violation(self, margin=0.0):
        """Distance outside [lower + margin, upper − margin] over the goal's scale (0 inside)."""
        scale = BOUNDS[self.name][3]
        v = 0.0
        if self.lower is not None:
            v = max(v, self.lower + margin * scale - self.value)
        if self.upper is not None:
            v = max(v, self.value - (self.upper - margin * scale))
        return v / scale


def goal_settings(params):
    """The goal-related scene values (SI), checked, with defaults for the missing ones."""
    out = {}
    for key, default in GOAL_DEFAULTS.items():
        value = params.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                not math.isfinite(value) or value <= 0:
            raise DesignError(key, value, 'finite and > 0 m')
        out[key] = float(value)
    return out


def _refine_extreme(theta, values, i):
    """Parabolic refinement of a sampled extreme at index i on a periodic uniform grid."""
    n = len(values)
    y0, y1, y2 = values[(i - 1) % n], values[i], values[(i + 1) % n]
    den = y0 - 2.0 * y1 + y2
    step = theta[1] - theta[0]
    shift = 0.0 if den == 0 else 0.5 * (y0 - y2) / den
    return theta[i] + max(-1.0, min(1.0, shift)) * step


def _below_horizontal(angle):
    return -np.arctan2(np.sin(angle), np.abs(np.cos(angle)))


def _segment_distance(p1, q1, p2, q2):
    """Smallest distance between segments p1q1 and p2q2 (arrays of shape (2, n))."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.sum(d1 * d1, axis=0)
    e = np.sum(d2 * d2, axis=0)
    f = np.sum(d2 * r, axis=0)
    c = np.sum(d1 * r, axis=0)
    b = np.sum(d1 * d2, axis=0)
    den = a * e - b * b
    with np.errstate(divide='ignore', invalid='ignore'):
        s = np.where(den > 1e-18 * a * e, np.clip((b * f - c * e) / den, 0.0, 1.0), 0.0)
        t = (b * s + f) / e
        t = np.clip(t, 0.0, 1.0)
        s = np.clip((b * t - c) / a, 0.0, 1.0)
    diff = p1 + d1 * s - (p2 + d2 * t)
    return np.sqrt(np.sum(diff * diff, axis=0))


def gear_module_limit(mech, samples=2048):
    """(undercut-free module, pitch-curve length, min |curvature radius|) for the train."""
    curve, a = mech.train.curve, mech.a
    u = np.r_[np.linspace(0.0, TWO_PI, samples, endpoint=False), curve.pieces]
    r, r1, r2 = curve(u), curve(u, 1), curve(u, 2)
    sun = polar_curvature_radius(r, r1, r2)
    # intermediate: R = a − ρ as a function of its own polar angle ψ, dψ/dθ = ρ/(a−ρ)
    q = a - r
    q1 = -r1 * q / r
    q2 = (-r2 * q / r + r1 * r1 * a / (r * r)) * q / r
    inter = polar_curvature_radius(q, q1, q2)
    rmin = float(np.min(np.abs(np.r_[sun, inter])))
    length = curve.length()
    m_undercut = rmin * math.sin(PRESSURE_ANGLE) ** 2 / ADDENDUM
    if not m_undercut > 0:
        return 0.0, length, rmin
    teeth = math.ceil(length / (math.pi * m_undercut) - 1e-9)
    return length / (math.pi * teeth), length, rmin


def evaluate_goals(mech, params=None, samples=720):
    """The eight goals for a built mechanism; params gives the scene values (defaults if None)."""
    cfg = goal_settings(params or {})
    theta, tips, _ = mech.cycle(samples)
    y = tips[:, 1, :]
    goals = {}

    # 1. non-interference between arms
    o3x, o3y = [], []
    for k in range(ARMS):
        _, (cx, cy) = mech.centres(theta, k)
        o3x.append(cx)
        o3y.append(cy)
    clearance = np.inf
    for j in range(ARMS):
        k = (j + 1) % ARMS
        dist = _segment_distance(np.stack([o3x[j], o3y[j]]), tips[j],
                                 np.stack([o3x[k], o3y[k]]), tips[k])
        clearance = min(clearance, float(dist.min()))
    goals['arm_clearance'] = clearance

    # 2-4. attitude at picking (highest) and planting (lowest) points of arm I
    th_pick = _refine_extreme(theta, -y[0], int(np.argmax(y[0])))
    th_plant = _refine_extreme(theta, y[0], int(np.argmin(y[0])))
    pick = float(_below_horizontal(mech.pusher_attitude(th_pick)))
    push = float(_below_horizontal(mech.pusher_attitude(th_plant)))
    goals['picking_angle'] = pick
    goals['pushing_angle'] = push
    goals['angle_difference'] = push - pick

    # 7. trajectory height, and the ground line for 5 and 6
    y_top = float(mech.tip(th_pick)[1])
    y_low = float(mech.tip(th_plant)[1])
    goals['trajectory_height'] = y_top - y_low
    ground = y_low + cfg['planting_depth']

    # 5. seedling push: ground frame, from planting until the tip clears the seedling top
    window = th_plant + theta
    gx, gy = mech.tip_ground(window, cfg['plant_spacing'])
    above = np.nonzero(gy > ground + cfg['seedling_height'])[0]
    end = max(int(above[0]) if above.size else len(window), 1)
    _, (o3x_p, _) = mech.centres(th_plant)
    side = 1.0 if float(o3x_p) >= float(mech.tip(th_plant)[0]) else -1.0  # arm body's side
    goals['seedling_push'] = float(np.max(side * (gx[0] - gx[:end])))

    # 6. gearbox above ground
    rho_max, rho_min = mech.train.curve.rho_max, mech.train.curve.rho_min
    lowest = -(rho_max + MIN_MODULE)
    for k in range(ARMS):
        (ix, iy), _ = mech.centres(theta, k)
        lowest = min(lowest, float(iy.min()) - (mech.a - rho_min + MIN_MODULE),
                     float(o3y[k].min()) - (rho_max + MIN_MODULE))
    goals['gearbox_clearance'] = lowest - ground

    # 8. gear module from curvature and a whole number of teeth
    goals['gear_module'] = gear_module_limit(mech)[0]

    out = []
    for name in GOAL_NAMES:
        lower, upper, unit, _ = BOUNDS[name]
        if name == 'arm_clearance':
            lower = cfg['arm_width']
        value = goals[name]
        if not math.isfinite(value):
            raise DesignError(name, value, 'a finite goal value', 'degenerate mechanism')
        passed = (lower is None or value >= lower) and (upper is None or value <= upper)
        out.append(Goal(name, value, lower, upper, unit, bool(passed)))
    return out


def design_summary(params, mech=None, goals=None):
    """JSON-ready design of a three-arm scene (SI units) for the `design` topic and the CLI."""
    mech = mech or ThreeArmMechanism.from_parameters(params)
    goals = goals if goals is not None else evaluate_goals(mech, params)
    cfg = goal_settings(params)
    summary = {
        'mechanism': 'three_arm',
        'plants_per_revolution': ARMS,
        'plant_spacing': cfg['plant_spacing'],
        'planting_depth': cfg['planting_depth'],
        'centre_distance': mech.a,
        'closure_residual': mech.train.closure.residual,
        'closure_method': mech.train.closure.method,
        'interpolant': mech.train.curve.interpolant,
        'pitch_radius_range': [mech.train.curve.rho_min, mech.train.curve.rho_max],
        'goals': [asdict(g) for g in goals],
        'goals_passed': sum(g.passed for g in goals),
        'all_goals_passed': all(g.passed for g in goals),
    }
    speed = params.get('nominal_ground_speed')
    if isinstance(speed, (int, float)) and not isinstance(speed, bool) and speed > 0:
        summary['nominal_ground_speed'] = float(speed)
        summary['carrier_speed'] = TWO_PI * float(speed) / (ARMS * cfg['plant_spacing'])
    return summary
