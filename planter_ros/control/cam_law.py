"""The electronic cam in the sync law (`speed_profile: cam`, doc/cam.md): plan a row's θ(s)
from a five-bar design and place it on the row where the row's grid is anchored.

`plan_row_cam` plans the profile with `planter_ros.cam.plan_cam` at the scene's top ground
speed (the design's `top_ground_speed`) and the default `DriveLimits` (a few ms to tens of ms:
callers run it off the control thread); a plan over the drive's limits even at constant
speed is refused (`CamLimitError`, the figure and the limit named), never handed on.
`plan_for_design` also plans and checks the change from the profile in force
(`cam.track.plan_transition`), so a change the drive cannot make is refused before it
reaches the command process, and the planned transition travels with the profile
(`profile_to_data`) so the command process need not plan it. `anchored_track` puts a profile
on the row as a `CamTrack` whose θ at the anchor distance is the measured angle there (no
jump when a grid starts); its plants are where θ = π (mod 2π), the five-bar's planting angle.
Pure: no ROS.
"""
from __future__ import annotations

from dataclasses import asdict
from functools import lru_cache
import math
from typing import Any

from planter_ros.cam import (
    CamError, CamInputError, CamLimitError, CamMechanism, CamProfile, CamSpec, CamTrack,
    DriveLimits, SoilLaw, plan_cam)
from planter_ros.cam.piecewise import Piecewise
from planter_ros.cam.track import Transition, fingerprint, plan_transition, remember_transition
from planter_ros.kinematics.design_inputs import top_ground_speed

__all__ = ['plan_row_cam', 'plan_for_design', 'anchored_track', 'profile_to_data',
           'profile_from_data', 'planning_speed', 'warm_up', 'DEFAULT_TOP_SPEED']

# top ground speed a cam is planned for when the design names no speed at all (m/s)
DEFAULT_TOP_SPEED = 0.3
_BISECTIONS = 80


def planning_speed(design: Any) -> float:
    """The ground speed (m/s) a design's cam is planned for: its top ground speed (the
    scene's `top_ground_speed`, or 1.5 × nominal: kinematics.design_inputs), or for a design
    that names none (an older recording) 1.5 × its nominal speed, or DEFAULT_TOP_SPEED."""
    top = getattr(design, 'top_ground_speed', None)
    if top:
        return float(top)
    nominal = getattr(design, 'nominal_ground_speed', None)
    return top_ground_speed(nominal) if nominal else DEFAULT_TOP_SPEED


@lru_cache(maxsize=64)
def _plan(mech: CamMechanism, spacing: float, speed: float, drive: DriveLimits,
          rule: str) -> Any:
    """plan_cam, kept: a scene's spacings are planned again and again (its schedule, each
    rule change back, the scene's check and the shell's own plan)."""
    return plan_cam(mech, spacing, speed, drive, rule, top_speeds=False)


def plan_row_cam(design: Any, rule: str, top_speed: float | None = None,
                 drive: DriveLimits | None = None) -> CamProfile:
    """θ(s) for a five-bar `design` (l1, l2, planting depth, plant spacing) under `rule`
    (design_speed | zero_slip) at `top_speed` (m/s; default `planning_speed(design)`) within
    `drive` (default DriveLimits()): the rule's profile, or the feasible one closest to it
    (`plan_cam`). ValueError for a design the cam cannot run (not a five-bar); CamLimitError
    when not even constant speed keeps within the drive's limits at that speed."""
    if getattr(design, 'mechanism', None) != 'five_bar':
        raise ValueError(f'speed_profile = cam needs a five-bar design, got '
                         f'{getattr(design, "mechanism", None)}')
    speed = top_speed or planning_speed(design)
    mech = CamMechanism(design.l1, design.l2, design.planting_depth)
    built = mech.design_spacing
    try:
        plan = _plan(mech, float(design.plant_spacing), float(speed), drive or DriveLimits(),
                     rule)
    except CamInputError as exc:
        if exc.parameter != 'spacing':
            raise
        raise CamInputError('plant_spacing', design.plant_spacing, f'{exc.allowed} for a '
                            f'five-bar built for {built:.4g} m (design_spacing): a smaller '
                            'design_spacing, or a larger plant_spacing') from None
    if not plan.feasible:
        raise CamLimitError.from_message(
            f'speed_profile = cam cannot plant plant_spacing = {design.plant_spacing:.4g} m '
            f'with a five-bar built for {built:.4g} m (design_spacing) at top_ground_speed = '
            f'{speed:.3g} m/s: {plan.figures.over_text()} even at constant speed, the cam\'s '
            'last fallback: allowed a lower top_ground_speed, a larger plant_spacing or a '
            'drive with more reserve')
    profile: CamProfile = plan.profile
    return profile


