"""Recorder (rosbag2 MCAP layout), the live monitor's bag, independent readers, replay."""
import math

import numpy as np
import pytest
import yaml

from planter_ros.prediction import PLANT_FIELDS
from planter_ros.recording.errors import BagWriteError
from planter_ros.recording.recorder import BagLayout, DELIMITER, Recorder, message_definition
from planter_ros.recording.replay import replay
from planter_ros.demo.samples import record_sample
from planter_ros.sim.bags import write_input_bag
from planter_ros.sim.runs import RunOptions, five_bar_design_message, simulate_run

MONITOR_PARAMS = {'window': 5, 'max_fix_age': 1.5, 'antenna_position': [1.5, -0.2]}


@pytest.fixture(scope='module')
def live_bag(tmp_path_factory):
    """The real monitor node on a 7 s stream with a drive stall, recording its bag."""
    run = simulate_run(five_bar_design_message(), RunOptions(
        duration=7.0, stall_at=2.3, stall_for=1.5, stall_level=0.05, seed=5))
    path = tmp_path_factory.mktemp('live') / 'live.mcap'
    tables = record_sample(run, path, MONITOR_PARAMS)
    return run, np.vstack(tables), path


def test_bag_has_the_rosbag2_layout(live_bag):
    from mcap.reader import make_reader
    _, _, path = live_bag
    with open(path, 'rb') as f:
        reader = make_reader(f)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        schemas = {s.name: s for s in summary.schemas.values()}
        assert {'geometry_msgs/msg/TwistStamped', 'sensor_msgs/msg/JointState',
                'std_msgs/msg/String', 'std_msgs/msg/Float64MultiArray',
                'diagnostic_msgs/msg/DiagnosticArray'} <= set(schemas)
        js = schemas['sensor_msgs/msg/JointState']
        assert js.encoding == 'ros2msg'
        text = js.data.decode()
        assert text.startswith(message_definition('sensor_msgs/msg/JointState').split('\n')[0])
        assert DELIMITER + 'MSG: std_msgs/Header\n' in text
        assert DELIMITER + 'MSG: builtin_interfaces/Time\n' in text
        channels = {c.topic: c for c in summary.channels.values()}
        speed = channels['/planter/ground_speed']
        assert speed.message_encoding == 'cdr'
        qos = yaml.safe_load(speed.metadata['offered_qos_profiles'])
        assert qos[0]['reliability'] == 'best_effort'
        design_qos = yaml.safe_load(channels['/planter/design'].metadata['offered_qos_profiles'])
        assert design_qos[0]['durability'] == 'transient_local'
        assert speed.metadata['topic_type_hash'].startswith('RIHS01_')
        stats = summary.statistics
        assert stats.message_count > 0 and stats.chunk_count >= 1
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        info = yaml.safe_load(meta['rosbag2']['serialized_metadata'])
        assert info['message_count'] == stats.message_count
        assert int(meta['planter_monitor']['window']) == MONITOR_PARAMS['window']
        assert float(meta['planter_map']['max_fix_age']) == MONITOR_PARAMS['max_fix_age']
        assert meta['planter_map']['antenna_position'] == '[1.5, -0.2]'


