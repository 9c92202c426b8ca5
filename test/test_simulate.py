"""`planter simulate`: realistic bags in the monitor's exact layout that replay like recorded ones:
replay reproduces the plants they carry (glitches, a stall, stops, a curve included), the
channels and metadata are a live monitor's, the same seed gives the same bytes, bad input is one
line and exit 2."""
import json

import numpy as np
import pytest

from cli_helpers import planter_here, run_planter
from planter_ros import interfaces
from planter_ros.prediction import PLANT_FIELDS
from planter_ros.recording.replay import replay
from planter_ros.sim.field import Curve, Stop
from planter_ros.sim.season import (
    Glitch, RunPlan, Stall, draw_plan, machine_rows, simulate_bag, simulate_plan,
    write_monitor_bag)

ROW = PLANT_FIELDS.index('row')
INDEX = PLANT_FIELDS.index('index')


def eventful_plan(rows, duration=24.0):
    """A run with every event the season draws: two stops, a curve, each kind of glitch and
    a stall."""
    return RunPlan(index=3, seed=11, duration=duration, rows=machine_rows(rows), cruise=0.3,
                   change=1.2, stops=(Stop(5.0, 1.5),), curves=(Curve(12.0, 19.0, -8.0),),
                   glitches=(Glitch('spike', 4.02, factor=3.0), Glitch('nan', 8.51),
                             Glitch('dropout', 14.0, length=0.9)),
                   stall=Stall(rows - 1, 9.0, 1.5, 0.1), drive_lag=0.06)


def by_row_and_index(table):
    return table[np.lexsort((table[:, INDEX], table[:, ROW]))]


@pytest.mark.parametrize('rows', [1, 3])
def test_replay_reproduces_the_plants_a_simulated_bag_carries(rows, tmp_path):
    from planter_ros.recording.bag_reader import read_recording
    from planter_ros.recording.cdr import decode_twist
    plan = eventful_plan(rows)
    summary = write_monitor_bag(simulate_plan(plan), tmp_path / 'run.mcap')
    result = replay(tmp_path / 'run.mcap', with_recorded=True)
    live, replayed = result.recorded_plants, result.plants.table()
    assert live.shape == replayed.shape and len(live) == summary['plants'] > 20 * rows
    # the monitor publishes each row's batch as it completes; replay sorts by time
    assert np.allclose(by_row_and_index(replayed), by_row_and_index(live), rtol=0, atol=1e-12,
                       equal_nan=True)
    assert sorted(set(live[:, ROW].astype(int))) == list(range(rows))
    # the events are in the bag: a NaN and a spike among the readings, a drop-out longer than
    # the gap rule (a plant after it without spacing), a turn, a stall that tilts a plant
    speed = read_recording(tmp_path / 'run.mcap', [interfaces.GROUND_SPEED]).topics[
        interfaces.GROUND_SPEED]
    stamp, v, w = decode_twist(speed.raw)
    assert np.isnan(v).sum() == 1 and np.nanmax(v) > 2.0 * plan.cruise * plan.change
    assert np.max(np.diff(np.sort(stamp))) * 1e-9 > 0.5
    gap_end = plan.start_time + 14.0 + 0.9
    for r in range(rows):
        mine = replayed[replayed[:, ROW] == r]
        after = mine[mine[:, PLANT_FIELDS.index('time')] > gap_end]
        assert np.isnan(after[0, PLANT_FIELDS.index('spacing')])
    assert np.min(w) < -0.02                       # the right turn's yaw rate
    stalled = replayed[replayed[:, ROW] == rows - 1]
    assert np.nanmax(np.abs(stalled[:, PLANT_FIELDS.index('tilt')])) > 0.3


@pytest.mark.realtime
def test_simulated_bag_has_the_live_monitors_layout(ros, tmp_path):
    """Channels (topic, type, QoS), metadata records and the settings record of the real
    monitor node's recording with the same rows."""
    from mcap.reader import make_reader
    from rclpy.parameter import Parameter

    from planter_ros.nodes.monitor_node import MonitorNode
    rows = machine_rows(3)
    params = [Parameter('bag_path', value=str(tmp_path / 'live.mcap')),
              Parameter('rows', value=[r.name for r in rows])]
    for r in rows:
        params += [Parameter(f'{r.name}.lateral_offset', value=r.lateral_offset),
                   Parameter(f'{r.name}.drive_node_id', value=r.drive_node_id)]
    node = MonitorNode(context=ros.context, parameter_overrides=params)
    node.destroy_node()
    plan = eventful_plan(3, duration=12.0)
    write_monitor_bag(simulate_plan(plan), tmp_path / 'sim.mcap')

    def layout(path):
        with open(path, 'rb') as f:
            reader = make_reader(f)
            summary = reader.get_summary()
            channels = {(c.topic, summary.schemas[c.schema_id].name,
                         summary.schemas[c.schema_id].data, c.message_encoding,
                         tuple(sorted(c.metadata.items())))
                        for c in summary.channels.values()}
            metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            return reader.get_header().profile, channels, metadata
    live, sim = layout(tmp_path / 'live.mcap'), layout(tmp_path / 'sim.mcap')
    assert sim[0] == live[0] == 'ros2'
    assert sim[1] == live[1] and len(sim[1]) == len(interfaces.RECORDED)
    for name in (interfaces.PREDICTION_SETTINGS_RECORD, interfaces.ROWS_RECORD):
        assert sim[2][name] == live[2][name]
    assert 'rosbag2' in sim[2]


