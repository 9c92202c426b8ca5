"""`planter analyze PATH... --out DIR`: a season of bags replayed on Dask into Parquet tables
(`plants/`, `bags/`), Shapefile, ISOXML and the season report under DIR; a re-run skips the bags
analysed before with the same model and settings unless --force. Details: doc/analysis.md.
"""

from planter_ros.cli.options import add_engine_arguments
from planter_ros.cli.replay import add_settings_arguments


def add_arguments(parser):
    parser.add_argument('paths', nargs='+', metavar='PATH',
                        help='.mcap files and directories holding bags (searched recursively '
                             'for .mcap files and rosbag2 bag directories)')
    parser.add_argument('--out', metavar='DIR', required=True,
                        help='directory of the tables (bags/, plants/): new, empty, or '
                             'the output of an earlier run (which it updates)')
    add_engine_arguments(parser)
    parser.add_argument('--force', action='store_true',
                        help='analyse every bag again, also those the tables hold for the same '
                             'model version and settings')
    parser.add_argument('--json', action='store_true',
                        help="print the run's report as JSON (SI) instead of text")
    add_settings_arguments(parser)
