"""`planter cam five-bar`: run (the options: cli/cam.py)."""

import json

from planter_ros.cam import CamMechanism, DriveLimits
from planter_ros.cam.plan import shared_builds
from planter_ros.cam.report import CamStudy, format_table, study
from planter_ros.kinematics.five_bar import design_five_bar
from planter_ros.output_files import atomic_output, require_finite


def run(args):
    drive = DriveLimits(**{k[len('drive_'):]: v for k, v in vars(args).items()
                           if k.startswith('drive_') and v is not None})   # checked together
    design = design_five_bar(args.depth, args.design_spacing, args.hole_ratio)
    mech = CamMechanism.from_design(design, args.nozzle_width)
    asked = CamStudy(mech, drive, args.rule, tuple(args.spacing), tuple(args.speed),
                     args.design_spacing, args.hole_ratio)
    # the study and its plot plan many of the same profiles: each built once
    with shared_builds():
        result = study(asked)
        require_finite(result, 'cam')
        if args.plot:
            # lazy: the plot's module only with --plot (matplotlib, an extra: dependencies)
            from planter_ros.plots.cam import plot_cam
            with atomic_output(args.plot) as tmp:
                plot_cam(asked, result['cases'], result['top_speeds'], tmp)
            result['plot'] = args.plot
    if args.json:
        print(json.dumps(result, indent=2, allow_nan=False))
    else:
        print(format_table(result))
    return 0