def test_a_season_is_drawn_from_its_seed(tmp_path):
    plans = [draw_plan(4, k, 60.0, 4) for k in range(40)]
    assert draw_plan(4, 7, 60.0, 4) == plans[7] and draw_plan(5, 7, 60.0, 4) != plans[7]
    assert len({p.cruise for p in plans}) == 40
    assert sum(bool(p.stops) for p in plans) > 10 and sum(bool(p.curves) for p in plans) > 20
    assert sum(p.stall is not None for p in plans) > 5
    kinds = {g.kind for p in plans for g in p.glitches}
    assert kinds == {'spike', 'nan', 'dropout'}
    for name, index in (('a', 7), ('b', 7), ('c', 8)):
        (tmp_path / name).mkdir()
        simulate_bag(tmp_path / name / 'run.mcap', 4, index, 12.0, 2)
    # the same seed: the same bytes (the recorder's CDR zeroes padding; the file name is in
    # the rosbag2 metadata, so both are named alike)
    assert (tmp_path / 'a' / 'run.mcap').read_bytes() == (tmp_path / 'b' / 'run.mcap').read_bytes()
    a, b, c = (replay(tmp_path / n / 'run.mcap', with_recorded=True) for n in 'abc')
    assert a.messages == b.messages and a.duration == b.duration
    assert np.array_equal(a.recorded_plants, b.recorded_plants, equal_nan=True)
    assert np.array_equal(a.plants.table(), b.plants.table(), equal_nan=True)
    assert a.plants.table().shape != c.plants.table().shape or not np.array_equal(
        a.plants.table(), c.plants.table(), equal_nan=True)


def test_simulate_command(tmp_path):
    out = tmp_path / 'season'
    r = planter_here('simulate', out, '--bags', 2, '--duration', 10, '--rows', 2, '--seed', 9,
                     '--workers', 1, '--json')
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads(r.stdout)
    assert report['bags'] == 2 and report['workers'] == 1 and report['failed'] == 0
    assert sorted(p.name for p in out.iterdir()) == ['run_9_00000.mcap', 'run_9_00001.mcap']
    assert [run['run'] for run in report['runs']] == [0, 1]
    assert 'planter simulate: 2/2 bags' in r.stderr
    for run in report['runs']:
        result = replay(run['bag'])
        assert len(result.plants) == run['plants'] > 0 and len(result.rows) == 2
    again = planter_here('simulate', out, '--bags', 2, '--seed', 9)
    assert again.returncode == 2 and again.stderr.count('\n') == 1
    assert 'already holds run_9_00000.mcap and 1 more' in again.stderr


@pytest.mark.parametrize('args, words', [
    (['--bags', '0'], '--bags = 0 is out of range'),
    (['--bags', '2', '--rows', '17'], '--rows = 17 is out of range'),
    (['--bags', '2', '--duration', '5'], '--duration = 5 is out of range'),
    (['--bags', '2', '--workers', '0'], '--workers = 0 is out of range'),
    (['--bags', '2', '--scheduler', 'localhost'], 'is not a scheduler address'),
    (['--bags', '2', '--workers', '1', '--scheduler', 'tcp://127.0.0.1:1'], 'not allowed'),
    (['--bags', '2', '--scene', 'config/rice_three_arm.yaml', '--rows', '2'],
     '--rows = 2 with --scene'),
    (['--bags', '2', '--scene', 'config/no_such_scene.yaml'], 'no_such_scene.yaml'),
])
def test_simulate_bad_input(args, words, tmp_path, capsys):
    from planter_ros.cli.main import main
    assert main(['simulate', str(tmp_path / 'x'), *args]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count('\n') == 1
    assert not (tmp_path / 'x').exists()


@pytest.mark.slow
def test_simulate_any_scene_twice_the_same_bytes_every_message_decoded_by_two_readers(tmp_path):
    """`--scene`: the rice three-arm (one row) and the four-row tomato machine; the same seed
    twice gives byte-identical bags; rosbags and mcap_ros2 decode every message (rosbags
    refuses a CDR message whose size does not match its fields: the JointState of
    rclpy's serialize_message had 4 bytes too many) and agree with the product's reader."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader

    from cli_helpers import REPO
    for scene, rows, mechanism in (('rice_three_arm', 1, 'three_arm'), ('tomato_4row', 4,
                                                                        'five_bar')):
        outs = []
        # the same seed, the same bytes: a fresh process, then this one (imports, caches warm)
        for k, run in enumerate((run_planter, planter_here)):
            out = tmp_path / f'{scene}_{k}'
            r = run('simulate', out, '--bags', 1, '--duration', 12, '--seed', 5, '--scene',
                    REPO / 'config' / f'{scene}.yaml', '--workers', 1, '--json',
                    **({'timeout': 300} if run is run_planter else {}))
            assert r.returncode == 0, r.stderr[-2000:]
            assert json.loads(r.stdout)['rows'] == rows
            outs.append(out / 'run_5_00000.mcap')
        assert outs[0].read_bytes() == outs[1].read_bytes(), scene
        bag = outs[0]
        result = replay(bag)
        assert result.design.mechanism == mechanism and len(result.rows) == rows
        assert result.acceptance_source.startswith("the run's scene")
        counts = {}
        with AnyReader([bag]) as reader:
            for connection, _, raw in reader.messages():
                reader.deserialize(raw, connection.msgtype)          # raises on a mismatch
                counts[connection.topic] = counts.get(connection.topic, 0) + 1
        decoded = {}
        with open(bag, 'rb') as f:
            for _, channel, _, message in make_reader(
                    f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
                decoded[channel.topic] = decoded.get(channel.topic, 0) + 1
                if channel.topic.endswith('/plants'):
                    assert len(message.data) % len(PLANT_FIELDS) == 0
        assert decoded == counts and sum(counts.values()) > 1000
        assert counts['/planter/joint_states'] == result.messages['joint_states']
        assert counts['/planter/ground_speed'] == result.messages['ground_speed']
