"""`planter simulate PATH --bags N`: a season of realistic bags (the monitor's exact layout, its
plants from the monitor's model) written fast without DDS, on the same Dask engine as `planter
analyze`; the same seed gives the same bytes. Details: doc/analysis.md (planter_ros.sim.season).
"""

from planter_ros.cli.options import add_engine_arguments, spec_option
from planter_ros.sim.options import SeasonOptions
from planter_ros.sim.tray import add_tray_arguments


def add_arguments(parser):
    parser.add_argument('path', metavar='PATH',
                        help='directory for the bags (made if missing; its parent must exist)')
    parser.add_argument('--bags', metavar='N', required=True,
                        type=spec_option(SeasonOptions, 'bags', '--bags'),
                        help='runs to simulate, 1..100000')
    parser.add_argument('--duration', metavar='S', default=60.0,
                        type=spec_option(SeasonOptions, 'duration', '--duration'),
                        help='length of each run in seconds, 10..3600 (default 60)')
    parser.add_argument('--rows', metavar='R', default=None,
                        type=spec_option(SeasonOptions, 'rows', '--rows'),
                        help='planting rows of the machine, 1..16 (default 4; 1 = a machine '
                             'without rows); not with --scene')
    parser.add_argument('--scene', metavar='FILE', help="the scene's machine (design, rows, cam, "
                        'schedule, monitor, limits, antenna; default: a tomato five-bar)')
    parser.add_argument('--seed', metavar='K', default=0,
                        type=spec_option(SeasonOptions, 'seed', '--seed'),
                        help='seed of the season, 0..2^32-1 (default 0): the same seed gives '
                             'the same bags')
    add_tray_arguments(parser, SeasonOptions, (0.02, 0.01), spec_option)
    add_engine_arguments(parser)
    parser.add_argument('--json', action='store_true',
                        help='print every bag written and what happens in it as JSON (SI)')
