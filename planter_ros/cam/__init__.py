"""Electronic cam for the geared five-bar: the sun-bar angle as a function of the row's
travelled distance, θ(s), shaped within each plant so one mechanism plants every spacing with
the hole it was designed for (doc/cam.md).

Pure numpy/scipy, no ROS: `mechanism` (the tip in the soil, the in-soil laws, sweep and tilt),
`drive` (the servo, gearbox and load; limits and load figures), `arc` (the out-of-soil arc, a
linear programme), `plan` (a plant's profile, planning within the limits, the fallback and the
top speeds), `track` (one row's cam across run-time spacing changes), `piecewise` (the cheap
evaluation).
"""

from .drive import DRIVE_SOURCE, DriveLimits, LoadFigures, sun_bar_motion
from .errors import CamError, CamInputError, CamLimitError, CamPlanningError
from .mechanism import RULES, CamMechanism, SoilLaw, constant_law, rule_law
from .plan import (CamPlan, CamProfile, CamSpec, build_profile, constant_profile, plan_cam,
                   rule_top_speed, sampled_tip_sweep)
from .track import CamTrack

__all__ = ['CamError', 'CamInputError', 'CamLimitError', 'CamPlanningError', 'CamMechanism',
           'SoilLaw', 'RULES', 'rule_law', 'constant_law', 'DriveLimits', 'DRIVE_SOURCE',
           'LoadFigures', 'CamSpec', 'CamProfile', 'CamPlan', 'plan_cam', 'build_profile',
           'constant_profile', 'rule_top_speed', 'sampled_tip_sweep', 'CamTrack', 'sun_bar_motion']
