"""Cam planning: one plant's θ(s), periodic in the spacing, within the drive's limits.

A period runs from the soil entry of one plant to the next plant's: the in-soil arc follows a
`SoilLaw` (θ = π at the planting instant, ±ψ at the soil edges), the out-of-soil arc is planned
by `arc.plan_arc` to meet the next entry with θ, θ′ and θ″ continuous (C2) and θ advanced by
2π per spacing. `plan_cam` plans the chosen rule at the top ground speed; where the limits
cannot be met it returns the feasible profile closest to the rule: a blend β of the rule's
in-soil law with the next law of its fallback chain (exact zero slip → the design-speed rule →
constant speed), β maximised under the limits, and reports which limit binds and up to what
ground speed each rule (exact zero slip, the design-speed rule) holds at this spacing.
"""

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field, replace
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from planter_ros.config import coerce, spec_of
from planter_ros.kinematics.arrays import FloatArray
from planter_ros.kinematics.design_inputs import DesignInputs
from planter_ros.kinematics.five_bar import TWO_PI, soil_trajectory

from .arc import ARC_PIECES, ArcEnds, plan_arc, straight_arc
from .drive import DriveLimits, LoadFigures, LoadSamples
from .errors import CamInputError, CamPlanningError
from .mechanism import RULES, BarsAndDepth, CamMechanism, SoilLaw, constant_law, rule_law
from .piecewise import Piecewise, State

__all__ = ['CamSpec', 'CamProfile', 'CamPlan', 'plan_cam', 'constant_profile', 'build_profile',
           'shared_builds', 'fallback_laws', 'rule_top_speed', 'rule_top_speeds',
           'sampled_tip_sweep', 'BRUTE_FORCE_SAMPLES', 'BLEND_HEADROOM', 'BLEND_STEPS',
           'SPEED_RANGE']

BLEND_STEPS = 14                 # bisection steps of β: resolution 2⁻¹⁴
# a blend is planned to this share of its binding limit, not to the limit itself: a change
# into it at run time (another spacing or rule: a transition arc) then has room to stay
# within the limits too
BLEND_HEADROOM = 0.98
SPEED_RANGE = (0.01, 3.0)        # ground speeds searched for a rule's top speed, m/s (scene's)
SOIL_TOLERANCE = 1e-12           # rad: the in-soil fit's largest error against its law
_MAX_SOIL_PIECES = 4096


# --- the in-soil arc -------------------------------------------------------------------------

def _phi_of_distance(law: SoilLaw, mech: CamMechanism, u: float, phi0: float) -> float:
    """Invert s(φ) = u by Newton's method from φ0 (s is increasing over the arc)."""
    phi = phi0
    for _ in range(50):
        s1 = law.derivatives(mech, phi)[0]
        step = (law.distance(mech, phi) - u) / s1
        phi -= step
        if abs(step) <= 1e-16 * max(1.0, abs(phi)):
            break
    return phi


def quintic_hermite(x: ArrayLike, states: ArrayLike) -> FloatArray:
    """Power-basis coefficients of the C2 quintic through (θ, θ′, θ″) at each x: per piece,
    c0..c2 from the left end, c3..c5 solved from the right end's deltas (so each break is met
    to round-off of θ″ itself, not of the large higher coefficients)."""
    x = np.asarray(x, dtype=np.float64)
    st = np.asarray(states, dtype=np.float64)
    h = np.diff(x)
    y0, d0, a0 = st[:-1, 0], st[:-1, 1], st[:-1, 2]
    y1, d1, a1 = st[1:, 0], st[1:, 1], st[1:, 2]
    e0 = y1 - (y0 + d0 * h + 0.5 * a0 * h * h)
    e1 = (d1 - (d0 + a0 * h)) * h
    e2 = (a1 - a0) * h * h
    c3 = (10.0 * e0 - 4.0 * e1 + 0.5 * e2) / h ** 3
    c4 = (-15.0 * e0 + 7.0 * e1 - e2) / h ** 4
    c5 = (6.0 * e0 - 3.0 * e1 + 0.5 * e2) / h ** 5
    return np.column_stack([y0, d0, 0.5 * a0, c3, c4, c5])


