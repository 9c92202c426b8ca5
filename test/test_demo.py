"""`planter demo` as a user runs it: bad input is one line; Ctrl-C stops cleanly with a summary."""
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from planter_ros.kinematics.plant_prediction import PLANT_FIELDS

from cli_helpers import REPO, run_planter


def test_bad_duration_and_scene_are_one_line_errors(tmp_path):
    out = run_planter('demo', '--duration', '2')
    assert out.returncode == 2 and out.stderr.count('\n') == 1
    assert '--duration = 2 is out of range: allowed number 8..3600 s' in out.stderr
    bad = tmp_path / 'bad.yaml'
    text = ('/**:\n  ros__parameters:\n    mechanism: five_bar\n    planting_depth: 0.045\n'
            '    plant_spacing: 0.2\n    hole_ratio: 1.9\n    nominal_ground_speed: 0.2\n')
    bad.write_text(text + '    nozzle_width: 0.04\n')
    out = run_planter('demo', '--scene', bad)
    assert out.returncode == 2 and 'hole_ratio = 1.9 is out of range' in out.stderr
    assert 'Traceback' not in out.stderr
    # a scene must say how wide its nozzle is (the hole the monitor reports depends on it)
    bad.write_text(text.replace('1.9', '0.05'))
    out = run_planter('demo', '--scene', bad)
    assert out.returncode == 2 and out.stderr.count('\n') == 1
    assert 'nozzle_width is required: allowed number 0..0.5 m' in out.stderr
    for option, value in (('--origin-latitude', '91'), ('--origin-longitude', 'east')):
        out = run_planter('demo', option, value)
        assert out.returncode == 2 and out.stderr.count('\n') == 1 and option in out.stderr


def test_an_existing_bag_is_never_overwritten(tmp_path):
    bag = tmp_path / 'run.mcap'
    bag.write_bytes(b'precious')
    out = run_planter('demo', '--bag', bag)
    assert out.returncode == 2 and out.stderr.count('\n') == 1
    assert 'exists' in out.stderr and 'never overwritten' in out.stderr
    assert bag.read_bytes() == b'precious'


