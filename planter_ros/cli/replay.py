"""`planter replay BAG [--json] [--plot FILE.png] [--geojson FILE] [--csv FILE] [--shapefile FILE]
[--isoxml PATH]`: re-run the monitor's model on a recording.

BAG is a .mcap file or a rosbag2 bag directory (split files `<name>_<n>.mcap`). The monitor's
settings recorded in the bag are used unless given here. A bag that is not MCAP or lacks the
needed topics is bad input (exit 2); of a damaged or cut-off bag every intact chunk is read,
with a warning on stderr naming the log-time range lost. `--geojson` and `--csv` write the
as-planted map (export.geojson_csv), `--shapefile` and `--isoxml` the same for farm software
(planter_ros.export, doc/exports.md).
"""

from planter_ros.cli.options import output_file, output_path, spec_option
from planter_ros.export import isoxml, shapefile
from planter_ros.prediction import PredictionSettings
from planter_ros.kinematics.design_inputs import DesignInputs


def add_arguments(parser):
    parser.add_argument('bag', help='a .mcap file or a rosbag2 bag directory')
    parser.add_argument('--json', action='store_true', help='machine-readable output (SI units)')
    parser.add_argument('--plot', metavar='FILE.png', type=output_file('--plot', ('.png',)),
                        help='plot spacing error and hole width along the row, the tilt '
                             'histogram and the map of the plants')
    parser.add_argument('--geojson', metavar='FILE',
                        type=output_file('--geojson', ('.geojson', '.json')),
                        help='write the as-planted map: an RFC 7946 FeatureCollection, one '
                             'Point [lon, lat] (WGS 84) per plant')
    parser.add_argument('--csv', metavar='FILE.csv', type=output_file('--csv', ('.csv',)),
                        help='write the same per-plant table as CSV')
    add_export_arguments(parser)
    add_settings_arguments(parser)


def add_export_arguments(parser):
    parser.add_argument('--shapefile', metavar='FILE.shp|FILE.zip',
                        type=output_path(shapefile.check_path, '--shapefile'),
                        help='write the as-planted map as an ESRI Shapefile (point per plant, '
                             'WGS 84 .prj): the set next to FILE.shp, or in one .zip')
    parser.add_argument('--isoxml', metavar='DIR|FILE.zip',
                        type=output_path(isoxml.check_path, '--isoxml'),
                        help='write ISO 11783-10 task data (TASKDATA.XML and a binary time log '
                             'of every plant) into DIR, or a .zip holding TASKDATA/')


def add_settings_arguments(parser):
    """The options that choose how a bag is replayed (also `planter analyze`'s)."""
    parser.add_argument('--upright-threshold', metavar='RAD',
                        type=spec_option(PredictionSettings, 'upright_threshold',
                                         '--upright-threshold'),
                        help='minimum stem angle to the ground for "upright" (rad; default: '
                             'the recorded setting, else 30 deg)')
    parser.add_argument('--nozzle-width', metavar='M',
                        type=spec_option(DesignInputs, 'nozzle_width', '--nozzle-width'),
                        help="nozzle width along the row added to the tip's sweep (m; default: "
                             "the design's, in a bag older than that the recorded setting)")
    parser.add_argument('--window', metavar='N',
                        type=spec_option(PredictionSettings, 'window', '--window'),
                        help='plants in the rolling uprightness rate (default: recorded, else 20)')
    parser.add_argument('--scene', metavar='FILE',
                        help="the run's scene: its crop's acceptance limits judge the run "
                             "(default: the limits recorded in the bag); its design is used if "
                             'the bag holds no usable design message (lost in a damaged part)')
    parser.add_argument('--max-input-gap', metavar='S',
                        type=spec_option(PredictionSettings, 'max_input_gap',
                                         '--max-input-gap'),
                        help='a longer gap in the ground speed or joint states ends the plant '
                             'sequence (s; default: recorded, else 0.5)')