def soil_arc(mech: CamMechanism, law: SoilLaw) -> Piecewise:
    """The in-soil arc θ(r) as a Piecewise, r from the soil entry (0) to the exit.

    Linear laws are one exact piece; others are quintic Hermite pieces through the exact θ, θ′,
    θ″ at breaks equally spaced in φ, doubled until the fit is within SOIL_TOLERANCE."""
    psi = mech.psi
    u_in = law.half_length(mech)
    if law.zero_slip == 0.0:
        rate = 1.0 / law.advance
        return Piecewise([0.0, 2.0 * u_in], [[math.pi - psi, rate]])
    pieces = 8
    while True:
        phi = np.linspace(-psi, psi, pieces + 1)
        u = np.array([law.distance(mech, p) for p in phi.tolist()])
        states = [[math.pi + p, *law.angle_derivatives(mech, p)[:2]] for p in phi.tolist()]
        fit = Piecewise(u + u_in, quintic_hermite(u, states))
        mid_u = 0.5 * (u[:-1] + u[1:])
        mid_phi = [_phi_of_distance(law, mech, m, 0.5 * (p0 + p1))
                   for m, p0, p1 in zip(mid_u.tolist(), phi[:-1].tolist(), phi[1:].tolist())]
        err = max(abs(fit.at(m + u_in)[0] - (math.pi + p))
                  for m, p in zip(mid_u.tolist(), mid_phi))
        if err <= SOIL_TOLERANCE:
            return fit
        if pieces >= _MAX_SOIL_PIECES:
            raise CamInputError('depth', mech.depth, f'clear of l1 + l2 = {mech.total:.6g} m '
                                f'for {law.name}', f'{pieces} pieces fit the in-soil law only '
                                f'to {err:.1e} rad')
        pieces *= 2


# --- a profile -------------------------------------------------------------------------------

@dataclass(frozen=True)
class CamSpec:
    """What a row's cam is planned for: the mechanism, the plant spacing (m), the top ground
    speed (m/s), the drive and its limits, and the rule ('design_speed', 'zero_slip', or
    'constant' for constant speed)."""

    mech: CamMechanism
    spacing: float
    speed: float
    drive: DriveLimits = field(default_factory=DriveLimits)
    rule: str = 'design_speed'


class CamProfile:
    """θ(s) of a row: plant k at s = k·spacing with θ = π + 2πk; periodic in the spacing.

    `evaluate(s)` gives (θ, θ′, θ″) in rad, rad/m, rad/m² for a scalar s (m) in a few µs:
    floats only, one bisect and Horner's rule. `period` is one plant's θ(r), r from its soil
    entry (r = 0, s = −entry) to the next plant's entry (r = spacing); `law` its in-soil law,
    `blend` β of it: 1 = the rule's law, 0 = constant speed."""

    def __init__(self, spec: CamSpec, law: SoilLaw, period: Piecewise, blend: float) -> None:
        self.spec = spec
        self.mech = spec.mech
        self.law = law
        self.spacing = float(spec.spacing)
        self.period = period
        self.entry = law.half_length(spec.mech)   # from the soil entry to the planting instant
        self.speed = spec.speed                   # ground speed it was planned for (m/s)
        self.drive = spec.drive
        self.rule = spec.rule                     # 'constant', 'design_speed' or 'zero_slip'
        self.blend = blend                        # β: 1 = the rule's law, 0 = constant speed
        self._samples: LoadSamples | None = None
        self._fingerprint: str | None = None      # cam.track.fingerprint's, once computed

    def evaluate(self, s: float) -> State:
        """(θ, θ′, θ″) at travelled distance s (m), θ unwrapped."""
        d = self.spacing
        w = s + self.entry
        k = math.floor(w / d)
        r = w - k * d
        if r >= d:                    # w / d rounded up to a whole number
            r -= d
            k += 1
        th, d1, d2 = self.period.at(r)
        return th + TWO_PI * k, d1, d2

    def values(self, s: ArrayLike, order: int = 0) -> FloatArray:
        """θ (order 0) or its derivative (1..3) at an array of s (numpy)."""
        w = np.asarray(s, dtype=np.float64) + self.entry
        k = np.floor(w / self.spacing)
        r = w - k * self.spacing
        out = self.period.values(r, order)
        return out + TWO_PI * k if order == 0 else out

    def edge_state(self, side: float) -> State:
        """(θ, θ′, θ″) of plant 0's soil exit (side +1, s = exit) or entry (side −1)."""
        r = self.period.end if side < 0 else 2.0 * self.entry
        th, d1, d2 = self.period.at(r)
        return th - (TWO_PI if side < 0 else 0.0), d1, d2

    @property
    def loads(self) -> LoadSamples:
        """The dense samples the load figures come from (computed once)."""
        if self._samples is None:
            self._samples = LoadSamples(self.period, self.spacing, self.mech, self.drive)
        return self._samples

    def figures(self, speed: float) -> LoadFigures:
        """Peak loads and utilisations at a steady ground speed (m/s)."""
        return self.loads.figures(float(speed))

    @property
    def tip_sweep(self) -> float:
        return self.law.tip_sweep(self.mech)

    @property
    def hole_width(self) -> float:
        return self.law.hole_width(self.mech)

    @property
    def tilt(self) -> float:
        return self.law.tilt(self.mech)


