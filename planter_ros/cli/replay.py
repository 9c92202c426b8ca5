"""`planter replay BAG [--json] [--plot FILE.png] [--geojson FILE] [--csv FILE] [--shapefile FILE]
[--isoxml PATH]`: re-run the monitor's model on a recording.

BAG is a .mcap file or a rosbag2 bag directory (split files `<name>_<n>.mcap`). The monitor's
settings recorded in the bag are used unless given here. A bag that is not MCAP or lacks the
needed topics is bad input (exit 2); of a damaged or cut-off bag every intact chunk is read,
with a warning on stderr naming the log-time range lost. `--geojson` and `--csv` write the
as-planted map (export.geojson_csv), `--shapefile` and `--isoxml` the same for farm software
(planter_ros.export, doc/exports.md).
"""

import json
import sys

from planter_ros.cli.options import output_file, output_path, spec_option
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
    from planter_ros.export import isoxml, shapefile
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


def settings_overrides(args):
    """The prediction settings given on the command line (None: not given)."""
    from planter_ros.scene import scene_limits
    return {'upright_threshold': args.upright_threshold, 'nozzle_width': args.nozzle_width,
            'window': args.window, 'max_input_gap': args.max_input_gap,
            'acceptance': args.scene and scene_limits(args.scene)}


def fallback_design(args):
    """The design of --scene (None without it); a bad scene is SceneError (exit 2)."""
    if not args.scene:
        return None
    from planter_ros.scene import open_scene
    return open_scene(args.scene).design()


OUTPUTS = ('plot', 'geojson', 'csv', 'shapefile', 'isoxml')


def run(args):
    """Replay the bag, then write each output asked for on its own (a failed one: stderr, 1)."""
    from planter_ros.analysis.bags import check_bag
    from planter_ros.config import one_line
    from planter_ros.export import geojson_csv, replay as exports
    from planter_ros.output_files import check_distinct
    from planter_ros.plots.replay import write_plot
    from planter_ros.recording.replay import replay
    from planter_ros.recording.replay_text import format_table
    check_distinct({f'--{o}': getattr(args, o) for o in OUTPUTS})
    design = fallback_design(args)
    check_bag(args.bag)         # BagSearchError, RecordingError: one line, exit 2 (cli.main)
    result = replay(args.bag, settings_overrides(args), fallback_design=design)
    for warning in result.warnings:
        print(f'planter: warning: {warning}', file=sys.stderr)
    plants = exports.replay_run(result, args.shapefile, args.isoxml)
    writers = {'plot': lambda p: write_plot(result, p),
               'geojson': lambda p: geojson_csv.write_geojson(result, p),
               'csv': lambda p: geojson_csv.write_csv(result, p)}
    if plants is not None:   # --shapefile or --isoxml given
        writers |= {'shapefile': lambda p: exports.write_shapefile_output(plants, p),
                    'isoxml': lambda p: exports.write_isoxml_output(plants, p)}
    written, failed = exports.write_each([(f'--{o}', getattr(args, o), writers[o])
                                          for o in OUTPUTS if getattr(args, o)])
    print(json.dumps(result.as_json(), indent=1, allow_nan=False) if args.json else
          '\n'.join([format_table(result), *written]))
    for line in failed:
        print(f'planter: error: {one_line(line)}', file=sys.stderr)
    return 1 if failed else 0
