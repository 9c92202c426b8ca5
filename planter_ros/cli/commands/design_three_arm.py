"""`planter design three-arm`: run (the options: cli/design_three_arm.py)."""

import json
import sys

from planter_ros.cli.main import BadInput
from planter_ros.config import ConfigError, from_mapping
from planter_ros.design.text import three_arm_table
from planter_ros.kinematics.design_inputs import DesignInputs, ThreeArmInputs
from planter_ros.kinematics.three_arm import ThreeArmMechanism, design_summary
from planter_ros.kinematics.three_arm.paper import paper_comparison
from planter_ros.output_files import atomic_output, require_finite
from planter_ros.scene import open_scene


def load_params(path, option='--params'):
    """The design node's parameters of a three-arm scene, the whole scene checked strictly
    (planter_ros.scene: every key and value); BadInput for anything else."""
    scene = open_scene(path)
    for warning in scene.warnings:                 # defaults taken, unusual values
        print(f'planter: warning: {warning}', file=sys.stderr)
    params = scene.parameters('design_node')
    mechanism = params.get('mechanism')
    if mechanism != 'three_arm':
        raise BadInput(f'{option} {path}: mechanism = {mechanism} is out of range: allowed '
                       'three_arm')
    try:
        for cls in (DesignInputs, ThreeArmInputs):
            from_mapping(cls, params)
        scene.antenna()
    except ConfigError as exc:
        raise BadInput(f'{option} {path}: {exc}') from None
    return params


def run(args):
    params = load_params(args.params)
    mech = ThreeArmMechanism.from_parameters(params)
    result = require_finite(design_summary(params, mech), 'three-arm design')
    result['params'] = str(args.params)
    result['paper_comparison'] = paper_comparison(mech)
    if args.plot:
        # lazy: the plot's module only with --plot (matplotlib, an extra: dependencies)
        from planter_ros.plots.three_arm import plot_design
        with atomic_output(args.plot) as tmp:
            plot_design(mech, params, tmp)
        result['plot'] = args.plot
    print(json.dumps(result, indent=2, allow_nan=False) if args.json else three_arm_table(result))
    return 0
