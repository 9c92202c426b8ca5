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

from planter_ros import interfaces
from planter_ros.cli.options import output_file, output_path, spec_option
from planter_ros.kinematics.plant_prediction import PredictionSettings
from planter_ros.kinematics.scene_settings import SceneSettings
from planter_ros.kinematics.spacing_quality import format_quality


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


def check_distinct_outputs(args):
    """BadInput when two output options name the same file (the later would replace the
    earlier)."""
    from pathlib import Path
    from planter_ros.cli.main import BadInput
    seen = {}
    for option in ('plot', 'geojson', 'csv', 'shapefile', 'isoxml'):
        path = getattr(args, option, None)
        if not path:
            continue
        key = Path(path).resolve()
        if key in seen:
            raise BadInput(f'--{option} = {path} is also --{seen[key]}: allowed a path no '
                           'other output option names')
        seen[key] = option


def export_run(args, result):
    """The replay's plants for --shapefile and --isoxml (None without them), checked before
    any file is written: BadInput for plants a format cannot hold."""
    if not (args.shapefile or args.isoxml):
        return None
    from planter_ros.cli.main import BadInput
    from planter_ros.export import ExportError
    from planter_ros.export.isoxml import check_run
    from planter_ros.export.runs import run_of_replay
    run = run_of_replay(result)
    if args.isoxml:
        try:
            check_run(run)
        except ExportError as exc:
            raise BadInput(f'--isoxml: {exc}') from None
    return run


def write_exports(args, run):
    """Write --shapefile and --isoxml of an export_run: lines for people saying what was
    written."""
    if run is None:
        return []
    from planter_ros.cli.main import BadInput
    from planter_ros.export import ExportError
    from planter_ros.export.isoxml import write_isoxml
    from planter_ros.export.shapefile import write_shapefile
    written = []
    try:
        if args.shapefile:
            plants, placed = write_shapefile(args.shapefile, [run])
            written.append(f'Shapefile written to {args.shapefile} ({plants} plants, {placed} '
                           'with a map position)')
        if args.isoxml:
            tasks, logged, _ = write_isoxml(args.isoxml, [run])
            written.append(f'ISOXML written to {args.isoxml} ({tasks} task, {logged} plants '
                           'in its time log)')
    except ExportError as exc:
        raise BadInput(str(exc)) from None
    return written


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
                        help="the run's scene: its design is used if the bag holds no usable "
                             'design message (lost in a damaged part)')
    parser.add_argument('--max-input-gap', metavar='S',
                        type=spec_option(PredictionSettings, 'max_input_gap',
                                         '--max-input-gap'),
                        help='a longer gap in the ground speed or joint states ends the plant '
                             'sequence (s; default: recorded, else 0.5)')


def settings_overrides(args):
    """The prediction settings given on the command line (None: not given)."""
    return {'upright_threshold': args.upright_threshold, 'nozzle_width': args.nozzle_width,
            'window': args.window, 'max_input_gap': args.max_input_gap}


def fallback_design(args):
    """The design of --scene (None without it); BadInput for a bad scene."""
    if not args.scene:
        return None
    from planter_ros.cli.main import BadInput
    from planter_ros.kinematics.scene_design import design_for_scene
    from planter_ros.scene import SceneError, load_scene
    try:
        return design_for_scene(load_scene(args.scene, 'design_node'))
    except SceneError as exc:
        raise BadInput(str(exc)) from None


def run(args):
    from planter_ros.cli.main import BadInput
    from planter_ros.output_files import atomic_output
    from planter_ros.recording.replay import ReplayError, replay
    check_distinct_outputs(args)
    design = fallback_design(args)
    try:
        result = replay(args.bag, settings_overrides(args), fallback_design=design)
    except ReplayError as exc:
        raise BadInput(str(exc)) from None
    for warning in result.warnings:
        print(f'planter: warning: {warning}', file=sys.stderr)
    exports = export_run(args, result)
    written = []
    if args.plot:
        from planter_ros.plots.replay import plot_replay
        with atomic_output(args.plot) as tmp:
            plot_replay(result, tmp)
        written.append(f'plot written to {args.plot}')
    if args.geojson or args.csv:
        from planter_ros.output_files import write_text_atomically
        from planter_ros.recording.export import csv_text, geojson_text
        placed = int(sum(1 for v in result.plants.latitude if math.isfinite(v)))
        for path, text, what in ((args.geojson, geojson_text, 'GeoJSON'),
                                 (args.csv, csv_text, 'CSV')):
            if path:
                write_text_atomically(path, text(result))
                written.append(f'{what} written to {path} ({len(result.plants)} plants, '
                               f'{placed} with a map position)')
    written += write_exports(args, exports)
    if args.json:
        print(json.dumps(result.as_json(), indent=1, allow_nan=False))
    else:
        print(format_table(result))
        print('\n'.join(written))
    return 0


def _named_rows(result):
    return len(result.rows) > 1 or bool(result.rows[0].name)


