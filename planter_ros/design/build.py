"""A scene's parameters -> its typed design (pure, no ROS): the one place a design is built.

One dispatcher from `mechanism` to the mechanism's own model. The five-bar path imports only
the five-bar core; the three-arm model (gear train, splines) is imported only for a three-arm
scene. A design the machine cannot run (the passive dyad does not assemble) is refused like an
infeasible one, so a node never publishes it. The values are checked against the scene's
ranges (kinematics.design_inputs) before any model runs.
"""

import math
from typing import Any, Mapping

import numpy as np

from planter_ros.config import as_dict, from_mapping
from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.five_bar import design_five_bar
from planter_ros.kinematics.mechanisms import PLANTS_PER_REVOLUTION
from planter_ros.kinematics.design_inputs import (DesignInputs, ThreeArmInputs,
                                                   top_ground_speed)

from .message import from_dict
from .model import Design

__all__ = ['TIP_PATH_SAMPLES', 'design_for_scene']

TIP_PATH_SAMPLES = 360     # one per degree of carrier angle, like the paper's own tables


def design_for_scene(params: Mapping[str, Any]) -> Design:
    """The design (SI) of a flat scene parameter dict.

    Values the scene leaves out take their defaults (design_inputs). Raises DesignError (one
    line) for a value out of range or an infeasible design.
    """
    scene = from_mapping(DesignInputs, params, DesignError.from_message)
    if scene.mechanism == 'five_bar':
        out = _five_bar(scene)
    else:
        arm = from_mapping(ThreeArmInputs, params, DesignError.from_message)
        out = _three_arm({**as_dict(scene), **as_dict(arm)})
    n = PLANTS_PER_REVOLUTION[scene.mechanism]
    out.update(mechanism=scene.mechanism, plants_per_revolution=n,
               plant_spacing=scene.plant_spacing, planting_depth=scene.planting_depth,
               crop=scene.crop, nominal_ground_speed=scene.nominal_ground_speed,
               top_ground_speed=top_ground_speed(scene.nominal_ground_speed,
                                                 scene.top_ground_speed),
               nominal_mechanism_speed=2.0 * math.pi * scene.nominal_ground_speed
               / (n * scene.plant_spacing), nozzle_width=scene.nozzle_width)
    return from_dict(out)


def _five_bar(scene: DesignInputs) -> dict[str, Any]:
    if len(scene.dyad_ratios) != 3:
        raise DesignError('dyad_ratios', scene.dyad_ratios, 'three ratios (l3, l4, l5)/(l1+l2)')
    built_for = scene.design_spacing or scene.plant_spacing
    design = design_five_bar(scene.planting_depth, built_for, scene.hole_ratio,
                             scene.design_method, tuple(scene.dyad_ratios))
    if not design.assemblable:
        raise DesignError('dyad_ratios', list(scene.dyad_ratios), 'ratios whose passive dyad '
                          'assembles over the whole cycle', 'the dyad does not close for this '
                          'design')
    return design.as_dict()


def _three_arm(params: dict[str, Any]) -> dict[str, Any]:
    # lazy: a five-bar scene never loads the gear train (17 ms, its scipy on use;
    # test_design_node's test_five_bar_scene_never_imports_the_gear_train)
    from planter_ros.kinematics import three_arm
    mech = three_arm.ThreeArmMechanism.from_parameters(params)
    out = three_arm.design_summary(params, mech)
    # what the monitor needs to predict each plant: arm I's tip over one carrier turn (frame,
    # x forward, y up); arms II and III follow the same path 2π/3 and 4π/3 later
    angle = np.linspace(0.0, 2.0 * math.pi, TIP_PATH_SAMPLES, endpoint=False)
    x, y = mech.tip(angle, 0)
    out['tip_path'] = {'angle': angle.tolist(), 'x': np.asarray(x).tolist(),
                       'y': np.asarray(y).tolist()}
    return out
