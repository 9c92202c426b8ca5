"""The machine file (scene/machine_file.py): read strictly like a scene, and its lever arms place
each plant on the map where the simulated machine set it."""
import math

import numpy as np
import pytest

from cli_helpers import REPO
from planter_ros.geo import LocalFrame, geodesic_distance
from planter_ros.rows import rows_from_scene
from planter_ros.scene import load_scene
from planter_ros.scene.machine_file import MachineFileError, open_machine, parse_machine
from planter_ros.sensing.plant_map import MapSettings, PlantSpots, place_plants
from planter_ros.sensing.row_speed import motion_samples
from planter_ros.sim.field import FieldProfile, demo_curves
from planter_ros.sim.gnss import SimulatedGnss, fix_positions

EXAMPLE = REPO / 'config' / 'machines' / 'tomato_4row_tractor.yaml'
ROW = {'node_id': 1, 'lateral_offset': 0.8, 'longitudinal_offset': -2.5, 'gear_ratio': 20,
       'encoder_counts': 131072, 'max_motor_speed': 628.3, 'max_motor_acceleration': 5000,
       'max_torque': 8.36}


def machine_text(rows=None, can=None, extra=''):
    rows = rows if rows is not None else {'left': ROW}
    text = 'machine: test\n'
    if can is not None:
        text += 'can: {' + ', '.join(f'{k}: {v}' for k, v in can.items()) + '}\n'
    text += 'rows:\n'
    for name, row in rows.items():
        text += f'  {name}: {{' + ', '.join(f'{k}: {v}' for k, v in row.items()) + '}\n'
    return text + extra


def test_the_shipped_example_fits_the_four_row_scene():
    machine = open_machine(EXAMPLE)
    scene = load_scene(REPO / 'config' / 'tomato_4row.yaml', 'sync_node')
    assert list(machine.rows) == scene['rows']
    params = machine.scene_parameters()
    assert params['can_channel'] == 'can0' and params['can_bitrate'] == 500_000
    assert params['motor_gear_ratio'] == 20.0 and params['counts_per_motor_rev'] == 131072
    rows = rows_from_scene(params)
    assert [r.drive_node_id for r in rows] == [1, 2, 3, 4]
    assert {r.longitudinal_offset for r in rows} == {-2.5}
    assert machine.rows['left_inner'].polarity == 'reversed'
    # the drive's limits at the sun bar: 628.3 rad/s at the motor through 20:1
    assert machine.rows['left_outer'].max_speed == pytest.approx(31.415)


@pytest.mark.parametrize('text, message', [
    (machine_text(extra='cna: {channel: can1}\n'), 'cna is not a machine-file key: did you mean '
                                                   '`can`?'),
    (machine_text({'left': {**ROW, 'gear_ratoi': 20}}),
     'rows.left.gear_ratoi is not a machine-file key: did you mean `rows.left.gear_ratio`?'),
    (machine_text(can={'bitrat': 250000}), 'can.bitrat is not a machine-file key: did you mean '
                                           '`can.bitrate`?'),
    (machine_text(can={'bitrate': 2000000}), 'can.bitrate = 2000000 is out of range: allowed '
                                             'integer 10000..1000000 bit/s'),
    (machine_text({'left': {**ROW, 'node_id': 0}}), 'rows.left.node_id = 0 is out of range: '
                                                    'allowed integer 1..127'),
    (machine_text({'left': ROW, 'right': ROW}), "rows.right.node_id = 1 is also row left's"),
    (machine_text({'left': {**ROW, 'polarity': 'backwards'}}), 'allowed normal or reversed'),
    (machine_text({'left': {**ROW, 'modes': '[csp, torque]'}}), 'allowed a list of csp and pv'),
    (machine_text({'left': {k: v for k, v in ROW.items() if k != 'max_torque'}}),
     'rows.left.max_torque is required'),
    (machine_text({'left': {**ROW, 'gear_ratio': '.nan'}}), 'rows.left.gear_ratio = nan is out '
                                                            'of range'),
    (machine_text({'left': {**ROW, 'phase_offset': 7}}), 'rows.left.phase_offset = 7 is out of '
                                                         'range: allowed number 0..6.28319 rad'),
    (machine_text({'1left': ROW}), 'rows has a bad name'),
    (machine_text({}), 'rows is missing or empty'),
    # issue 32: a bit rate no CANopen drive runs at, an ISOBUS on the drives' own bus, a motor
    # speed no servo reaches (60 000 r/min)
    (machine_text(can={'bitrate': 123456}), 'can.bitrate = 123456 is out of range: allowed a '
                                            'CiA 301 bit rate'),
    (machine_text(extra='isobus: {channel: can0}\n'),
     "isobus.channel = 'can0' is the drives' bus (can.channel)"),
    (machine_text(extra='isobus: {channel: can1, bitrate: 500000}\n'),
     'isobus.bitrate = 500000 is out of range: allowed 250000 bit/s'),
    (machine_text({'left': {**ROW, 'max_motor_speed': 6283}}),
     'rows.left.max_motor_speed = 6283 is out of range: allowed number 0.1..1100 rad/s'),
    ('- a list\n', 'is not a mapping'),
    ('rows: {left: 3}\n', 'rows.left is not a mapping'),
])
def test_a_bad_machine_file_is_refused_in_one_line_naming_the_key(text, message):
    with pytest.raises(MachineFileError) as caught:
        parse_machine(text, 'm.yaml')
    assert message in str(caught.value) and '\n' not in str(caught.value)
    assert str(caught.value).startswith('machine file m.yaml')