def format_table(result):
    """Per-plant rows and the summary for people (mm and degrees, labelled)."""
    p = result.plants
    t0 = float(p.time[0]) if len(p) else 0.0
    messages = result.messages
    names = {row.index: row.label for row in result.rows} if _named_rows(result) else None
    width = max((len(n) for n in names.values()), default=3) if names else 0
    row_head = f'{"row":<{width}} ' if names else ''
    lines = [f'bag {result.path}: {messages[interfaces.GROUND_SPEED.name]} ground speed and '
             f'{messages[interfaces.JOINT_STATES.name]} joint state messages over '
             f'{result.duration:.1f} s',
             f'{row_head}{"plant":>5} {"t [s]":>8} {"x [m]":>8} {"spacing [mm]":>12} '
             f'{"error [mm]":>10} {"lambda":>7} {"sweep [mm]":>10} {"hole [mm]":>9} '
             f'{"tilt [deg]":>10} {"upright":>7}']
    for i in range(len(p)):
        spacing = '' if not math.isfinite(p.spacing[i]) else f'{p.spacing[i] * 1e3:.1f}'
        err = '' if not math.isfinite(p.spacing_error[i]) else f'{p.spacing_error[i] * 1e3:+.1f}'
        lam = f'{p.speed_ratio[i]:.3f}' if math.isfinite(p.speed_ratio[i]) else 'inf'
        row = f'{names.get(int(p.row[i]), "?"):<{width}} ' if names else ''
        lines.append(f'{row}{int(p.index[i]):>5} {p.time[i] - t0:>8.3f} {p.position[i]:>8.3f} '
                     f'{spacing:>12} {err:>10} {lam:>7} {p.tip_sweep[i] * 1e3:>10.2f} '
                     f'{p.hole_width[i] * 1e3:>9.2f} {math.degrees(p.tilt[i]):>10.2f} '
                     f'{"yes" if p.upright[i] else "NO":>7}')
    return '\n'.join(lines + [''] + format_summary(result).splitlines())


def _mm(v):
    return 'n/a' if v is None else f'{v * 1e3:.2f} mm'


def format_summary(result):
    """The replay summary for people: plants, spacing error and quality, hole width (tip sweep
    and nozzle), uprightness, the map; what a figure means where the model is not validated,
    next to it; with rows, one line per row too (positions along each row's own travelled
    distance)."""
    s = result.summary
    rate = 'n/a' if s['uprightness_rate'] is None else f'{100 * s["uprightness_rate"]:.1f} %'
    threshold = math.degrees(result.settings.upright_threshold)
    nozzle = _nozzle(result)
    notes = list(result.notes or [])
    lines = [
        f'plants: {s["plants"]} (design spacing {s["design_spacing"] * 1e3:.1f} mm)',
        f'spacing error: mean {_mm(s["spacing_error_mean"])}, sigma '
        f'{_mm(s["spacing_error_std"])}, max |error| {_mm(s["spacing_error_max"])}',
        f'spacing quality (ISO 7256-1): {format_quality(s["spacing_quality"])}',
        f'hole width: mean {_mm(s["hole_width_mean"])}, max {_mm(s["hole_width_max"])} (tip '
        f'sweep mean {_mm(s["tip_sweep_mean"])} + nozzle width {nozzle})']
    lines += _notes_for(notes, ('tip_sweep', 'hole_width'))
    lines.append(f'uprightness: {rate} (threshold {threshold:.1f} deg to the ground)')
    lines += _notes_for(notes, ('tilt', 'upright', 'uprightness_rate'))
    lines.append(_map_line(result))
    if _named_rows(result):
        for row, r in zip(result.rows, result.row_summaries):
            where = f'y = {row.lateral_offset:+.2f} m'
            if not row.enabled:
                lines.append(f'row {row.label} ({where}): disabled')
                continue
            upright = 'n/a' if r['uprightness_rate'] is None else \
                f'{100 * r["uprightness_rate"]:.1f} %'
            q = r['spacing_quality']['quality_of_feed_index']
            feed = 'n/a' if q is None else f'{100 * q:.1f} %'
            lines.append(f'row {row.label} ({where}): {r["plants"]} plants, spacing error mean '
                         f'{_mm(r["spacing_error_mean"])}, sigma {_mm(r["spacing_error_std"])}, '
                         f'max {_mm(r["spacing_error_max"])}; quality of feed {feed}; upright '
                         f'{upright}')
    return '\n'.join(lines)


def _nozzle(result):
    return _mm(result.nozzle_width)


def _notes_for(notes, fields):
    """The notes about any of `fields` not shown yet, as indented lines (taken from `notes`)."""
    lines = []
    for note in list(notes):
        if set(note['fields']) & set(fields):
            lines.append(f'  note: {note["text"]}')
            notes.remove(note)
    return lines


def _map_line(result):
    placed = int(sum(1 for v in result.plants.latitude if math.isfinite(v)))
    if not result.fixes:
        return 'map: no usable GNSS fix in the bag: no plant has a map position'
    origin = result.placement.origin
    return (f'map: {placed} of {len(result.plants)} plants placed from {result.fixes} GNSS '
            f'fixes (antenna at x = {result.antenna.antenna_position[0]:+.2f} m, y = '
            f'{result.antenna.antenna_position[1]:+.2f} m; origin {origin[0]:.7f}, '
            f'{origin[1]:.7f})')
