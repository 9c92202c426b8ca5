"""Three-arm non-circular planetary gear planting mechanism for rice (paper 2).

Stable API for the nodes, the monitor and the command line (pure numpy/scipy, SI units):

    from planter_ros.kinematics.three_arm import ThreeArmMechanism, design_summary
    mech = ThreeArmMechanism.from_parameters(params)   # builds spline, closure, gear maps once
    x, y = mech.tip(theta, arm=0)          # tip in the frame (m); theta = carrier angle (rad)
    alpha = mech.attitude(theta, arm=0)    # arm line angle (rad, counter-clockwise from +x)
    mech.pusher_attitude(theta, arm)       # pusher axis angle (rad)
    mech.tip_relative(theta, arm)          # tip in the carrier frame
    mech.tip_ground(theta, spacing, arm)   # tip relative to the ground (3 plants per turn)
    theta, tips, alphas = mech.cycle(n)    # one revolution of all three arms, vectorised
    design_summary(params, mech)           # JSON-ready dict for the `design` topic

`params` is a scene dict (config/rice_three_arm.yaml via planter_ros.scene.load_scene).
Bad input raises planter_ros.kinematics.errors.DesignError with a one-line message.
"""

from .gear_train import ARMS, PARAMETER_NAMES, GearTrain, Installation, ThreeArmMechanism
from .goals import Goal, design_summary, evaluate_goals
from .pitch_curve import INTERPOLANTS, PitchCurve, solve_centre_distance

__all__ = ['ARMS', 'INTERPOLANTS', 'PARAMETER_NAMES', 'GearTrain', 'Goal', 'Installation',
           'PitchCurve', 'ThreeArmMechanism', 'design_summary', 'evaluate_goals',
           'solve_centre_distance']