def test_ctrl_c_stops_the_demo_cleanly_with_a_summary_and_a_finalised_bag(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    proc = subprocess.Popen([sys.executable, '-m', 'planter_ros.cli', 'demo', '--duration', '60'],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                            cwd=tmp_path)
    lines = []
    deadline = time.monotonic() + 60
    for line in proc.stdout:                       # wait until plants are being placed
        lines.append(line)
        if line.startswith('t =   4.0 s') or time.monotonic() > deadline:
            break
    proc.send_signal(signal.SIGINT)
    rest, _ = proc.communicate(timeout=30)
    out = ''.join(lines) + rest
    assert proc.returncode == 130, out
    assert 'interrupted: stopping' in out
    assert 'drive shut down (target 0, disabled, pre-operational)' in out
    assert 'Traceback' not in out
    placed = next(line for line in out.splitlines() if 'plants placed' in line)
    assert int(placed.split()[-1]) >= 1
    # the default bag lands under ./bags, finalised, and the demo ends with its replay
    bags = list((tmp_path / 'bags').glob('planter_*'))
    assert len(bags) == 1
    assert f'recorded bags/{bags[0].name}' in out
    replayed = next(line for line in out.splitlines() if line.strip().startswith('plants:'))
    assert int(replayed.split()[1]) >= 1
    assert 'spacing error: mean' in out and 'uprightness:' in out


def test_the_four_row_demo_plants_every_row_through_the_turns_and_replays_per_row(tmp_path):
    from planter_ros.recording.replay import replay
    bag = tmp_path / 'four_rows.mcap'
    out = run_planter('demo', '--scene', REPO / 'config' / 'tomato_4row.yaml', '--duration',
                      '16', '--bag', bag, timeout=180)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    names = ['left_outer', 'left_inner', 'right_inner', 'right_outer']
    for name in names:
        assert f'  row {name} (y = ' in out.stdout                  # the demo's own summary
        assert f'row {name} (y = ' in out.stdout.split('replay')[-1]  # and the replay's
    assert out.stdout.count('    left turn R = 10 m') == 4
    assert 'without compensation expect -15.00 mm (-y·d/R)' in out.stdout
    assert 'drive watchdog trips     none' in out.stdout
    result = replay(bag, with_recorded=True)
    assert [r.name for r in result.rows] == names
    assert all(s['plants'] >= 5 for s in result.row_summaries)
    # replay reproduces what the monitor published, row by row, its map positions included
    row = PLANT_FIELDS.index('row')

    def by_row(table):
        return table[np.lexsort((table[:, 0], table[:, row]))]
    assert result.recorded_fields == PLANT_FIELDS
    assert np.allclose(by_row(result.plants.table()), by_row(result.recorded_plants),
                       rtol=0, atol=1e-12, equal_nan=True)
    assert np.isfinite(result.plants.latitude).all()
    check_map_files(tmp_path, bag, result)
    check_markers(bag, result)
    check_spacing_quality(bag, result)


def check_map_files(tmp_path, bag, result):
    """The GeoJSON is RFC 7946 and the plants in it are d apart on the ellipsoid (2 % RMS per
    row); the CSV has the same table."""
    import csv
    import json
    from planter_ros.cli.main import main
    from planter_ros.geo import geodesic_distance
    geo, table = tmp_path / 'map.geojson', tmp_path / 'map.csv'
    assert main(['replay', str(bag), '--geojson', str(geo), '--csv', str(table)]) == 0
    collection = json.loads(geo.read_text())
    assert collection['type'] == 'FeatureCollection'
    features = collection['features']
    assert len(features) == len(result.plants)
    d = result.summary['design_spacing']
    for name in {f['properties']['row_name'] for f in features}:
        mine = [f for f in features if f['properties']['row_name'] == name]
        assert all(f['type'] == 'Feature' and f['geometry']['type'] == 'Point' for f in mine)
        assert set(mine[0]['properties']) == {'row', 'row_name', 'index', 'time', 'spacing',
                                              'spacing_error', 'hole_width', 'tilt', 'upright'}
        lon, lat = np.array([f['geometry']['coordinates'] for f in mine]).T
        assert np.all((np.abs(lat - 52.0) < 0.01) & (np.abs(lon - 5.0) < 0.01))  # [lon, lat]
        step = geodesic_distance(lon[:-1], lat[:-1], lon[1:], lat[1:])
        spaced = np.array([f['properties']['spacing'] is not None for f in mine[1:]])
        rms = np.sqrt(np.mean((step[spaced] - d) ** 2))
        assert rms < 0.02 * d, (name, rms)
        # of which the map's own part (against the plants' spacing along the row): < 1 %
        spacing = np.array([f['properties']['spacing'] or np.nan for f in mine[1:]])
        assert np.sqrt(np.mean((step[spaced] - spacing[spaced]) ** 2)) < 0.01 * d
    with open(table, newline='') as f:
        lines = list(csv.DictReader(f))
    assert len(lines) == len(features)
    assert float(lines[3]['latitude']) == pytest.approx(
        features[3]['geometry']['coordinates'][1], abs=1e-9)


def check_markers(bag, result):
    """Every placed plant is a stem in the bag's MarkerArrays (decoded with rosbags): red when
    not upright, leaning by its tilt, its root at the planting depth and as far from its row
    neighbour as the map says; each row's tip path passes through its newest plant."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore
    from planter_ros.geo import geodesic_distance
    store = get_typestore(Stores.ROS2_JAZZY)
    stems, paths = {}, {}
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic == '/planter/plant_markers']
        assert conns and conns[0].msgtype == 'visualization_msgs/msg/MarkerArray'
        for conn, _, raw in reader.messages(connections=conns):
            for m in store.deserialize_cdr(raw, conn.msgtype).markers:
                assert m.header.frame_id == 'field'
                kind, row = m.ns.split('/')
                (stems if kind == 'plants' else paths).setdefault(row, {})[m.id] = m
    depth = result.design['planting_depth']
    p = result.plants
    for row in result.rows:
        mine = np.flatnonzero(p.row == row.index)          # in time order, as published
        markers = [stems[row.name][k] for k in sorted(stems[row.name])]
        assert len(markers) == mine.size
        roots = []
        for i, m in zip(mine, markers):
            assert m.type == 5 and len(m.points) == 2       # LINE_LIST: one stem
            root, top = m.points
            assert root.z == pytest.approx(-depth)
            lean = math.atan2(math.hypot(top.x - root.x, top.y - root.y), top.z - root.z)
            assert lean == pytest.approx(abs(p.tilt[i]), abs=1e-9)
            assert (m.color.r > 0.8 and m.color.g < 0.2) == (p.upright[i] == 0)
            roots.append((root.x, root.y))
        roots = np.array(roots)
        lat, lon = p.latitude[mine], p.longitude[mine]
        np.testing.assert_allclose(np.hypot(*np.diff(roots, axis=0).T),
                                   geodesic_distance(lon[:-1], lat[:-1], lon[1:], lat[1:]),
                                   rtol=0, atol=1e-5)
        path = paths[row.name][0]
        assert path.type == 4 and len(path.points) > 50
        points = np.array([(q.x, q.y, q.z) for q in path.points])
        newest = np.array([roots[-1][0], roots[-1][1], -depth])
        assert np.min(np.linalg.norm(points - newest, axis=1)) < 1e-9


def check_spacing_quality(bag, result):
    """Replay's indices are a hand count of its own per-plant spacings; the monitor published
    the same, per row and for the machine, on spacing_quality."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore
    p = result.plants
    d = result.summary['design_spacing']
    for row, summary in zip(result.rows, result.row_summaries):
        x = p.spacing[(p.row == row.index) & np.isfinite(p.spacing)]
        q = summary['spacing_quality']
        assert q['spacings'] == x.size >= 4
        assert q['multiple_index'] == np.count_nonzero(x <= 0.5 * d) / x.size
        assert q['miss_index'] == np.count_nonzero(x > 1.5 * d) / x.size
        singles = x[(x > 0.5 * d) & (x <= 1.5 * d)]
        assert q['precision'] == pytest.approx(np.std(singles, ddof=1) / np.mean(singles),
                                               rel=1e-9)
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic == '/planter/spacing_quality']
        last = [store.deserialize_cdr(raw, c.msgtype) for c, _, raw in
                reader.messages(connections=conns)][-1]
    labels = last.layout.dim[1].label.split(',')
    table = np.reshape(last.data, (-1, len(labels)))
    machine = table[table[:, 0] == -1][0]
    for k, field in enumerate(labels[1:], start=1):
        want = result.summary['spacing_quality'][field]
        assert machine[k] == pytest.approx(math.nan if want is None else want, rel=1e-9,
                                           nan_ok=True)
