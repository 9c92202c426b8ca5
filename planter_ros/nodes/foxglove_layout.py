"""The Foxglove layout of a monitor's bag, made for a scene's rows (config/foxglove_layout*.json
are made by it; a test keeps them equal to what it makes today).

Panels, each under its id `<type>!<name>` with Foxglove's own panel type (case-sensitive: the
Map panel is `map`, the others `3D`, `Plot`, `DiagnosticSummary`) and only the keys that panel
persists (`foxglovePanelTitle` names a panel, the Plot panel's own `title` is deprecated); the
test checks both against Foxglove's registry and config types (test/data/foxglove_panels.json):
* Map: the machine's GNSS antenna (`gnss/fix`) and each planted plant (`plant_fixes`), both
  sensor_msgs/NavSatFix, the map following the antenna.
* 3D: the plants and the tip paths (`plant_markers`) in the `field` frame, with a 1 m grid.
* Plots, one series per planting row (`plant_rows` keyed by header.frame_id = the row's name):
  spacing error with the target 0 drawn, the speed ratio λ with the target 1 drawn; the
  ISO 7256-1 quality of feed per row and of the whole machine (`spacing_quality`).
* The diagnostics summary.

`python -m planter_ros.nodes.foxglove_layout SCENE OUT.json` writes the layout of a scene.
"""

import argparse
import json

from planter_ros import interfaces
from planter_ros.output_files import write_text_atomically
from planter_ros.prediction import QUALITY_FIELDS
from planter_ros.scene import open_scene

from .markers import FRAME

__all__ = ['MAP', 'layout', 'layout_text']

ROW_COLOURS = ('#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', '#9467bd', '#8c564b', '#e377c2',
               '#7f7f7f', '#bcbd22', '#17becf')
TARGET_COLOUR = '#555555'
MAP = 'map!planter-map'          # Foxglove registers the Map panel as type `map`
QUALITY_COLUMNS = 1 + len(QUALITY_FIELDS)       # the 'row' column, then the indices


def _series(path, label, colour, stamp='headerStamp'):
    return {'value': path, 'label': label, 'color': colour, 'enabled': True,
            'timestampMethod': stamp, 'showLine': True}


def _target(value, label):
    """A reference line: a Plot path that is a number draws a horizontal line there."""
    return {'value': str(value), 'label': label, 'color': TARGET_COLOUR, 'enabled': True,
            'timestampMethod': 'receiveTime'}


def _plot(title, paths, unit_range=None):
    config = {'foxglovePanelTitle': title, 'paths': paths, 'showXAxisLabels': True,
              'showYAxisLabels': True, 'showLegend': True, 'legendDisplay': 'top',
              'showPlotValuesInLegend': True, 'isSynced': True, 'xAxisVal': 'timestamp',
              'sidebarDimension': 240}
    if unit_range is not None:
        config['minYValue'], config['maxYValue'] = unit_range
    return config


def _split(direction, first, second, percentage=50):
    return {'direction': direction, 'first': first, 'second': second,
            'splitPercentage': percentage}


def layout(labels):
    """The layout (a dict, Foxglove's layout JSON) for planting rows named `labels` (their
    `Row.label`, in the scene's order)."""
    rows_topic = interfaces.PLANT_ROWS.resolved()
    quality = interfaces.SPACING_QUALITY.resolved()
    feed = QUALITY_FIELDS.index('quality_of_feed_index') + 1

    def per_row(field):
        return [_series(f'{rows_topic}{{header.frame_id=="{label}"}}.vector.{field}', label,
                        ROW_COLOURS[k % len(ROW_COLOURS)]) for k, label in enumerate(labels)]
    fix = interfaces.GNSS_FIX.resolved()
    plants = interfaces.PLANT_FIXES.resolved()
    panels = {
        MAP: {
            'foxglovePanelTitle': 'where: GNSS antenna track and the planted plants',
            'layer': 'map', 'customTileUrl': '', 'disabledTopics': [],
            'followTopic': fix, 'topicColors': {fix: '#1f77b4', plants: '#2ca02c'},
            'zoomLevel': 20},
        '3D!planter3d': {
            'foxglovePanelTitle': 'plants and tip paths (field frame, 1 m grid)',
            'cameraState': {'distance': 12, 'perspective': True, 'phi': 50,
                            'target': [0, 0, 0], 'targetOffset': [0, 0, 0],
                            'targetOrientation': [0, 0, 0, 1], 'thetaOffset': 30, 'fovy': 45,
                            'near': 0.01, 'far': 5000},
            'followMode': 'follow-none', 'followTf': FRAME,
            'scene': {'enableStats': False, 'backgroundColor': '#f4f1ea'},
            'transforms': {},
            'topics': {interfaces.PLANT_MARKERS.resolved(): {'visible': True}},
            'layers': {'grid-field': {
                'visible': True, 'frameLocked': True, 'label': 'Grid (1 m)',
                'instanceId': 'grid-field', 'layerId': 'foxglove.Grid', 'frameId': FRAME,
                'size': 50, 'divisions': 50, 'lineWidth': 0.5, 'color': '#9a9a9a',
                'position': [0, 0, 0], 'rotation': [0, 0, 0], 'order': 1}}},
        'Plot!spacing': _plot('spacing error [m] per row (target 0)',
                              per_row('x') + [_target(0, 'target 0')]),
        'Plot!lambda': _plot('speed ratio λ per row (1 = in sync)',
                             per_row('y') + [_target(1, 'in sync')], (0.5, 1.5)),
        'Plot!quality': _plot(
            'quality of feed per row and machine (ISO 7256-1, fraction 0..1)',
            [_series(f'{quality}.data[{(k + 1) * QUALITY_COLUMNS + feed}]', label,
                     ROW_COLOURS[k % len(ROW_COLOURS)], 'receiveTime')
             for k, label in enumerate(labels)]
            + [_series(f'{quality}.data[{feed}]', 'machine', '#000000', 'receiveTime')],
            (0, 1)),
        'DiagnosticSummary!diag': {'topicToRender': interfaces.DIAGNOSTICS.resolved(),
                                   'minLevel': 0, 'pinnedIds': [], 'hardwareIdFilter': '',
                                   'sortByLevel': True},
    }
    tree = _split('row', _split('column', MAP, '3D!planter3d', 50),
                  _split('column', _split('column', 'Plot!spacing', 'Plot!lambda'),
                         _split('column', 'Plot!quality', 'DiagnosticSummary!diag', 55)), 45)
    return {'configById': panels, 'globalVariables': {}, 'userNodes': {},
            'playbackConfig': {'speed': 1}, 'layout': tree}


def layout_text(labels):
    """The layout as the JSON text of the shipped files."""
    return json.dumps(layout(labels), indent=2, ensure_ascii=False) + '\n'


def main(argv=None):
    """Write the layout of a scene's planting rows."""
    parser = argparse.ArgumentParser(description=main.__doc__, allow_abbrev=False)
    parser.add_argument('scene', help='scene parameter file')
    parser.add_argument('out', help='layout file to write (.json)')
    args = parser.parse_args(argv)
    labels = [row.label for row in open_scene(args.scene).rows() if row.enabled]
    write_text_atomically(args.out, layout_text(labels))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
