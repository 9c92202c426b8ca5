"""`planter design three-arm --params FILE`: the eight goals of a three-arm scene."""

from planter_ros.cli.options import output_file


def add_arguments(parser):
    parser.add_argument('--params', required=True, metavar='FILE',
                        help='ROS 2 parameter file of a three_arm scene, e.g. '
                             'config/rice_three_arm.yaml')
    parser.add_argument('--json', action='store_true', help='print JSON (SI units) for machines')
    parser.add_argument('--plot', metavar='FILE.png', type=output_file('--plot', ('.png',)),
                        help='draw pitch curves, trajectories and arm angles')
