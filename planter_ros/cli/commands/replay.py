"""`planter replay`: run, and the settings a replay takes from the options (also `planter
analyze`'s; the options: cli/replay.py)."""

import json
import sys

from planter_ros.analysis.bags import check_bag
from planter_ros.config import one_line
from planter_ros.export import geojson_csv, replay as exports
from planter_ros.output_files import check_distinct
from planter_ros.recording.replay import replay
from planter_ros.recording.replay_text import format_table
from planter_ros.scene import open_scene, scene_limits


def settings_overrides(args):
    """The prediction settings given on the command line (None: not given)."""
    return {'upright_threshold': args.upright_threshold, 'nozzle_width': args.nozzle_width,
            'window': args.window, 'max_input_gap': args.max_input_gap,
            'acceptance': args.scene and scene_limits(args.scene)}


def fallback_design(args):
    """The design of --scene (None without it); a bad scene is SceneError (exit 2)."""
    if not args.scene:
        return None
    return open_scene(args.scene).design()


def _plot(result, path):
    # lazy: the plot's module only with --plot (matplotlib: an extra, dependencies)
    from planter_ros.plots.replay import write_plot
    return write_plot(result, path)


OUTPUTS = ('plot', 'geojson', 'csv', 'shapefile', 'isoxml')


def run(args):
    """Replay the bag, then write each output asked for on its own (a failed one: stderr, 1)."""
    check_distinct({f'--{o}': getattr(args, o) for o in OUTPUTS})
    design = fallback_design(args)
    check_bag(args.bag)         # BagSearchError, RecordingError: one line, exit 2 (cli.main)
    result = replay(args.bag, settings_overrides(args), fallback_design=design)
    for warning in result.warnings:
        print(f'planter: warning: {warning}', file=sys.stderr)
    plants = exports.replay_run(result, args.shapefile, args.isoxml)
    writers = {'plot': lambda p: _plot(result, p),
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
