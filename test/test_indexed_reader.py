"""Replay's fast path reads a finalised bag through its indexes (recording.indexed): it gives the
messages an independent reader (rosbags) gives, for the sample bags and a simulated season bag;
an index that lies sends the file to the careful reader (same messages, a warning); a file
written without message indexes is read record by record."""
from pathlib import Path

import numpy as np
import pytest

from planter_ros import interfaces
from planter_ros.recording.bag_reader import read_recording
from planter_ros.recording.replay import replay
from planter_ros.sim.season import draw_plan, simulate_plan, write_monitor_bag

REPO = Path(__file__).resolve().parents[1]
WANTED = (interfaces.GROUND_SPEED, interfaces.JOINT_STATES, interfaces.DESIGN,
          interfaces.PLANTS, interfaces.GNSS_FIX)


@pytest.fixture(scope='module')
def season_bag(tmp_path_factory):
    path = tmp_path_factory.mktemp('indexed') / 'run.mcap'
    write_monitor_bag(simulate_plan(draw_plan(2, 0, 14.0, 3)), path)
    return path


def with_rosbags(path):
    """{topic name: [(log time, bytes)]} in log-time order, read by rosbags."""
    from rosbags.rosbag2 import Reader
    out = {}
    with Reader(path) as reader:
        for conn, log, raw in reader.messages():
            out.setdefault(conn.topic, []).append((log, bytes(raw)))
    return out


def mine(path):
    rec = read_recording(path, WANTED)
    assert rec.warnings == []
    return {t.name: sorted(zip(t.log, map(bytes, t.raw)), key=lambda m: m[0])
            for t in rec.topics.values()}


@pytest.mark.parametrize('name', ['season', *sorted(p.name for p in
                                                   (REPO / 'bags').glob('sample_*.mcap'))])
def test_the_same_messages_as_rosbags(name, season_bag):
    path = season_bag if name == 'season' else REPO / 'bags' / name
    theirs, ours = with_rosbags(path), mine(path)
    assert ours and all(ours[topic] == theirs[topic] for topic in ours)
    assert len(ours) >= 4 if name == 'season' else len(ours) >= 3


def test_an_index_that_lies_sends_the_file_to_the_careful_reader(season_bag, tmp_path):
    from mcap.reader import make_reader
    with open(season_bag, 'rb') as f:
        summary = make_reader(f).get_summary()
    joints = next(c.id for c in summary.channels.values()
                  if c.topic == interfaces.JOINT_STATES.resolved())
    data = bytearray(season_bag.read_bytes())
    # the offset of the first joint state in the fourth chunk's message index
    at = summary.chunk_indexes[3].message_index_offsets[joints] + 15 + 8
    data[at:at + 8] = (10 ** 6).to_bytes(8, 'little')           # points outside the chunk
    bad = tmp_path / 'lying.mcap'
    bad.write_bytes(bytes(data))
    result, good = replay(bad), replay(season_bag)
    assert any('message index' in w and 'reading every intact chunk' in w
               for w in result.warnings), result.warnings
    assert np.array_equal(result.plants.table(), good.plants.table(), equal_nan=True)


def test_a_file_without_message_indexes(season_bag, tmp_path):
    from mcap.reader import make_reader
    from mcap.writer import IndexType, Writer
    plain = tmp_path / 'plain.mcap'
    with open(season_bag, 'rb') as f, open(plain, 'wb') as out:
        reader = make_reader(f)
        summary = reader.get_summary()
        writer = Writer(out, index_types=IndexType.CHUNK | IndexType.METADATA,
                        chunk_size=64_000)
        writer.start(profile='ros2', library='test')
        schemas = {sid: writer.register_schema(s.name, s.encoding, s.data)
                   for sid, s in summary.schemas.items()}
        channels = {cid: writer.register_channel(c.topic, c.message_encoding,
                                                 schemas[c.schema_id], c.metadata)
                    for cid, c in summary.channels.items()}
        for record in reader.iter_metadata():
            writer.add_metadata(record.name, record.metadata)
        for _, channel, message in reader.iter_messages(log_time_order=False):
            writer.add_message(channels[channel.id], message.log_time, message.data,
                               message.publish_time)
        writer.finish()
    with open(plain, 'rb') as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    assert len(chunks) > 3 and all(not c.message_index_offsets for c in chunks)
    assert mine(plain) == mine(season_bag)
    assert np.array_equal(replay(plain).plants.table(), replay(season_bag).plants.table(),
                          equal_nan=True)
