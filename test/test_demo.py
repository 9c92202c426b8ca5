"""`planter demo` as a user runs it: bad input is one line; SIGTERM to the demo alone (what
`timeout` sends) stops it like Ctrl-C with a summary, a finalised bag and exit 0 (every other way
of stopping it by a signal: test_demo_stops.py); a killed demo's drives are still shut down; the
verdict line and its exit code; two demos side by side and a stray node in the default domain
change nothing; a design published into the demo's graph is logged, fails the verdict and is
scored as the design in force; the four-row demo's map, markers and spacing quality. (The second
signal's forced exit itself: test_stop_signals.py.)"""
import json
import math
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from planter_ros.prediction import PLANT_FIELDS

from cli_helpers import REPO, run_planter

pytestmark = pytest.mark.realtime          # (test/conftest.py)

DEMO = [sys.executable, '-m', 'planter_ros.cli', 'demo']


def demo_env():
    return dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')


def start_demo(*args, cwd):
    return subprocess.Popen(DEMO + [str(a) for a in args], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env=demo_env(), cwd=cwd)


def read_until(proc, prefix, lines, timeout=90):
    """Read the demo's output into `lines` until a line starts with `prefix`."""
    deadline = time.monotonic() + timeout
    for line in proc.stdout:
        lines.append(line)
        if line.startswith(prefix):
            return line
        assert time.monotonic() < deadline, ''.join(lines)
    raise AssertionError(f'no line {prefix!r}:\n' + ''.join(lines))


def read_until_run_time(proc, seconds, lines):
    """Read the demo's output until its progress line says the field run is `seconds` in
    (the line comes every 2 s, a little late on a loaded host: t = 4.1 s)."""
    deadline = time.monotonic() + 90
    for line in proc.stdout:
        lines.append(line)
        shown = re.match(r't = +([\d.]+) s', line)
        if shown and float(shown.group(1)) >= seconds:
            return line
        assert time.monotonic() < deadline, ''.join(lines)
    raise AssertionError(f'no progress line at t >= {seconds} s:\n' + ''.join(lines))


def children_of(pid):
    """Process ids whose parent is `pid` (from /proc)."""
    out = []
    for entry in Path('/proc').iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / 'stat').read_text().rsplit(')', 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.append(int(entry.name))
    return out


def alive(pid):
    try:
        state = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0]
    except OSError:
        return False
    return state != 'Z'


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


def test_sigterm_stops_the_demo_cleanly_with_summaries_a_finalised_bag_and_exit_0(tmp_path):
    cwd = tmp_path
    proc = start_demo('--duration', '60', cwd=cwd)
    lines = []
    read_until_run_time(proc, 4.0, lines)     # plants are being placed
    proc.send_signal(signal.SIGTERM)
    rest, _ = proc.communicate(timeout=60)
    out = ''.join(lines) + rest
    assert proc.returncode == 0, out
    assert 'interrupted by SIGTERM: stopping' in out
    assert 'drive shut down (target 0, disabled, pre-operational)' in out
    assert 'Traceback' not in out
    placed = next(line for line in out.splitlines() if 'plants placed' in line)
    assert int(placed.split()[-1]) >= 1
    assert re.search(r'control loop +command gap mean [\d.]+ ms, p99\.9 [\d.]+ ms, max', out)
    assert out.rstrip().splitlines()[-1].startswith('verdict: PASS (stopped by SIGTERM after ')
    # the default bag lands under ./bags, finalised; the demo and `planter replay` of it read
    # it without a warning
    bags = list((cwd / 'bags').glob('planter_*'))
    assert len(bags) == 1
    assert f'recorded bags/{bags[0].name}' in out and 'warning' not in out
    replayed = run_planter('replay', bags[0], '--json', cwd=cwd)
    assert replayed.returncode == 0 and replayed.stderr == ''
    result = json.loads(replayed.stdout)
    assert result['warnings'] == [] and result['summary']['plants'] >= 1