def test_rosbags_decodes_every_message_to_the_published_values(live_bag):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore
    run, live, path = live_bag
    store = get_typestore(Stores.ROS2_JAZZY)
    got = {}
    with Reader(path) as reader:
        for conn, _, raw in reader.messages():
            got.setdefault(conn.topic, []).append(store.deserialize_cdr(raw, conn.msgtype))
    speed = got['/planter/ground_speed']
    assert np.array_equal([m.twist.linear.x for m in speed], run.speed_v)
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in speed]
    assert np.allclose(stamps, run.speed_t, rtol=0, atol=1e-6)
    joints = got['/planter/joint_states']
    assert [list(m.name) for m in joints[:1]] == [['sun_bar']]
    assert np.array_equal([m.position[0] for m in joints], run.joint_pos)
    assert np.array_equal([m.velocity[0] for m in joints], run.joint_vel)
    assert np.array_equal([m.data for m in got['/planter/speed_command']], run.command)
    plants = np.vstack([np.reshape(m.data, (-1, m.layout.dim[1].size))
                        for m in got['/planter/plants']])
    assert got['/planter/plants'][0].layout.dim[1].label == ','.join(PLANT_FIELDS)
    assert np.array_equal(plants, live, equal_nan=True)
    rates = [m.data for m in got['/planter/uprightness_rate']]
    assert rates[-1] == live[-1, PLANT_FIELDS.index('uprightness_rate')]
    statuses = [s for m in got['/diagnostics'] for s in m.status]
    assert any(s.name == 'monitor_node: prediction' and s.level == 0 for s in statuses)


def test_mcap_reader_decodes_every_message_to_the_published_values(live_bag):
    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message
    from geometry_msgs.msg import TwistStamped
    from sensor_msgs.msg import JointState
    run, _, path = live_bag
    speeds, joints = [], []
    with open(path, 'rb') as f:
        for _, channel, message in make_reader(f).iter_messages():
            if channel.topic == '/planter/ground_speed':
                speeds.append(deserialize_message(message.data, TwistStamped))
                stamp = speeds[-1].header.stamp
                assert message.publish_time == stamp.sec * 1_000_000_000 + stamp.nanosec
            elif channel.topic == '/planter/joint_states':
                joints.append(deserialize_message(message.data, JointState))
    assert np.array_equal([m.twist.linear.x for m in speeds], run.speed_v)
    assert np.array_equal([m.position[0] for m in joints], run.joint_pos)
    assert np.array_equal([m.velocity[0] for m in joints], run.joint_vel)


def test_replay_matches_the_live_monitor(live_bag):
    _, live, path = live_bag
    result = replay(path, with_recorded=True)
    assert result.settings.window == MONITOR_PARAMS['window']
    assert result.map_settings.max_fix_age == MONITOR_PARAMS['max_fix_age']
    assert result.antenna.antenna_position == MONITOR_PARAMS['antenna_position']
    # the nozzle width is the design's (a scene value): the holes are the tip sweep + it
    assert result.nozzle_width == result.design.nozzle_width == 0.04
    assert np.allclose(result.plants.hole_width - result.plants.tip_sweep, 0.04, atol=1e-15)
    assert len(result.plants) == live.shape[0] >= 5
    assert np.allclose(result.plants.table(), live, rtol=0, atol=1e-12, equal_nan=True)
    assert np.array_equal(result.recorded_plants, live, equal_nan=True)
    assert result.plants.upright.min() == 0.0        # the stall felled a plant
    assert not result.warnings


def test_split_files_are_named_readable_and_replay_as_one_bag(tmp_path):
    from rosbags.rosbag2 import Reader
    run = simulate_run(five_bar_design_message(), RunOptions(duration=7.0, seed=6))
    whole = write_input_bag(run, tmp_path / 'whole.mcap')
    split = write_input_bag(run, tmp_path / 'split', split_duration=2.0)
    names = [f.name for f in split.files]
    assert names == [f'split_{i}.mcap' for i in range(len(names))] and len(names) == 4
    meta = yaml.safe_load((tmp_path / 'split' / 'metadata.yaml').read_text())
    info = meta['rosbag2_bagfile_information']
    assert info['relative_file_paths'] == names
    assert info['message_count'] == whole.message_count
    counted = 0
    for f in split.files:
        with Reader(f) as reader:         # each file stands alone: schemas, channels, summary
            assert {c.topic for c in reader.connections} >= {'/planter/ground_speed'}
            counted += reader.message_count
    assert counted == whole.message_count
    a, b = replay(tmp_path / 'whole.mcap'), replay(tmp_path / 'split')
    assert len(a.plants) >= 5
    assert np.array_equal(a.plants.table(), b.plants.table(), equal_nan=True)


