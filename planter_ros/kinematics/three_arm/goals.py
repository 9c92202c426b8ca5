"""The eight design goals of paper 2 (§4.1), each a number with bounds, a unit and pass/fail.

Definitions where the paper gives only a name (also in doc/design.md):

1. arm_clearance (m, ≥ arm_width): the smallest distance between the centre lines O3→D of any
   two arms over one carrier turn. Two arm shells of width `arm_width` touch when it falls
   below that width.
2. picking_angle (rad, −5°…15°): angle of the pusher axis (the seedling clamp) below the
   horizontal at the picking point: by default the highest point of the tip's trajectory in
   the frame (the seedling tray is above the mechanism), or arm I at the scene's
   `picking_phase`. Positive = tip pointing down, regardless of whether it points forward or
   backward.
3. pushing_angle (rad, 45°…65°): the same angle at the planting point: by default the lowest
   point of the trajectory, or arm I at the scene's `planting_phase`. The tip is at planting
   depth there, so the planting point also fixes the ground line of goals 5 and 6.
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

Provenance (`BASIS`): the paper fixes goals 2, 3, 4, 7 and 8 (their bounds need nothing but the
mechanism); goals 1, 5 and 6 need values the paper never gives (arm width; plant spacing,
seedling height, planting depth and a tolerance; planting depth and an addendum), so they rest
on our assumptions, which each goal reports. Goal 5 also reports the zero-slip plant spacing:
the spacing at which the ground moves under the tip at the tip's own speed at planting.

The goal arithmetic is written once for one design and for a batch: every array carries the
mechanism's `batch_shape` in front (see gear_train.ThreeArmMechanism and batch.MechanismBatch).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planter_ros.config import specs

from ..arrays import FloatArray, Floats
from ..errors import DesignError
from ..scene_settings import SceneSettings, ThreeArmSettings
from .gear_train import ARMS, ThreeArmMechanism
from .pitch_curve import TWO_PI, polar_curvature_radius

DEG = math.pi / 180.0
PRESSURE_ANGLE = 20.0 * DEG
ADDENDUM = 1.0
MIN_MODULE = 0.0025
MODULE_SAMPLES = 2048       # per turn, where the pitch curves' curvature is checked (goal 8)
PUSH_TOLERANCE = 0.01       # m, goal 5's upper bound

# name: (lower, upper, unit, scale used by the optimiser to weigh a violation)
BOUNDS = {
    'arm_clearance': (None, None, 'm', 0.01),        # lower = arm_width from the scene
    'picking_angle': (-5.0 * DEG, 15.0 * DEG, 'rad', 5.0 * DEG),
    'pushing_angle': (45.0 * DEG, 65.0 * DEG, 'rad', 5.0 * DEG),
    'angle_difference': (50.0 * DEG, 60.0 * DEG, 'rad', 5.0 * DEG),
    'seedling_push': (None, PUSH_TOLERANCE, 'm', 0.01),
    'gearbox_clearance': (0.02, None, 'm', 0.01),
    'trajectory_height': (0.26, None, 'm', 0.02),
    'gear_module': (MIN_MODULE, None, 'm', 0.0005),
}
GOAL_NAMES = tuple(BOUNDS)

# paper: the paper states the goal and its bound, nothing else is needed; assumption: the goal
# needs values the paper never gives (listed per goal by `assumed_values`)
BASIS = {'arm_clearance': 'assumption', 'picking_angle': 'paper', 'pushing_angle': 'paper',
         'angle_difference': 'paper', 'seedling_push': 'assumption',
         'gearbox_clearance': 'assumption', 'trajectory_height': 'paper', 'gear_module': 'paper'}

# scene parameters the goals need, with the scene's defaults for the ones a scene leaves out
_POSITIVE = ('plant_spacing', 'planting_depth', 'seedling_height', 'arm_width')
_PHASES = ('picking_phase', 'planting_phase')
GOAL_SPECS = {spec.name: spec for cls in (SceneSettings, ThreeArmSettings) for spec in specs(cls)
              if spec.name in _POSITIVE + _PHASES}
GOAL_DEFAULTS = {name: spec.default for name, spec in GOAL_SPECS.items()}


@dataclass
class Goal:
    name: str
    value: float
    lower: float | None
    upper: float | None
    unit: str
    passed: bool
    basis: str = ''                                  # 'paper' or 'assumption' (BASIS)
    # the assumed values it rests on, figures computed alongside (SI)
    assumed: dict[str, float] = field(default_factory=dict)
    derived: dict[str, float] = field(default_factory=dict)

    def violation(self, margin: float = 0.0) -> float:
        """Distance outside [lower + margin, upper − margin] over the goal's scale (0 inside)."""
        return float(violation(self.name, self.value, self.lower, self.upper, margin))