def test_a_killed_demo_still_has_its_drives_shut_down_by_the_sync_process(tmp_path):
    """A forced exit (a second signal, SIGKILL, a crash) skips the demo's own clean-up: the
    sync process sees its pipe break and shuts its drives down itself."""
    proc = start_demo('--duration', '60', cwd=tmp_path)
    lines = []
    read_until_run_time(proc, 2.0, lines)
    helpers = [pid for pid in children_of(proc.pid) if alive(pid)]
    assert helpers                                     # the sync process
    proc.kill()
    rest, _ = proc.communicate(timeout=30)             # until the sync process closes stdout
    deadline = time.monotonic() + 20
    while any(alive(pid) for pid in helpers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(alive(pid) for pid in helpers)
    assert 'drive shut down (target 0, disabled, pre-operational)' in rest, ''.join(lines) + rest


@pytest.fixture(scope='module')
def four_row_demo(tmp_path_factory):
    """One 16 s run of the 4-row demo: its completed `planter demo` and its bag, read by the
    two tests below."""
    bag = tmp_path_factory.mktemp('four_rows') / 'four_rows.mcap'
    out = run_planter('demo', '--scene', REPO / 'config' / 'tomato_4row.yaml',
                      '--duration', '16', '--bag', bag, timeout=180)
    return out, bag


@pytest.mark.slow
def test_the_4_row_layout_opens_the_4_row_demo_bag(four_row_demo):
    from test_foxglove_layout import check_the_4_row_layout_opens
    out, bag = four_row_demo
    assert bag.exists(), out.stdout[-2000:] + out.stderr[-2000:]
    check_the_4_row_layout_opens(bag)


@pytest.mark.slow
def test_the_four_row_demo_plants_every_row_through_the_turns_and_replays_per_row(
        four_row_demo, tmp_path):
    from planter_ros.recording.replay import replay
    out, bag = four_row_demo
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    names = ['left_outer', 'left_inner', 'right_inner', 'right_outer']
    for name in names:
        assert f'  row {name} (y = ' in out.stdout                  # the demo's own summary
        assert f'row {name} (y = ' in out.stdout.split('replay')[-1]  # and the replay's
        assert f'  control loop {name}' in out.stdout
    assert out.stdout.count('    left turn R = 10 m') == 4
    assert 'without compensation expect -15.00 mm (-y·d/R)' in out.stdout
    assert 'drive watchdog trips     none' in out.stdout
    assert out.stdout.rstrip().splitlines()[-1].startswith('verdict: PASS: ')
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
    """The GeoJSON is RFC 7946 and the plants in it are as far apart on the ellipsoid as the
    monitor measured along the row (1 % of d RMS per row: the map's own error) and so d apart
    within the demo's spacing tolerance (the control's error in a real-time graph depends on
    the host: 2.5 % of d seen with the suite on two processes of a loaded 2-core machine; the
    2 % bar is the closed-loop bench's); the CSV has the same table."""
    from planter_ros.demo.verdict import SPACING_TOLERANCE
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
                                              'spacing_error', 'hole_width', 'tilt', 'upright',
                                              'status', 'reason', 'input_gap'}
        lon, lat = np.array([f['geometry']['coordinates'] for f in mine]).T
        assert np.all((np.abs(lat - 52.0) < 0.01) & (np.abs(lon - 5.0) < 0.01))  # [lon, lat]
        step = geodesic_distance(lon[:-1], lat[:-1], lon[1:], lat[1:])
        spaced = np.array([f['properties']['spacing'] is not None for f in mine[1:]])
        rms = np.sqrt(np.mean((step[spaced] - d) ** 2))
        assert rms < SPACING_TOLERANCE * d, (name, rms)
        # of which the map's own part (against the plants' spacing along the row): < 1 %
        spacing = np.array([f['properties']['spacing'] or np.nan for f in mine[1:]])
        assert np.sqrt(np.mean((step[spaced] - spacing[spaced]) ** 2)) < 0.01 * d
    with open(table, newline='') as f:
        lines = list(csv.DictReader(f))
    assert len(lines) == len(features)
    assert float(lines[3]['latitude_deg']) == pytest.approx(
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
    depth = result.design.planting_depth
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
            # a plant in an input gap has no tilt (NaN): its stem is drawn upright
            tilt = abs(p.tilt[i]) if math.isfinite(p.tilt[i]) else 0.0
            assert lean == pytest.approx(tilt, abs=1e-9)
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


# a design node with the pepper scene (d = 0.3 m) and a ground-speed sensor claiming 1 m/s (its
# node name in argv[2], none if empty), as a second machine's nodes (or a mistake) on the same
# host would publish them
STRAY = r'''
import sys
import rclpy
from geometry_msgs.msg import TwistStamped
from rclpy.executors import SingleThreadedExecutor
from planter_ros import interfaces
from rclpy.parameter import Parameter
from planter_ros.nodes.design_node import DesignNode
from planter_ros.scene import open_scene
rclpy.init()
node = DesignNode(namespace=interfaces.NAMESPACE, parameter_overrides=[
    Parameter(k, value=v) for k, v in open_scene(sys.argv[1]).node_overrides('design_node')])
ex = SingleThreadedExecutor()
ex.add_node(node)
sensor = pub = None
if sys.argv[2]:
    sensor = rclpy.create_node(sys.argv[2], namespace=interfaces.NAMESPACE)
    pub = interfaces.GROUND_SPEED.publisher(sensor)
    ex.add_node(sensor)
print('stray up', flush=True)
msg = TwistStamped()
msg.twist.linear.x = 1.0
while True:
    if pub is not None:
        msg.header.stamp = sensor.get_clock().now().to_msg()
        pub.publish(msg)
    ex.spin_once(timeout_sec=0.02)
'''


def start_stray(domain, sensor='stray_sensor'):
    env = dict(demo_env(), ROS_DOMAIN_ID=str(domain))
    proc = subprocess.Popen([sys.executable, '-c', STRAY,
                             str(REPO / 'config' / 'pepper_five_bar.yaml'), sensor],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    read_until(proc, 'stray up', [], timeout=60)       # after its own log lines
    return proc


@pytest.mark.slow
def test_two_demos_side_by_side_and_a_stray_graph_in_domain_0_change_nothing(tmp_path):
    stray = start_stray(0)
    try:
        demos = [start_demo('--duration', '10', '--bag', tmp_path / f'run{i}.mcap',
                            cwd=tmp_path) for i in range(2)]
        outs = [proc.communicate(timeout=180)[0] for proc in demos]
    finally:
        stray.kill()
        stray.wait()
    domains = set()
    for proc, out in zip(demos, outs):
        assert proc.returncode == 0, out
        assert out.rstrip().splitlines()[-1].startswith('verdict: PASS: '), out
        domains.add(int(re.search(r'DDS domain (\d+) \(private\)', out).group(1)))
        assert 'unchanged during the run' in out and 'design change' not in out
        # its own sensor only: at most 20 Hz over the 10 s run (fewer on a loaded host; the
        # stray sensor's 50 Hz would more than double it)
        accepted = int(re.search(r'ground-speed samples +(\d+) accepted', out).group(1))
        assert accepted <= 215, out
        assert 'd = 200 mm' in out and 'drive watchdog trips     none' in out
        assert int(re.search(r'plants placed +(\d+)', out).group(1)) in range(7, 10)
    assert len(domains) == 2 and 0 not in domains


@pytest.mark.slow
def test_a_design_published_into_the_demos_graph_is_logged_scored_in_force_and_fails(
        tmp_path):
    from planter_ros.recording.replay import replay
    bag = tmp_path / 'intruded.mcap'
    proc = start_demo('--duration', '14', '--bag', bag, cwd=tmp_path)
    lines = []
    header = read_until(proc, 'planter demo:', lines)
    domain = int(re.search(r'DDS domain (\d+) \(private\)', header).group(1))
    read_until_run_time(proc, 4.0, lines)
    intruder = start_stray(domain, sensor='')  # a second design node, the pepper scene
    try:
        rest, _ = proc.communicate(timeout=120)
    finally:
        intruder.kill()
        intruder.wait()
    out = ''.join(lines) + rest
    assert proc.returncode == 1, out
    verdict = out.rstrip().splitlines()[-1]
    assert verdict.startswith('verdict: FAIL: ')
    assert 'design changed by another node during the run (1x, the latest from ' \
           '/planter/design_node' in verdict
    # the sync node and the monitor log it with the publishing node
    assert re.search(r'\[planter\.sync_node\]: design change 1 from /planter/design_node '
                     r'\(publisher [0-9a-f.]+\): five_bar, d = 0\.3 m', out), out
    assert re.search(r'\[planter\.monitor_node\]: design change 1 from /planter/design_node', out)
    # the plants after the change are scored against d = 300 mm, not 200
    assert 'd in force: 200 -> 300 mm' in out
    result = replay(bag)
    errors = result.plants.spacing_error
    late = (result.plants.time > result.plants.time[0] + 8.0) & (errors == errors)
    # a drive that tripped plants nothing after the change: the full suite on this 2-core host
    # has seen the sync process stall ~330 ms as the intruder joined the graph (an open
    # problem of the command path, not of design authority, which the lines above check)
    assert late.any() or 'drive watchdog trips     none' not in out, out
    if late.any():
        assert abs(float(errors[late].mean())) < 0.1 * 0.3, out
        assert max(result.plants.spacing[late]) > 0.25                      # pepper spacing