def anchored_track(profile: CamProfile, theta: float, s: float) -> CamTrack:
    """A track of `profile` whose θ at the row's distance `s` (m) is `theta` (rad): the profile
    shifted along s (θ(s) is non-decreasing and gains 2π per plant, so one shift does it)."""
    d = profile.spacing
    k = math.floor((theta - math.pi) / (2.0 * math.pi))
    lo, hi = k * d, (k + 1) * d                 # θ(lo) = π + 2πk ≤ theta < θ(hi)
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if profile.evaluate(mid)[0] <= theta:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-12 * d:
            break
    return CamTrack(profile, origin=s - lo)


def profile_to_data(profile: CamProfile,
                    previous: CamProfile | None = None) -> dict[str, Any]:
    """A planned profile as JSON-ready data (the shell plans, the command process runs it);
    with `previous`, the planned transition from it (if one was planned) travels along."""

    period = profile.period
    data: dict[str, Any] = {'mech': asdict(profile.mech), 'law': asdict(profile.law),
            'spacing': profile.spacing, 'speed': profile.speed, 'drive': asdict(profile.drive),
            'rule': profile.rule, 'blend': profile.blend,
            'breaks': period.breaks.tolist(), 'coeffs': period.coeffs.tolist(),
            'fingerprint': fingerprint(profile)}
    if previous is not None:
        data['transition'] = plan_transition(previous, profile).as_data()
    return data


def profile_from_data(data: dict[str, Any]) -> CamProfile:
    """The profile `profile_to_data` gave (ValueError/TypeError/KeyError if it is not one);
    a transition that came with it is kept for `CamTrack.change` (cam.track)."""
    spec = CamSpec(CamMechanism(**data['mech']), float(data['spacing']), float(data['speed']),
                   DriveLimits(**data['drive']), str(data['rule']))
    profile = CamProfile(spec, SoilLaw(**data['law']), Piecewise(data['breaks'], data['coeffs']),
                         float(data['blend']))
    if data.get('fingerprint') not in (None, fingerprint(profile)):
        raise ValueError('cam profile: its data do not match its fingerprint')
    if data.get('transition') is not None:
        transition = Transition.from_data(data['transition'])
        if transition.new == fingerprint(profile):
            remember_transition(transition)
    return profile


def plan_for_design(design: Any, rule: str,
                    previous: CamProfile | None = None) -> tuple[CamProfile | None, str]:
    """(profile, '') for a design the cam can run, (None, why: constant speed) for one it
    cannot (not a five-bar, zero slip undefined at this depth). CamLimitError (one line, the
    figure and the limit) when its plan, or the change from `previous` (the profile in force)
    to it, is over the drive's limits however it is spread: refused, the design not to be
    applied."""
    try:
        profile = plan_row_cam(design, rule)
    except CamLimitError:
        raise
    except (ValueError, CamError) as exc:
        return None, f'no cam for this design ({exc}): constant speed'
    if previous is not None:
        try:
            plan_transition(previous, profile)
        except CamLimitError:
            raise
        except CamInputError as exc:
            raise CamLimitError.from_message(f'the change to plant_spacing = '
                                             f'{profile.spacing:.4g} m cannot be made: {exc}') \
                from None
    return profile, ''


def warm_up() -> None:
    """Plan one cam and throw it away: the first plan of a process imports and sets up the
    linear-programme solver (about 0.4 s); later ones take tens of ms. Run at start-up, so a
    spacing changed at run time is planned at once."""
    mech = CamMechanism(0.0948, 0.1187, 0.045)
    plan_cam(mech, 0.3, DEFAULT_TOP_SPEED, DriveLimits(), 'design_speed', top_speeds=False)
