"""`planter simulate --scene` with an electronic cam (doc/cam.md): the simulated rows follow the
cam the sync node plans (control.cam_law.plan_row_cam) on CSP drives, so the bags' shaft angle
within each revolution is the cam's θ(s), and `planter replay` and `planter analyze` of them
find the plants at the designed spacing with the cam's hole and tilt; the same seed gives the
same bytes. Every figure is checked against the cam core's own plan, not a number typed in."""
import json
import math

import numpy as np
import pytest

from cli_helpers import REPO, planter_here, run_planter

SPACING = 0.3          # m: twice what the mechanism is built for (0.15 m), where the cam matters


def cam_scene(tmp_path, spacing=SPACING, profile='cam'):
    """config/tomato_cam.yaml planting `spacing` all run long (no schedule: the demo's only)."""
    lines = []
    for line in (REPO / 'config' / 'tomato_cam.yaml').read_text().splitlines():
        if line.strip().startswith('spacing_schedule'):
            continue
        if line.strip().startswith('plant_spacing:'):
            line = f'    plant_spacing: {spacing}'
        if line.strip().startswith('speed_profile:'):
            line = f'    speed_profile: {profile}'
        lines.append(line)
    path = tmp_path / f'{profile}_{spacing}.yaml'
    path.write_text('\n'.join(lines) + '\n')
    return path


def planned_cam(scene):
    """The profile the sync node plans for the scene (the cam core's plan)."""
    from planter_ros.config import from_mapping
    from planter_ros.control.cam_law import plan_row_cam
    from planter_ros.control.phase_lock import PhaseLockConfig
    from planter_ros.scene import open_scene
    opened = open_scene(scene)
    law = from_mapping(PhaseLockConfig, opened.parameters('sync_node'))
    assert law.speed_profile == 'cam'
    return plan_row_cam(opened.design(), law.cam_rule)


def read_motion(bag):
    """(joint stamps s, angles rad; ground-speed stamps s, speeds m/s) read by rosbags, which
    decodes every message of the bag (it refuses one whose size does not match its fields)."""
    from rosbags.highlevel import AnyReader
    joint, speed = [], []
    with AnyReader([bag]) as reader:
        for connection, _, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            if connection.topic not in ('/planter/joint_states', '/planter/ground_speed'):
                continue
            t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            if connection.topic == '/planter/joint_states':
                joint.append((t, msg.position[0]))
            else:
                speed.append((t, msg.twist.linear.x))
    joint, speed = np.array(sorted(joint)), np.array(sorted(speed))
    return joint[:, 0], joint[:, 1], speed[:, 0], speed[:, 1]


def angle_errors(bag, profile):
    """The shaft angle against the cam within each revolution: every joint sample's angle
    minus the plan's θ at the distance travelled since the revolution's planting instant
    (θ = π + 2πk, the cam's planting angle; distance: the trapezoid of the recorded ground
    speed), and the same against constant speed (2π per spacing). Samples while the machine
    cruises, away from a speed sensor drop-out or a NaN."""
    jt, theta, st, v = read_motion(bag)
    finite = np.isfinite(v)
    st, v = st[finite], v[finite]
    distance = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(st))))
    steady = np.interp(jt, st, v) > 0.5 * np.median(v)
    for k in np.flatnonzero(np.diff(st) > 0.1):
        steady &= ~((jt > st[k] - 0.5) & (jt < st[k + 1] + 1.0))
    s = np.interp(jt, st, distance)
    crossings = math.pi + 2 * math.pi * np.arange(
        math.ceil((theta.min() - math.pi) / (2 * math.pi)),
        math.floor((theta.max() - math.pi) / (2 * math.pi)) + 1)
    s_cross = np.interp(np.interp(crossings, np.maximum.accumulate(theta), jt), st, distance)
    k = np.searchsorted(crossings, theta, side='right') - 1
    use = steady & (k >= 0)
    into = s[use] - s_cross[k[use]]
    assert abs(profile.evaluate(0.0)[0] - math.pi) < 1e-9      # the plan plants at s = 0
    cam = theta[use] - (crossings[k[use]] + profile.values(into, 0) - math.pi)
    constant = theta[use] - (crossings[k[use]] + 2 * math.pi * into / profile.spacing)
    return cam, constant