def _check_spacing_speed(spacing: float, speed: float) -> None:
    """Spacing and speed in the scene's ranges (the same as the command line's)."""
    for value, scene_name, name in ((spacing, 'plant_spacing', 'spacing'),
                                    (speed, 'nominal_ground_speed', 'speed')):
        spec = spec_of(DesignInputs, scene_name)
        try:
            coerce(spec, float(value))
        except (TypeError, ValueError):         # ValueError: a ConfigError too
            raise CamInputError(name, value, spec.allowed()) from None


# the profiles built inside a `shared_builds` block: (spec, law, blend, pieces) -> profile
_BUILT: ContextVar[dict[tuple[CamSpec, SoilLaw, float, int], CamProfile] | None] = \
    ContextVar('cam_profiles_built', default=None)


@contextmanager
def shared_builds() -> Iterator[None]:
    """Within the block (this thread), `build_profile` builds each profile once: the same spec,
    law, blend and pieces give the same profile, so a second call returns the first one's.
    For a command that plans the same profiles more than once (`planter cam`: the study, then
    its plot's grid and feasibility map); not process-wide, so a timing of the planner
    (`planter bench`) or a node planning at run time always plans afresh."""
    token = _BUILT.set({})
    try:
        yield
    finally:
        _BUILT.reset(token)


def build_profile(spec: CamSpec, law: SoilLaw, blend: float,
                  pieces: int = ARC_PIECES) -> CamProfile:
    """The profile of `law` (β = `blend` of the rule's) in the soil and an out-of-soil arc
    planned for `spec` (module doc); inside `shared_builds`, built once per arguments."""
    built = _BUILT.get()
    if built is None:
        return _build_profile(spec, law, blend, pieces)
    key = (spec, law, float(blend), int(pieces))
    profile = built.get(key)
    if profile is None:
        profile = built[key] = _build_profile(spec, law, blend, pieces)
    return profile


def _build_profile(spec: CamSpec, law: SoilLaw, blend: float, pieces: int) -> CamProfile:
    mech, spacing, drive = spec.mech, spec.spacing, spec.drive
    half = law.half_length(mech)
    length = spacing - 2.0 * half
    if not length > 1e-6 * spacing:
        raise CamInputError('spacing', spacing, f'> {2 * half:.6g} m (the in-soil arc of '
                            f'{law.name} for this mechanism)')
    soil = soil_arc(mech, law)
    start = law.edge_state(mech, +1)
    end_th, end_d1, end_d2 = law.edge_state(mech, -1)
    end = (end_th + TWO_PI, end_d1, end_d2)
    ends = ArcEnds(length, start, end)
    arc = straight_arc(ends)
    if arc is None:
        limits = drive.effective(mech)
        arc, _ = plan_arc(ends, spec.speed, limits, lambda th: drive.torque_terms(mech, th),
                          pieces)
    period = Piecewise.join([soil, arc.shifted(2.0 * half)])
    return CamProfile(spec, law, period, blend)


def constant_profile(mech: CamMechanism, spacing: float,
                     drive: DriveLimits | None = None) -> CamProfile:
    """Constant sun-bar speed 2π/d (today's machine), as a profile."""
    drive = DriveLimits() if drive is None else drive
    return build_profile(CamSpec(mech, spacing, 0.0, drive, 'constant'), constant_law(spacing),
                         0.0)


# --- planning --------------------------------------------------------------------------------

