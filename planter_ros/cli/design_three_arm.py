"""`planter design three-arm --params FILE`: the eight goals of a three-arm scene."""

import json
import sys

from planter_ros.output_files import require_finite
from planter_ros.cli.options import output_file


def add_arguments(parser):
    parser.add_argument('--params', required=True, metavar='FILE',
                        help='ROS 2 parameter file of a three_arm scene, e.g. '
                             'config/rice_three_arm.yaml')
    parser.add_argument('--json', action='store_true', help='print JSON (SI units) for machines')
    parser.add_argument('--plot', metavar='FILE.png', type=output_file('--plot', ('.png',)),
                        help='draw pitch curves, trajectories and arm angles')


def load_params(path, option='--params'):
    """The design node's parameters of a three-arm scene, the whole scene checked strictly
    (planter_ros.scene: every key and value); BadInput for anything else."""
    from planter_ros.cli.main import BadInput
    from planter_ros.config import ConfigError, from_mapping
    from planter_ros.kinematics.scene_settings import SceneSettings, ThreeArmSettings
    from planter_ros.scene import open_scene
    scene = open_scene(path)
    for warning in scene.warnings:                 # defaults taken, unusual values
        print(f'planter: warning: {warning}', file=sys.stderr)
    params = scene.parameters('design_node')
    mechanism = params.get('mechanism')
    if mechanism != 'three_arm':
        raise BadInput(f'{option} {path}: mechanism = {mechanism} is out of range: allowed '
                       'three_arm')
    try:
        for cls in (SceneSettings, ThreeArmSettings):
            from_mapping(cls, params)
        scene.antenna()
    except ConfigError as exc:
        raise BadInput(f'{option} {path}: {exc}') from None
    return params


def run(args):
    from planter_ros.kinematics.three_arm import ThreeArmMechanism, design_summary
    from planter_ros.kinematics.three_arm.paper import paper_comparison
    from planter_ros.output_files import atomic_output

    params = load_params(args.params)
    mech = ThreeArmMechanism.from_parameters(params)
    result = require_finite(design_summary(params, mech), 'three-arm design')
    result['params'] = str(args.params)
    result['paper_comparison'] = paper_comparison(mech)
    if args.plot:
        from planter_ros.plots.three_arm import plot_design
        with atomic_output(args.plot) as tmp:
            plot_design(mech, params, tmp)
        result['plot'] = args.plot
    from planter_ros.design.text import three_arm_table
    print(json.dumps(result, indent=2, allow_nan=False) if args.json else three_arm_table(result))
    return 0