@pytest.mark.slow
def test_simulated_cam_bags_follow_the_plan_and_plant_what_it_promises(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    scene = cam_scene(tmp_path)
    profile = planned_cam(scene)
    assert profile.spacing == SPACING and profile.tip_sweep < 0.1 * SPACING
    bags = []
    # the same seed, the same bytes: a fresh process (as a user runs it), then this one (its
    # imports and plan cache warm)
    for k, run in enumerate((run_planter, planter_here)):
        out = tmp_path / f'season_{k}'
        r = run('simulate', out, '--bags', 1, '--duration', 30, '--seed', 3, '--scene', scene,
                '--workers', 1, '--json', **({'timeout': 300} if run is run_planter else {}))
        assert r.returncode == 0, r.stderr[-2000:]
        bags.append(out / 'run_3_00000.mcap')
    assert bags[0].read_bytes() == bags[1].read_bytes()
    bag = bags[0]
    with open(bag, 'rb') as f:          # mcap_ros2 decodes every message (rosbags: below)
        assert sum(1 for _ in make_reader(f, decoder_factories=[DecoderFactory()])
                   .iter_decoded_messages()) > 1000

    # the shaft's angle within each revolution is the cam's, not constant speed's
    cam, constant = angle_errors(bag, profile)
    assert cam.size > 1000
    assert np.median(np.abs(cam)) < 0.02 and np.percentile(np.abs(cam), 95) < 0.06, (
        np.median(np.abs(cam)), np.percentile(np.abs(cam), 95))
    assert np.median(np.abs(constant)) > 10 * np.median(np.abs(cam))

    # replay: every cruising plant at d, with the cam's hole and tilt, upright as it promises
    replayed = planter_here('replay', bag, '--json')
    assert replayed.returncode == 0, replayed.stderr
    report = json.loads(replayed.stdout)
    plants = [p for p in report['plants'] if p['spacing'] is not None and p['input_gap'] == 0
              and p['ground_speed'] > 0.5 * profile.speed]
    assert len(plants) >= 15
    errors = np.array([p['spacing_error'] for p in plants])
    assert np.sqrt(np.mean(errors ** 2)) < 0.01 * SPACING
    sweeps = np.array([p['tip_sweep'] for p in plants])
    tilts = np.array([p['tilt'] for p in plants])
    assert abs(np.median(sweeps) - profile.tip_sweep) < 0.5e-3, np.median(sweeps)
    assert abs(np.median(tilts) - profile.tilt) < math.radians(1.0), np.median(tilts)
    threshold = report['settings']['upright_threshold']
    promised = float(abs(profile.tilt) <= math.pi / 2 - threshold)
    assert all(p['upright'] == promised for p in plants)
    assert report['acceptance']['passed'], report['acceptance']

    # analyze: the same plants in its table (with units in the column names)
    import pyarrow.parquet as pq
    out = tmp_path / 'tables'
    analysed = planter_here('analyze', bag.parent, '--out', out, '--workers', 1)
    assert analysed.returncode == 0, analysed.stderr[-2000:]
    table = pq.read_table(out / 'plants').to_pandas()
    cruising = table[(table['ground_speed_m_s'] > 0.5 * profile.speed)
                     & table['spacing_error_m'].notna() & ~table['input_gap']]
    assert len(cruising) == len(plants)
    assert abs(cruising['tip_sweep_m'].median() - profile.tip_sweep) < 0.5e-3
    assert abs(cruising['tilt_rad'].median() - profile.tilt) < math.radians(1.0)
    assert ' PASS' in analysed.stdout


def test_a_cam_scene_the_cam_cannot_run_is_one_line(tmp_path, capsys):
    from planter_ros.cli.main import main
    text = (REPO / 'config' / 'rice_three_arm.yaml').read_text()
    scene = tmp_path / 'rice_cam.yaml'
    scene.write_text(text + '/planter/sync_node:\n  ros__parameters:\n    speed_profile: cam\n')
    assert main(['simulate', str(tmp_path / 'x'), '--bags', '1', '--scene', str(scene)]) == 2
    err = capsys.readouterr().err
    assert 'speed_profile = cam' in err and err.count('\n') == 1
    assert not (tmp_path / 'x').exists()


@pytest.mark.slow
def test_simulate_runs_the_scenes_spacing_schedule_on_the_cam(tmp_path):
    """The cam demo's scene (one five-bar built for 0.15 m planting 0.15, 0.25, 0.35 and 0.5 m
    in turn, `spacing_schedule`): each run changes the design at those times, the rows follow
    each spacing's planned cam, and replay finds every spacing at its d with its plan's sweep;
    the live monitor's plants in the bag are replay's."""
    import dataclasses

    from planter_ros.control.cam_law import plan_row_cam
    from planter_ros.prediction import PLANT_FIELDS
    from planter_ros.recording.replay import replay
    from planter_ros.scene import open_scene
    from test_cam_demo import (SPACINGS, cam_scene as schedule_scene, check_segments,
                               segment_figures)
    scene = schedule_scene(tmp_path, [6.0, 0.25, 14.0, 0.35, 20.0, 0.5])
    design = open_scene(scene).design()
    plans = {d: plan_row_cam(dataclasses.replace(design, plant_spacing=d), 'design_speed')
             for d in SPACINGS}
    out = tmp_path / 'season'
    r = planter_here('simulate', out, '--bags', 1, '--duration', 32, '--seed', 3, '--scene', scene,
                     '--workers', 1, '--json')
    assert r.returncode == 0, r.stderr[-2000:]
    events = json.loads(r.stdout)['runs'][0]['events']
    assert events['spacing_changes'] == [{'start': t, 'spacing': d} for t, d in
                                         ((6.0, 0.25), (14.0, 0.35), (20.0, 0.5))]
    result = replay(out / 'run_3_00000.mcap', with_recorded=True)
    live, replayed = result.recorded_plants, result.plants.table()
    assert live.shape == replayed.shape
    order = np.argsort(live[:, PLANT_FIELDS.index('index')], kind='stable')
    assert np.allclose(live[order], replayed, atol=1e-12, equal_nan=True)
    plants = [{k: (None if isinstance(v, float) and math.isnan(v) else v)
               for k, v in zip(PLANT_FIELDS, row)} for row in replayed.tolist()]
    segments = segment_figures([p for p in plants if p['input_gap'] == 0],
                               cruise=0.5 * design.nominal_ground_speed)
    check_segments(segments, plans, boundary=0.01)