@dataclass(frozen=True)
class CamPlan:
    """A planned cam and its report (SI)."""

    profile: CamProfile            # the profile to run (the rule, or its feasible blend)
    rule: str
    spacing: float
    speed: float                   # top ground speed it was planned for
    blend: float                   # β of the profile's law: 1 = `blend_of`, 0 = `blended_with`
    blend_of: str                  # the law blended (the rule, or a fallback), by name
    blended_with: str              # the law it is blended with ('' when β = 1: the rule itself)
    figures: LoadFigures           # the profile's loads at `speed`
    # the rule's own (β = 1) loads at `speed`; None: its out-of-soil arc cannot be planned
    # within the drive's limits at all (the rule does not run)
    rule_figures: LoadFigures | None
    top_speeds: dict[str, tuple[float, str]]  # rule -> (m/s, limit that stops it) here

    @property
    def feasible(self) -> bool:
        return self.figures.feasible

    @property
    def exact(self) -> bool:
        """The rule itself runs (no fallback)."""
        return not self.blended_with

    @property
    def rule_runs(self) -> bool:
        """The rule's own profile is within every limit."""
        return self.rule_figures is not None and self.rule_figures.feasible

    @property
    def rule_exceeds(self) -> list[str]:
        """The limits the rule's own profile exceeds (['out-of-soil arc']: not plannable)."""
        return ['out-of-soil arc'] if self.rule_figures is None else self.rule_figures.exceeded

    @property
    def rule_loads(self) -> dict[str, Any] | None:
        return None if self.rule_figures is None else self.rule_figures.as_dict()

    @property
    def binding(self) -> str:
        """Which limit binds: the rule's most exceeded limit, else the profile's closest."""
        if self.rule_figures is not None and not self.rule_figures.feasible:
            return self.rule_figures.binding
        return self.figures.binding

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (SI)."""
        p = self.profile
        return {'rule': self.rule, 'spacing': self.spacing, 'ground_speed': self.speed,
                'law': p.law.name, 'blend': self.blend, 'blend_of': self.blend_of,
                'blended_with': self.blended_with or None,
                'tip_sweep': p.tip_sweep, 'hole_width': p.hole_width, 'tilt': p.tilt,
                'feasible': self.feasible, 'binding': self.binding,
                'rule_exceeds': self.rule_exceeds,
                'loads': self.figures.as_dict(), 'rule_loads': self.rule_loads,
                'top_speeds': {k: {'ground_speed': v, 'limit': why}
                               for k, (v, why) in self.top_speeds.items()}}


def fallback_laws(mech: CamMechanism, spacing: float, rule: str) -> list[SoilLaw]:
    """The laws tried, in order, when the rule cannot run: from exact zero slip first towards
    the design-speed rule (the design hole, no tilt), then towards constant speed."""
    laws = [rule_law(mech, rule)]
    if rule == 'zero_slip':
        laws.append(rule_law(mech, 'design_speed'))
    laws.append(constant_law(spacing))
    return laws


def plan_cam(mech: CamMechanism | BarsAndDepth, spacing: float, speed: float,
             drive: DriveLimits | None = None, rule: str = 'design_speed',
             top_speeds: bool = True) -> CamPlan:
    """Plan the cam for `mech` (a CamMechanism, or a five-bar design) at plant spacing
    `spacing` (m) and top ground speed `speed` (m/s) within `drive`'s limits (module doc).

    When the rule's profile exceeds a limit, the laws of `fallback_laws` are tried in turn;
    the first that runs is blended with the one before it, β (the share of the one before)
    maximised by bisection with every limit's utilisation ≤ BLEND_HEADROOM: the feasible
    profile closest to the rule that leaves a run-time change into it room. If not even
    constant speed runs, that is returned, infeasible, with its figures. `top_speeds`: also
    find up to what ground speed each rule holds at this spacing (a few more plans)."""
    if not isinstance(mech, CamMechanism):
        mech = CamMechanism.from_design(mech)
    drive = DriveLimits() if drive is None else drive
    _check_spacing_speed(spacing, speed)
    spacing, speed = float(spacing), float(speed)
    spec = CamSpec(mech, spacing, speed, drive, rule)
    laws = fallback_laws(mech, spacing, rule)

    def build(law: SoilLaw, beta: float) -> tuple[CamProfile, LoadFigures] | None:
        """The law's profile and its figures; None when its out-of-soil arc cannot be planned
        at all (limits so far below the motion that the programme fails): that law does not
        run."""
        try:
            candidate = build_profile(spec, law, beta)
        except CamPlanningError:
            return None
        return candidate, candidate.figures(speed)

    chosen = build(laws[0], 1.0)
    rule_figures = None if chosen is None else chosen[1]
    beta, blend_of, blended_with = 1.0, laws[0].name, ''
    if rule_figures is None or not rule_figures.feasible:
        for upper, lower in zip(laws, laws[1:]):
            low = build(lower, 0.0)
            if low is None:
                continue
            chosen, beta, blend_of, blended_with = low, 0.0, upper.name, lower.name
            if not low[1].feasible:
                continue
            lo, hi = 0.0, 1.0
            for _ in range(BLEND_STEPS):
                mid = 0.5 * (lo + hi)
                candidate = build(upper.blend(lower, mid), mid)
                if candidate is not None and \
                        max(candidate[1].utilisation.values()) <= BLEND_HEADROOM:
                    lo, chosen, beta = mid, candidate, mid
                else:
                    hi = mid
            break
    if chosen is None:      # the chain ends at constant speed, whose arc is a straight line
        raise CamPlanningError(f'no law of the {rule} fallback chain could be planned at '
                               f'{spacing:.6g} m')
    profile, figures = chosen
    tops = rule_top_speeds(mech, spacing, drive, speed) if top_speeds else {}
    return CamPlan(profile, rule, spacing, speed, beta, blend_of, blended_with, figures,
                   rule_figures, tops)


def rule_top_speeds(mech: CamMechanism, spacing: float, drive: DriveLimits | None = None,
                    hint: float = 0.3, pieces: int = ARC_PIECES) -> dict[str, tuple[float, str]]:
    """Up to what ground speed each rule, and constant speed, holds at this spacing:
    {'zero_slip' | 'design_speed' | 'constant': (m/s, the limit that stops it)}."""
    drive = DriveLimits() if drive is None else drive
    tops: dict[str, tuple[float, str]] = {}
    for name in RULES:
        try:
            tops[name] = rule_top_speed(mech, spacing, name, drive, hint, pieces)
        except CamInputError as exc:             # zero slip undefined for this depth
            tops[name] = (0.0, f'undefined here: {exc}')
        except CamPlanningError as exc:          # limits far below the motion
            tops[name] = (0.0, f'not planned: {exc}')
    tops['constant'] = constant_profile(mech, spacing, drive).loads.top_speed()
    return tops


def rule_top_speed(mech: CamMechanism, spacing: float, rule: str, drive: DriveLimits,
                   hint: float = 0.3, pieces: int = ARC_PIECES) -> tuple[float, str]:
    """Up to what steady ground speed the rule's full profile (β = 1), planned for that speed,
    stays within every limit at this spacing: (m/s, the limit that stops it). Searched over
    SPEED_RANGE; the top of the range if it holds there.

    Fixed point: plan at v, find the fixed profile's own top speed v* (closed form per
    limit), plan again at v*; a few rounds, then a bisection guard keeps the answer feasible."""
    law = rule_law(mech, rule)
    spec = CamSpec(mech, spacing, hint, drive, rule)

    def profile_at(v: float) -> CamProfile:
        return build_profile(replace(spec, speed=v), law, 1.0, pieces)

    lo_v, hi_v = SPEED_RANGE
    v = min(max(hint, lo_v), hi_v)
    best, why = 0.0, 'speed'
    tried = set()
    for _ in range(8):
        profile = profile_at(v)
        top, limit = profile.loads.top_speed()
        if profile.figures(v).feasible:
            best = max(best, v)
        if top >= hi_v and profile.figures(hi_v).feasible:
            return hi_v, 'none within the searched range'
        why = limit
        nxt = min(max(top, lo_v), hi_v)
        key = round(nxt, 9)
        if abs(nxt - v) <= 1e-4 * v or key in tried:
            v = nxt
            break
        tried.add(key)
        v = nxt
    profile = profile_at(v)
    if profile.figures(v).feasible:
        return v, why
    # guard: bisect between the best feasible speed seen and v
    lo, hi = best, v
    for _ in range(12):
        mid = 0.5 * (lo + hi)
        if mid < lo_v:
            break
        f = profile_at(mid).figures(mid)
        if f.feasible:
            lo = mid
        else:
            hi, why = mid, f.binding
    return lo, why



BRUTE_FORCE_SAMPLES = 1_000_000


def sampled_tip_sweep(profile: CamProfile, samples: int = BRUTE_FORCE_SAMPLES) -> float:
    """The tip sweep found by brute force, independently of the closed form: θ(s) through
    scipy's PPoly of the profile's coefficients at `samples` equally spaced distances over one
    revolution (one spacing, from plant 0's soil entry), the tip from the five-bar's soil
    trajectory, the extent along the row of the samples in the soil (y ≤ D). It misses each
    soil edge by less than one step, an error of at most max|dx/ds|·d/samples."""
    mech = profile.mech
    r = np.linspace(0.0, profile.spacing, int(samples), endpoint=False)
    theta = profile.period.to_scipy()(r)
    x, y = soil_trajectory(mech.l1, mech.l2, theta, 0.0)
    x = x + r
    inside = x[y <= mech.depth]
    return float(inside.max() - inside.min()) if inside.size else 0.0
