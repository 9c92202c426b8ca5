"""The electronic cam in the sync law (`speed_profile: cam`, doc/cam.md): plan a row's θ(s)
from a five-bar design and place it on the row where the row's grid is anchored.

`plan_row_cam` plans the profile with `planter_ros.cam.plan_cam` at the scene's top ground
speed and the default `DriveLimits` (a few ms to tens of ms: callers run it off the control
thread). `anchored_track` puts that profile on the row as a `CamTrack` whose θ at the anchor
distance is the measured angle there (no jump when a grid starts); its plants are where θ = π
(mod 2π), the five-bar's planting angle. Pure: no ROS.
"""
from __future__ import annotations

import math
from typing import Any

from planter_ros.cam import CamMechanism, CamProfile, CamTrack, DriveLimits, plan_cam

__all__ = ['plan_row_cam', 'plan_for_design', 'anchored_track', 'profile_to_data',
           'profile_from_data', 'warm_up', 'DEFAULT_TOP_SPEED']

# top ground speed a cam is planned for when the design names none (m/s)
DEFAULT_TOP_SPEED = 0.3
_BISECTIONS = 80


def plan_row_cam(design: Any, rule: str, top_speed: float | None = None) -> CamProfile:
    """θ(s) for a five-bar `design` (l1, l2, planting depth, plant spacing) under `rule`
    (design_speed | zero_slip) at `top_speed` (m/s; default the design's nominal ground speed):
    the rule's profile, or the feasible one closest to it (`plan_cam`)."""
    if getattr(design, 'mechanism', None) != 'five_bar':
        raise ValueError(f'speed_profile = cam needs a five-bar design, got '
                         f'{getattr(design, "mechanism", None)}')
    speed = top_speed or getattr(design, 'nominal_ground_speed', None) or DEFAULT_TOP_SPEED
    mech = CamMechanism(design.l1, design.l2, design.planting_depth)
    plan = plan_cam(mech, design.plant_spacing, speed, DriveLimits(), rule, top_speeds=False)
    return plan.profile


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


def profile_to_data(profile: CamProfile) -> dict:
    """A planned profile as JSON-ready data (the shell plans, the command process runs it)."""
    from dataclasses import asdict
    period = profile.period
    return {'mech': asdict(profile.mech), 'law': asdict(profile.law),
            'spacing': profile.spacing, 'speed': profile.speed, 'drive': asdict(profile.drive),
            'rule': profile.rule, 'blend': profile.blend,
            'breaks': period.breaks.tolist(), 'coeffs': period.coeffs.tolist()}


def profile_from_data(data: dict) -> CamProfile:
    """The profile `profile_to_data` gave (ValueError/TypeError/KeyError if it is not one)."""
    from planter_ros.cam import SoilLaw
    from planter_ros.cam.piecewise import Piecewise
    return CamProfile(CamMechanism(**data['mech']), SoilLaw(**data['law']),
                      float(data['spacing']), Piecewise(data['breaks'], data['coeffs']),
                      float(data['speed']), DriveLimits(**data['drive']), str(data['rule']),
                      float(data['blend']))


def plan_for_design(design: Any, rule: str) -> tuple[CamProfile | None, str]:
    """(profile, '') for a design the cam can run, else (None, why: constant speed)."""
    from planter_ros.cam import CamError
    try:
        return plan_row_cam(design, rule), ''
    except (ValueError, CamError) as exc:
        return None, f'no cam for this design ({exc}): constant speed'


def warm_up() -> None:
    """Plan one cam and throw it away: the first plan of a process imports and sets up the
    linear-programme solver (about 0.4 s); later ones take tens of ms. Run at start-up, so a
    spacing changed at run time is planned at once."""
    mech = CamMechanism(0.0948, 0.1187, 0.045)
    plan_cam(mech, 0.3, DEFAULT_TOP_SPEED, DriveLimits(), 'design_speed', top_speeds=False)