def test_a_missing_machine_file_is_one_line(tmp_path):
    with pytest.raises(MachineFileError, match='does not exist'):
        open_machine(tmp_path / 'none.yaml')


def simulated_plants(heading, antenna_to_row, duration=40.0, curves=()):
    """A run starting at `heading` (rad from east): exact fixes at the antenna, a plant every
    0.2 m of the antenna's path; the truth computed here from the antenna's true track and
    heading."""
    gnss = SimulatedGnss(noise=0.0, origin_heading=heading)
    profile = FieldProfile(duration, 0.4, curves=curves)
    t = np.arange(0.0, duration, 0.05)
    v = np.array([profile(x) for x in t])
    w = np.array([profile.yaw_rate(x) for x in t])
    tf = np.arange(0.0, duration, 0.1)
    lat, lon, _ = fix_positions(profile, tf, gnss)               # the antenna's track
    var = np.full(tf.size, 1e-6)
    fixes = (tf, np.zeros(tf.size), lat, lon, var, var, np.full(tf.size, 2.0))
    grid = np.linspace(0.0, duration, 100_001)
    distance = profile.row_distance(grid, 0.0)
    tp = np.interp(np.arange(5.0, distance[-1] - 1.0, 0.2), distance, grid)
    # the truth: where the antenna was at each plant, plus the lever arm turned by the heading
    frame = LocalFrame(gnss.origin_latitude, gnss.origin_longitude)
    a_lat, a_lon, _ = fix_positions(profile, tp, gnss)
    east, north = frame.to_east_north(a_lon, a_lat)
    heading = heading + profile.pose(tp)[2]
    forward, left = antenna_to_row
    east_true = east + np.cos(heading) * forward - np.sin(heading) * left
    north_true = north + np.sin(heading) * forward + np.cos(heading) * left
    true_lon, true_lat = frame.to_lonlat(east_true, north_true)
    return (t, v, w), fixes, tp, true_lat, true_lon


@pytest.mark.parametrize('curves', [(), demo_curves(40.0)], ids=['straight', 'curves'])
def test_the_lever_arms_place_each_plant_within_5_mm(curves):
    """0.8 m left and 2.5 m behind the antenna, heading 10° (then the demo's curves): the
    map's plants within 5 mm."""
    machine = parse_machine(machine_text())
    params = machine.scene_parameters()
    row = rows_from_scene(params)[0]
    assert (row.lateral_offset, row.longitudinal_offset) == (0.8, -2.5)
    motion, fixes, tp, true_lat, true_lon = simulated_plants(
        math.radians(10.0), (row.longitudinal_offset, row.lateral_offset), curves=curves)
    mt = motion_samples(motion, [row.lateral_offset], yaw=True)
    n = tp.size

    def place(forward):
        return place_plants(PlantSpots(tp, np.full(n, row.lateral_offset), forward), mt, fixes,
                            MapSettings(), params['antenna_position'])
    placed = place(np.full(n, row.longitudinal_offset))
    off = geodesic_distance(placed.longitude, placed.latitude, true_lon, true_lat)
    assert np.all(np.isfinite(off)) and n > 50
    assert np.max(off) < 0.005, np.max(off)
    # without the longitudinal lever arm every plant is 2.5 m off
    ignored = place(None)
    off = geodesic_distance(ignored.longitude, ignored.latitude, true_lon, true_lat)
    assert np.min(off) > 2.4


@pytest.mark.parametrize('change, message', [
    # gear ratio 1000: the motor would turn 60 000 r/min at the scene's speed
    ({'gear_ratio': 1000, 'max_motor_speed': 1047}, 'needs the motor (1000 turns per sun bar '
                                                    'turn) at'),
    ({'node_id': 127}, "left_outer.drive_node_id = 127 is the master's own node id"),
    ({'encoder_counts': 1}, 'encoder_counts = 1 per motor turn through gear_ratio = 20 is 20 '
                            'counts per sun bar turn'),
])
def test_the_machine_file_against_the_scene_is_refused_before_any_work(tmp_path, change,
                                                                        message):
    """`--check FILE --scene SCENE` (and the demo, a launch, commissioning: the same
    deployment_parameters): each refused in one line naming the value and the limit."""
    import subprocess
    import sys
    import yaml
    data = yaml.safe_load(EXAMPLE.read_text())
    data['rows']['left_outer'].update(change)
    path = tmp_path / 'machine.yaml'
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    out = subprocess.run([sys.executable, '-m', 'planter_ros.scene.machine_file', str(path),
                          '--check', '--scene', str(REPO / 'config' / 'tomato_4row.yaml')],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and out.stdout == '', out.stderr
    assert out.stderr.count('\n') == 1 and message in out.stderr, out.stderr
