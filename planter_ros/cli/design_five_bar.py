"""`planter design five-bar`: agronomic needs (D, d, k) -> bar lengths: table, JSON or plot.

The options are the scene's values (kinematics.design_inputs): same ranges as a scene file and
the design node's parameters."""

from planter_ros.cli.options import output_file, spec_option
from planter_ros.kinematics.design_inputs import DesignInputs


def add_arguments(parser):
    parser.add_argument('--depth', type=spec_option(DesignInputs, 'planting_depth', '--depth'),
                        required=True, metavar='M', help='planting depth D (m), e.g. 0.045')
    parser.add_argument('--spacing', type=spec_option(DesignInputs, 'plant_spacing',
                                                      '--spacing'),
                        required=True, metavar='M', help='plant spacing d along the row (m), '
                        'e.g. 0.2')
    parser.add_argument('--hole-ratio', type=spec_option(DesignInputs, 'hole_ratio',
                                                         '--hole-ratio'),
                        default=0.05, metavar='K',
                        help='hole entry-exit distance over depth, k = t/D (default 0.05)')
    parser.add_argument('--method', type=spec_option(DesignInputs, 'design_method', '--method'),
                        default='exact', metavar='exact|paper',
                        help="'exact' solves ψ - sin ψ = πkD/d; 'paper' uses the paper's "
                             'cube-root approximation (default exact)')
    parser.add_argument('--speed', type=spec_option(DesignInputs, 'nominal_ground_speed',
                                                    '--speed'),
                        metavar='M/S', help='ground speed v (m/s): adds the sun-bar speed '
                        'ω1 = 2πv/d')
    parser.add_argument('--tolerance', type=float, metavar='M',
                        help='bar length tolerance (m): hole-width range over built machines '
                             'with l1, l2 anywhere within ±M')
    parser.add_argument('--speed-error', type=float, metavar='F',
                        help='ground-speed error as a fraction of the synchronised speed '
                             '(0.01 = 1 %%): hole-width range with the speed anywhere within ±F')
    parser.add_argument('--json', action='store_true', help='print JSON (SI units) for machines')
    parser.add_argument('--plot', metavar='FILE.png', type=output_file('--plot', ('.png',)),
                        help='draw static and soil-frame trajectories, velocity, acceleration')