def test_split_by_size(tmp_path):
    run = simulate_run(five_bar_design_message(), RunOptions(duration=8.0, seed=6))
    rec = write_input_bag(run, tmp_path / 'bysize', split_size=20_000, flush_period=0.001)
    assert len(rec.files) >= 3
    assert all(f.stat().st_size < 60_000 for f in rec.files)


def test_an_existing_bag_is_never_overwritten(tmp_path):
    target = tmp_path / 'x.mcap'
    target.write_bytes(b'precious')
    with pytest.raises(BagWriteError, match='already exists'):
        Recorder(target)
    assert target.read_bytes() == b'precious'
    (tmp_path / 'dir').mkdir()
    with pytest.raises(BagWriteError, match='already exists'):
        Recorder(tmp_path / 'dir')
    with pytest.raises(BagWriteError, match='bag directory'):
        Recorder(tmp_path / 'y.mcap', BagLayout(split_size=1000))


def test_default_bag_path_is_timestamped_under_bags(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    first = Recorder()
    second = Recorder()
    first.close()
    second.close()
    assert first.path.parent.name == 'bags' and first.path.name.startswith('planter_')
    assert second.path != first.path and (second.path / 'metadata.yaml').exists()


def test_truncated_bag_replays_up_to_its_last_intact_chunk(tmp_path):
    run = simulate_run(five_bar_design_message(), RunOptions(duration=20.0, seed=8))
    write_input_bag(run, tmp_path / 'full.mcap', chunk_size=16_000)
    full = replay(tmp_path / 'full.mcap')
    data = (tmp_path / 'full.mcap').read_bytes()
    (tmp_path / 'cut.mcap').write_bytes(data[:int(len(data) * 0.6)])
    cut = replay(tmp_path / 'cut.mcap')
    assert any('not finalised' in w for w in cut.warnings)
    n = len(cut.plants)
    assert 0.3 * len(full.plants) < n < len(full.plants)
    assert np.array_equal(cut.plants.table(), full.plants.table()[:n], equal_nan=True)


def test_qos_yaml_round_trips_through_rosbags():
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosbags.rosbag2.metadata import parse_qos
    from planter_ros.recording.recorder import qos_yaml
    q = parse_qos(qos_yaml(QoSProfile(depth=7, reliability=ReliabilityPolicy.BEST_EFFORT)))
    assert q[0].depth == 7 and q[0].reliability.name == 'BEST_EFFORT'
    assert math.isfinite(q[0].deadline.sec)


def test_topics_sharing_a_qos_profile_each_have_it_written_out_in_the_metadata(tmp_path):
    """The profiles' YAML is made once per distinct profile list: topics that share one still
    each have their own, written out (no YAML alias), and a different profile its own."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from planter_ros.recording.recorder import qos_yaml
    shared = QoSProfile(depth=3)
    other = QoSProfile(depth=3, reliability=ReliabilityPolicy.BEST_EFFORT)
    assert qos_yaml(shared) == qos_yaml(QoSProfile(depth=3)) != qos_yaml(other)
    rec = Recorder(tmp_path / 'b.mcap')
    for name, qos in (('/a', shared), ('/b', QoSProfile(depth=3)), ('/c', other)):
        rec.add_topic(name, 'std_msgs/msg/String', qos)
    rec.close()
    from mcap.reader import make_reader
    with open(tmp_path / 'b.mcap', 'rb') as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    text = meta['rosbag2']['serialized_metadata']
    assert '&id' not in text and '*id' not in text
    topics = {t['topic_metadata']['name']: t['topic_metadata']['offered_qos_profiles']
              for t in yaml.safe_load(text)['topics_with_message_count']}
    assert topics['/a'] == topics['/b'] == yaml.safe_load(qos_yaml(shared))
    assert topics['/c'] == yaml.safe_load(qos_yaml(other))
    assert topics['/c'][0]['reliability'] == 'best_effort'
