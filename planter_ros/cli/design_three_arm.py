"""`planter design three-arm --params FILE`: the eight goals of a three-arm scene."""

import json
import math

from planter_ros.cli.options import output_file, require_finite


def add_arguments(parser):
    parser.add_argument('--params', required=True, metavar='FILE',
                        help='ROS 2 parameter file of a three_arm scene, e.g. '
                             'config/rice_three_arm.yaml')
    parser.add_argument('--json', action='store_true', help='print JSON (SI units) for machines')
    parser.add_argument('--plot', metavar='FILE.png', type=output_file('--plot', ('.png',)),
                        help='draw pitch curves, trajectories and arm angles')


def load_params(path, option='--params'):
    """Scene dict of a three-arm parameter file, every value checked against its range
    (kinematics.scene_settings, and the antenna the monitor reads: geo); BadInput for anything
    else."""
    from planter_ros.cli.main import BadInput
    from planter_ros.config import ConfigError, from_mapping
    from planter_ros.geo import AntennaSettings
    from planter_ros.kinematics.scene_settings import SceneSettings, ThreeArmSettings
    from planter_ros.scene import SceneError, load_scene
    try:
        params = load_scene(path)
    except SceneError as exc:
        raise BadInput(str(exc)) from None
    mechanism = params.get('mechanism')
    if mechanism != 'three_arm':
        raise BadInput(f'{option} {path}: mechanism = {mechanism} is out of range: allowed '
                       'three_arm')
    try:
        for cls in (SceneSettings, ThreeArmSettings, AntennaSettings):
            from_mapping(cls, params)
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
    print(json.dumps(result, indent=2, allow_nan=False) if args.json else format_table(result))
    return 0


def _show(value, unit):
    if value is None:
        return '—'
    if unit == 'rad':
        return f'{math.degrees(value):.2f} deg'
    return f'{value * 1000:.2f} mm'


def format_table(r):
    """Human table: mm and degrees, labelled."""
    lines = [f"scene {r['params']}: three-arm, {r['interpolant']} pitch curve",
             f"centre distance a      {r['centre_distance'] * 1000:.6f} mm "
             f"(closure residual {r['closure_residual']:.2g}, {r['closure_method']})",
             f"pitch radius range     {r['pitch_radius_range'][0] * 1000:.2f} … "
             f"{r['pitch_radius_range'][1] * 1000:.2f} mm",
             '']
    rows = [('goal', 'value', 'lower', 'upper', 'pass', 'basis')]
    for g in r['goals']:
        rows.append((g['name'], _show(g['value'], g['unit']), _show(g['lower'], g['unit']),
                     _show(g['upper'], g['unit']), 'yes' if g['passed'] else 'NO',
                     g['basis'] + _assumed(g)))
    lines += _table(rows, right=(1, 2, 3, 4))
    lines.append(f"goals passed           {r['goals_passed']} of {len(r['goals'])}: "
                 f"{r['paper_goals_passed']} of {r['paper_goals']} the paper fixes, "
                 f"{r['assumption_goals_passed']} of {r['assumption_goals']} on assumptions")
    lines.append(f"picking, planting at   θ = {math.degrees(r['picking_phase']):.1f}°, "
                 f"{math.degrees(r['planting_phase']):.1f}° (arm I; "
                 f"{r['phases_from']['picking_phase']}, {r['phases_from']['planting_phase']})")
    if r['zero_slip_spacing'] > 0:
        lines.append(f"zero-slip spacing      {r['zero_slip_spacing'] * 1000:.1f} mm (the plant "
                     f"spacing at which the ground keeps pace with the tip at planting; scene "
                     f"{r['plant_spacing'] * 1000:.0f} mm)")
    else:
        lines.append('zero-slip spacing      none: the tip moves forward in the frame at '
                     'planting, so no forward ground speed keeps pace with it')
    if 'carrier_speed' in r:
        lines.append(f"carrier speed          {r['carrier_speed']:.4f} rad/s at "
                     f"{r['nominal_ground_speed']:.3g} m/s "
                     f"({r['carrier_speed'] * 60 / (2 * math.pi):.2f} r/min)")
    if 'plot' in r:
        lines.append(f"plot                   {r['plot']}")
    if 'paper_comparison' in r:
        lines += ['', *_comparison_table(r['paper_comparison'])]
    return '\n'.join(lines)


def _assumed(g):
    """The assumed values (all lengths) in mm, for the basis column."""
    shown = ', '.join(f'{k} {v * 1000:g} mm' for k, v in g['assumed'].items())
    return f' ({shown})' if shown else ''


def _comparison_table(c):
    """Model against the paper's Table 1, per arm, in degrees."""
    def deg(v):
        return f'{math.degrees(v):.1f}'
    rows = [('arm', 'picking θ', 'Table 1', 'Δ', 'planting θ', 'Table 1', 'Δ',
             'picking angle at Table 1 θ', 'pushing angle at Table 1 θ')]
    for a in c['arms']:
        rows.append((a['arm'], deg(a['picking_phase']), deg(a['paper_picking_phase']),
                     f"{math.degrees(a['picking_phase_difference']):+.1f}",
                     deg(a['planting_phase']), deg(a['paper_planting_phase']),
                     f"{math.degrees(a['planting_phase_difference']):+.1f}",
                     deg(a['picking_angle_at_paper_phase']),
                     deg(a['pushing_angle_at_paper_phase'])))
    return ["against the paper's Table 1 (carrier angle θ of each arm, deg; the model picks at "
            'the highest tip point and plants at the lowest)',
            *_table(rows, right=tuple(range(1, 9)))]


def _table(rows, right=()):
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return ['  '.join(c.rjust(w) if i in right else c.ljust(w)
                      for i, (c, w) in enumerate(zip(row, widths))).rstrip() for row in rows]