def violation(name: str, value: Floats, lower: float | None, upper: float | None,
              margin: float = 0.0) -> Floats:
    """Distance of value(s) outside [lower + margin·scale, upper − margin·scale], over the
    goal's scale; 0 inside (arrays welcome)."""
    scale = BOUNDS[name][3]
    v = np.zeros_like(np.asarray(value, dtype=float))
    if lower is not None:
        v = np.maximum(v, lower + margin * scale - value)
    if upper is not None:
        v = np.maximum(v, value - (upper - margin * scale))
    return v / scale


def goal_bounds(cfg: Mapping[str, float]) -> dict[str, tuple[float | None, float | None, str]]:
    """name -> (lower, upper, unit) for the scene values `cfg` (arm_width is goal 1's bound)."""
    out: dict[str, tuple[float | None, float | None, str]] = {}
    for name, (lower, upper, unit, _) in BOUNDS.items():
        out[name] = (cfg['arm_width'] if name == 'arm_clearance' else lower, upper, unit)
    return out


def assumed_values(name: str, cfg: Mapping[str, float]) -> dict[str, float]:
    """The values goal `name` rests on that the paper does not give (SI), by name."""
    if name == 'arm_clearance':
        return {'arm_width': cfg['arm_width']}
    if name == 'seedling_push':
        return {'plant_spacing': cfg['plant_spacing'], 'seedling_height': cfg['seedling_height'],
                'planting_depth': cfg['planting_depth'], 'tolerance': PUSH_TOLERANCE}
    if name == 'gearbox_clearance':
        return {'planting_depth': cfg['planting_depth'], 'addendum': MIN_MODULE * ADDENDUM}
    return {}


