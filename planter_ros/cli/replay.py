"""`planter replay BAG [--json] [--plot FILE.png] [--geojson FILE] [--csv FILE] [--shapefile FILE]
[--isoxml PATH]`: re-run the monitor's model on a recording.

BAG is a .mcap file or a rosbag2 bag directory (split files `<name>_<n>.mcap`). The monitor's
settings recorded in the bag are used unless given here. A bag that is not MCAP or lacks the
needed topics is bad input (exit 2); of a damaged or cut-off bag every intact chunk is read,
with a warning on stderr naming the log-time range lost. `--geojson` and `--csv` write the
as-planted map (recording.export), `--shapefile` and `--isoxml` the same for farm software
(planter_ros.export, doc/exports.md).
"""

import json
import math
import sys

from planter_ros.cli.options import output_file, output_path, spec_option
from planter_ros.prediction import PredictionSettings
from planter_ros.kinematics.scene_settings import SceneSettings


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
                        type=spec_option(SceneSettings, 'nozzle_width', '--nozzle-width'),
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


def run(args):
    """Replay the bag, then write each output asked for: one that fails is named on stderr
    (exit 1) and never keeps the others from being written."""
    from planter_ros.cli.main import BadInput
    from planter_ros.recording.errors import RecordingError
    from planter_ros.recording.replay import replay
    from planter_ros.recording.replay_text import format_table
    from planter_ros.output_files import check_distinct
    check_distinct({f'--{o}': getattr(args, o)
                    for o in ('plot', 'geojson', 'csv', 'shapefile', 'isoxml')})
    check_bag(args.bag)
    design = fallback_design(args)
    try:
        result = replay(args.bag, settings_overrides(args), fallback_design=design)
    except RecordingError as exc:
        raise BadInput(str(exc)) from None
    for warning in result.warnings:
        print(f'planter: warning: {warning}', file=sys.stderr)
    from planter_ros.export.outputs import replay_run
    exports = replay_run(result, args.shapefile, args.isoxml)
    written, failed = [], []
    for option, path, write in _outputs(args, result, exports):
        try:
            written.append(write())
        except Exception as exc:          # one output's failure must not lose the others
            failed.append(f'{option} {path} not written: {type(exc).__name__}: '
                          f'{str(exc).strip().splitlines()[0] if str(exc).strip() else ""}')
    if args.json:
        print(json.dumps(result.as_json(), indent=1, allow_nan=False))
    else:
        print(format_table(result))
        print('\n'.join(written))
    from planter_ros.cli.main import one_line
    for line in failed:
        print(f'planter: error: {one_line(line)}', file=sys.stderr)
    return 1 if failed else 0


def check_bag(bag):
    """BadInput for a BAG that is empty or neither a file nor a directory (a FIFO named .mcap
    would be read forever): one line, before any reading."""
    from pathlib import Path

    from planter_ros.analysis.bags import path_kind
    from planter_ros.cli.main import BadInput
    if str(bag).strip() == '':
        raise BadInput('BAG is empty: allowed a .mcap file or a rosbag2 bag directory')
    kind = path_kind(Path(bag))
    if kind not in ('file', 'dir', 'missing', 'a symbolic link to nothing'):
        raise BadInput(f'BAG = {bag} is {kind}, not a bag: allowed a .mcap file or a rosbag2 '
                       'bag directory')


def _outputs(args, result, exports):
    """(option, path, writer) of each output asked for, in the order they are written; a
    writer returns the line for people."""
    from planter_ros.output_files import atomic_output, write_text_atomically
    placed = int(sum(1 for v in result.plants.latitude if math.isfinite(v)))
    counts = f'({len(result.plants)} plants, {placed} with a map position)'

    def plot():
        from planter_ros.plots.replay import plot_replay
        with atomic_output(args.plot) as tmp:
            plot_replay(result, tmp)
        return f'plot written to {args.plot}'

    def text(path, make, what):
        def write():
            write_text_atomically(path, make(result))
            return f'{what} written to {path} {counts}'
        return write

    def export(option):
        def write():
            from planter_ros.export.outputs import write_outputs
            return write_outputs(exports, args.shapefile if option == 'shapefile' else None,
                                 args.isoxml if option == 'isoxml' else None)[0]
        return write

    from planter_ros.recording.export import csv_text, geojson_text
    makers = {'plot': plot, 'geojson': text(args.geojson, geojson_text, 'GeoJSON'),
              'csv': text(args.csv, csv_text, 'CSV'), 'shapefile': export('shapefile'),
              'isoxml': export('isoxml')}
    return [(f'--{option}', getattr(args, option), write) for option, write in makers.items()
            if getattr(args, option)]
