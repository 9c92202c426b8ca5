"""A scene's parameters -> the design JSON the design node publishes (pure, no ROS).

One dispatcher from `mechanism` to the mechanism's own model. The five-bar path imports only
the five-bar core; the three-arm model (gear train, splines) is imported only for a three-arm
scene. A design the machine cannot run (the passive dyad does not assemble) is refused like an
infeasible one, so a node never publishes it.
"""

import math

from planter_ros.interfaces import PLANTS_PER_REVOLUTION

from .errors import DesignError, require_positive_finite

MECHANISMS = tuple(PLANTS_PER_REVOLUTION)


def design_for_scene(params):
    """Return the JSON-ready design dict (SI) for a flat scene parameter dict.

    Keys always present: mechanism, plants_per_revolution, plant_spacing (m), planting_depth
    (m), crop, nominal_ground_speed (m/s), nominal_mechanism_speed (rad/s), then the model's
    own fields. Raises DesignError (one line) for a bad or infeasible scene.
    """
    mechanism = params.get('mechanism', 'five_bar')
    if mechanism not in MECHANISMS:
        raise DesignError('mechanism', mechanism, ' or '.join(MECHANISMS))
    spacing = _number(params, 'plant_spacing')
    speed = _number(params, 'nominal_ground_speed')
    require_positive_finite('nominal_ground_speed', speed, 'm/s')
    if mechanism == 'five_bar':
        out = _five_bar(params, spacing)
    else:
        out = _three_arm(params)
    n = PLANTS_PER_REVOLUTION[mechanism]
    out.update(mechanism=mechanism, plants_per_revolution=n, plant_spacing=spacing,
               planting_depth=_number(params, 'planting_depth'),
               crop=str(params.get('crop', '')), nominal_ground_speed=speed,
               nominal_mechanism_speed=2.0 * math.pi * speed / (n * spacing))
    return out


def _number(params, name):
    value = params.get(name)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise DesignError(name, value, 'a number')
    return float(value)


def _five_bar(params, spacing):
    from .five_bar import PAPER_DYAD_RATIOS, design_five_bar
    ratios = params.get('dyad_ratios', PAPER_DYAD_RATIOS)
    if isinstance(ratios, (str, bytes)) or not hasattr(ratios, '__len__'):
        raise DesignError('dyad_ratios', ratios, 'three ratios (l3, l4, l5)/(l1+l2)')
    design = design_five_bar(_number(params, 'planting_depth'), spacing,
                             _number(params, 'hole_ratio'),
                             str(params.get('design_method', 'exact')),
                             tuple(float(r) for r in ratios))
    if not design.assemblable:
        raise DesignError('dyad_ratios', list(ratios), 'ratios whose passive dyad assembles '
                          'over the whole cycle', 'the dyad does not close for this design')
    return design.as_dict()


TIP_PATH_SAMPLES = 360     # one per degree of carrier angle, like the paper's own tables


def _three_arm(params):
    import numpy as np

    from . import three_arm
    mech = three_arm.ThreeArmMechanism.from_parameters(params)
    out = three_arm.design_summary(params, mech)
    # what the monitor needs to predict each plant: arm I's tip over one carrier turn (frame,
    # x forward, y up); arms II and III follow the same path 2π/3 and 4π/3 later
    angle = np.linspace(0.0, 2.0 * math.pi, TIP_PATH_SAMPLES, endpoint=False)
    x, y = mech.tip(angle, 0)
    out['tip_path'] = {'angle': angle.tolist(), 'x': np.asarray(x).tolist(),
                       'y': np.asarray(y).tolist()}
    return out