def goal_settings(params: Mapping[str, object]) -> dict[str, float]:
    """The goal-related scene values (SI), checked, with defaults for the missing ones."""
    out: dict[str, float] = {}
    for key, default in GOAL_DEFAULTS.items():
        value = params.get(key, default)
        spec = GOAL_SPECS[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                not math.isfinite(value):
            raise DesignError(key, value, spec.allowed())
        if key in _POSITIVE and value <= 0:
            raise DesignError(key, value, 'finite and > 0 m')
        if key in _PHASES and not ((spec.low is None or spec.low <= value)
                                   and (spec.high is None or value <= spec.high)):
            raise DesignError(key, value, spec.allowed())
        out[key] = float(value)
    return out


Indices = NDArray[np.intp]


def _take(values: FloatArray, index: Indices) -> FloatArray:
    """values[..., index] for an index array of the leading shape (periodic)."""
    n = values.shape[-1]
    taken: FloatArray = np.take_along_axis(values, (np.asarray(index) % n)[..., None],
                                           axis=-1)[..., 0]
    return taken


def _refine_extreme(theta: FloatArray, values: FloatArray, i: Indices) -> Floats:
    """Parabolic refinement of a sampled extreme at index i on a periodic uniform grid."""
    y0, y1, y2 = _take(values, i - 1), _take(values, i), _take(values, i + 1)
    den = y0 - 2.0 * y1 + y2
    step = theta[1] - theta[0]
    with np.errstate(divide='ignore', invalid='ignore'):
        shift = np.where(den == 0, 0.0, 0.5 * (y0 - y2) / np.where(den == 0, 1.0, den))
    refined: Floats = theta[i] + np.clip(shift, -1.0, 1.0) * step
    return refined


def _below_horizontal(angle: Floats) -> Floats:
    below: Floats = -np.arctan2(np.sin(angle), np.abs(np.cos(angle)))
    return below


def _segment_distance(p1: FloatArray, q1: FloatArray, p2: FloatArray,
                      q2: FloatArray) -> FloatArray:
    """Smallest distance between segments p1q1 and p2q2 (arrays of shape (2, ...))."""
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
    distance: FloatArray = np.sqrt(np.sum(diff * diff, axis=0))
    return distance


def gear_module_limit(mech: ThreeArmMechanism,
                      samples: int = MODULE_SAMPLES) -> tuple[Floats, Floats, Floats]:
    """(undercut-free module, pitch-curve length, min |curvature radius|) for the train
    (arrays of the mechanism's batch_shape)."""
    curve, a = mech.train.curve, _per_design(mech, mech.a)[..., None]
    u = np.r_[np.linspace(0.0, TWO_PI, samples, endpoint=False), curve.pieces]
    r, r1, r2 = curve(u), curve(u, 1), curve(u, 2)
    sun = polar_curvature_radius(r, r1, r2)
    # intermediate: R = a − ρ as a function of its own polar angle ψ, dψ/dθ = ρ/(a−ρ)
    q = a - r
    q1 = -r1 * q / r
    q2 = (-r2 * q / r + r1 * r1 * a / (r * r)) * q / r
    inter = polar_curvature_radius(q, q1, q2)
    rmin = np.minimum(np.min(np.abs(sun), axis=-1), np.min(np.abs(inter), axis=-1))
    length = curve.length()
    m_undercut = rmin * math.sin(PRESSURE_ANGLE) ** 2 / ADDENDUM
    ok = m_undercut > 0
    with np.errstate(divide='ignore', invalid='ignore'):
        teeth = np.ceil(length / (math.pi * np.where(ok, m_undercut, 1.0)) - 1e-9)
        module = np.where(ok, length / (math.pi * teeth), 0.0)
    if mech.batch_shape == ():
        return float(module), float(length), float(rmin)
    return module, length, rmin


def _per_design(mech: ThreeArmMechanism, value: Floats) -> FloatArray:
    """A per-design value (float, or (P, 1) in a batch) in the batch's shape."""
    return np.reshape(np.asarray(value, dtype=float), mech.batch_shape)


def _extremes(theta: FloatArray, y: FloatArray) -> tuple[Floats, Floats]:
    """Carrier angles of the highest and lowest samples of y (..., n), refined."""
    return (_refine_extreme(theta, -y, np.argmax(y, axis=-1)),
            _refine_extreme(theta, y, np.argmin(y, axis=-1)))


def _at(mech: ThreeArmMechanism, fn: Callable[[FloatArray, int], Floats], theta: ArrayLike,
        arm: int = 0) -> FloatArray:
    """fn(θ, arm) at one carrier angle per design (θ of batch_shape)."""
    out = np.asarray(fn(np.asarray(theta, dtype=float)[..., None], arm))
    return out[..., 0]


def _at_pair(mech: ThreeArmMechanism, fn: Callable[[FloatArray, int], tuple[Floats, Floats]],
             theta: ArrayLike, arm: int = 0) -> tuple[FloatArray, FloatArray]:
    """_at for a function of (x, y)."""
    x, y = fn(np.asarray(theta, dtype=float)[..., None], arm)
    return np.asarray(x)[..., 0], np.asarray(y)[..., 0]


def _phases(theta: FloatArray, y: FloatArray, cfg: Mapping[str, float],
            shape: tuple[int, ...]) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """(picking, planting, highest, lowest) carrier angles of arm I: the scene's phases where
    given, else the highest and lowest tip points (refined from the samples y; one design's are
    0-d arrays)."""
    high, low = (np.asarray(v) for v in _extremes(theta, y))
    pick = high if cfg['picking_phase'] < 0 else np.full(shape, cfg['picking_phase'])
    plant = low if cfg['planting_phase'] < 0 else np.full(shape, cfg['planting_phase'])
    return pick, plant, high, low


def goal_values(mech: ThreeArmMechanism, cfg: Mapping[str, float],
                samples: int = 720) -> dict[str, Floats]:
    """The eight goal values, name -> array of the mechanism's batch_shape, plus the phases
    used ('picking_phase', 'planting_phase') and the zero-slip plant spacing."""
    theta, tips, _ = mech.cycle(samples)
    y = tips[..., 0, 1, :]
    out: dict[str, Floats] = {}

    centres = [mech.centres(theta, k) for k in range(ARMS)]

    # 1. non-interference between arms
    o3 = [np.stack(c[1]) for c in centres]
    ends = [np.moveaxis(tips[..., k, :, :], -2, 0) for k in range(ARMS)]
    clearance: Floats = np.inf
    for j in range(ARMS):
        k = (j + 1) % ARMS
        dist = _segment_distance(o3[j], ends[j], o3[k], ends[k])
        clearance = np.minimum(clearance, dist.min(axis=-1))
    out['arm_clearance'] = clearance

    # 2-4. attitude at picking and planting (arm I)
    th_pick, th_plant, th_high, th_low = _phases(theta, y, cfg, mech.batch_shape)
    pick = _below_horizontal(_at(mech, mech.pusher_attitude, th_pick))
    push = _below_horizontal(_at(mech, mech.pusher_attitude, th_plant))
    out['picking_angle'] = pick
    out['pushing_angle'] = push
    out['angle_difference'] = push - pick

    # 7. trajectory height; the ground is planting_depth above the planting point (5 and 6)
    y_top = _at_pair(mech, mech.tip, th_high)[1]
    y_low = _at_pair(mech, mech.tip, th_low)[1]
    tip_x, tip_y = _at_pair(mech, mech.tip, th_plant)
    ground = tip_y + cfg['planting_depth']

    # 5. seedling push: ground frame, from planting until the tip clears the seedling top
    window = th_plant[..., None] + theta
    gx, gy = (np.asarray(v) for v in mech.tip_ground(window, cfg['plant_spacing']))
    above = gy > (ground + cfg['seedling_height'])[..., None]
    end = np.maximum(np.where(above.any(axis=-1), np.argmax(above, axis=-1), len(theta)), 1)
    o3x = _at(mech, lambda t, arm: mech.centres(t, arm)[1][0], th_plant)
    side = np.where(o3x >= tip_x, 1.0, -1.0)                  # the arm body's side
    travel = side[..., None] * (gx[..., :1] - gx)
    out['seedling_push'] = np.max(np.where(np.arange(len(theta)) < end[..., None], travel,
                                           -np.inf), axis=-1)

    # 6. gearbox above ground
    a = _per_design(mech, mech.a)
    rho_max, rho_min = mech.train.curve.rho_max, mech.train.curve.rho_min
    lowest = -(rho_max + MIN_MODULE)
    for (_, iy), (_, py) in centres:
        lowest = np.minimum(lowest, np.minimum(np.min(iy, axis=-1) - (a - rho_min + MIN_MODULE),
                                               np.min(py, axis=-1) - (rho_max + MIN_MODULE)))
    out['gearbox_clearance'] = lowest - ground
    out['trajectory_height'] = y_top - y_low

    # 8. gear module from curvature and a whole number of teeth
    out['gear_module'] = np.asarray(gear_module_limit(mech)[0], dtype=float)

    # the plant spacing at which the ground keeps pace with the tip at planting
    # (ground-frame dx/dθ = tip dx/dθ + 3d/2π = 0)
    out['zero_slip_spacing'] = -TWO_PI / ARMS * _at_pair(mech, mech.tip_velocity, th_plant)[0]
    out['picking_phase'] = np.mod(th_pick, TWO_PI)
    out['planting_phase'] = np.mod(th_plant, TWO_PI)
    return out


def evaluate_goals(mech: ThreeArmMechanism, params: Mapping[str, object] | None = None,
                   samples: int = 720) -> list[Goal]:
    """The eight goals for a built mechanism; params gives the scene values (defaults if None)."""
    cfg = goal_settings(params or {})
    return goals_from_values(goal_values(mech, cfg, samples), cfg)


def goals_from_values(values: Mapping[str, Floats], cfg: Mapping[str, float]) -> list[Goal]:
    """Goal records (one design) from goal_values' output."""
    out: list[Goal] = []
    for name, (lower, upper, unit) in goal_bounds(cfg).items():
        value = float(values[name])
        if not math.isfinite(value):
            raise DesignError(name, value, 'a finite goal value', 'degenerate mechanism')
        passed = (lower is None or value >= lower) and (upper is None or value <= upper)
        derived = {'zero_slip_spacing': float(values['zero_slip_spacing'])} \
            if name == 'seedling_push' else {}
        out.append(Goal(name, value, lower, upper, unit, bool(passed), BASIS[name],
                        assumed_values(name, cfg), derived))
    return out


def goal_counts(goals: list[Goal]) -> dict[str, tuple[int, int]]:
    """{'paper': (passed, of), 'assumption': (passed, of)} by provenance."""
    out: dict[str, tuple[int, int]] = {}
    for basis in ('paper', 'assumption'):
        mine = [g for g in goals if g.basis == basis]
        out[basis] = (sum(g.passed for g in mine), len(mine))
    return out


def design_summary(params: Mapping[str, object], mech: ThreeArmMechanism | None = None,
                   goals: list[Goal] | None = None) -> dict[str, object]:
    """JSON-ready design of a three-arm scene (SI units) for the `design` topic and the CLI."""
    mech = mech or ThreeArmMechanism.from_parameters(params)
    cfg = goal_settings(params)
    values = goal_values(mech, cfg)
    goals = goals if goals is not None else goals_from_values(values, cfg)
    counts = goal_counts(goals)
    summary: dict[str, object] = {
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
        'paper_goals_passed': counts['paper'][0],
        'paper_goals': counts['paper'][1],
        'assumption_goals_passed': counts['assumption'][0],
        'assumption_goals': counts['assumption'][1],
        'picking_phase': float(values['picking_phase']),
        'planting_phase': float(values['planting_phase']),
        'phases_from': {name: 'scene' if cfg[name] >= 0 else 'tip extremes'
                        for name in _PHASES},
        'zero_slip_spacing': float(values['zero_slip_spacing']),
    }
    speed = params.get('nominal_ground_speed')
    if isinstance(speed, (int, float)) and not isinstance(speed, bool) and speed > 0:
        summary['nominal_ground_speed'] = float(speed)
        summary['carrier_speed'] = TWO_PI * float(speed) / (ARMS * cfg['plant_spacing'])
    return summary
