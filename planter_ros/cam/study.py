"""Constant speed and the cam side by side, per spacing and ground speed: the figures the
command line prints, the plot draws and the bench checks (SI, JSON-ready)."""

import time
from typing import Any

from .plan import (BRUTE_FORCE_SAMPLES, CamProfile, CamSpec, constant_profile, plan_cam,
                   sampled_tip_sweep)

__all__ = ['profile_summary', 'compare']


def profile_summary(profile: CamProfile, speed: float,
                    samples: int = BRUTE_FORCE_SAMPLES) -> dict[str, Any]:
    """Sweep, hole, tilt and loads of a profile at ground speed `speed`; with `samples` > 0
    also the brute-force sweep and its difference from the closed form (m)."""
    out: dict[str, Any] = {'law': profile.law.name, 'tip_sweep': profile.tip_sweep,
           'hole_width': profile.hole_width, 'tilt': profile.tilt,
           'loads': profile.figures(speed).as_dict()}
    if samples:
        t0 = time.perf_counter()
        sampled = sampled_tip_sweep(profile, samples)
        out['sweep_check'] = {'samples_per_revolution': int(samples), 'tip_sweep': sampled,
                              'error': abs(sampled - profile.tip_sweep),
                              'time': time.perf_counter() - t0}
    return out


def compare(spec: CamSpec, samples: int = BRUTE_FORCE_SAMPLES) -> dict[str, Any]:
    """Constant speed and the cam planned (and timed) for `spec`: its spacing and top ground
    speed, drive and rule."""
    spacing, speed, drive, rule = spec.spacing, spec.speed, spec.drive, spec.rule
    t0 = time.perf_counter()
    plan = plan_cam(spec.mech, spacing, speed, drive, rule, top_speeds=False)
    planned = time.perf_counter() - t0
    cam = profile_summary(plan.profile, speed, samples)
    cam.update({'rule': rule, 'blend': plan.blend, 'blend_of': plan.blend_of,
                'blended_with': plan.blended_with or None, 'feasible': plan.feasible,
                'binding': plan.binding, 'rule_exceeds': plan.rule_exceeds,
                'rule_loads': plan.rule_loads, 'plan_time': planned})
    constant = profile_summary(constant_profile(plan.profile.mech, spacing, drive), speed,
                               samples)
    constant['feasible'] = constant['loads']['feasible']
    return {'spacing': float(spacing), 'ground_speed': float(speed), 'constant': constant,
            'cam': cam}
