"""recording.errors: each way a recording fails reaches the user as the one RecordingError they
act on (check the path, record the topic, give the scene, choose another bag path), and
`planter` prints it as one line with exit code 2; damage inside a file is read around, not
raised, except by the low-level readers."""
import contextlib
import io
import re

from mcap.reader import make_reader
import pytest

from planter_ros import interfaces
from planter_ros.cli.main import main
from planter_ros.recording import recovery
from planter_ros.recording.errors import (
    BagDamagedError, BagUnreadableError, BagWriteError, DecodeError, RecordingError,
    ReplayError, TopicMissingError)
from planter_ros.recording.indexed import IndexedFile
from planter_ros.recording.recorder import BagLayout, Recorder
from planter_ros.recording.replay import replay
from planter_ros.sim.bags import write_input_bag
from planter_ros.sim.runs import RunOptions, five_bar_design_message, simulate_run

KINDS = (BagDamagedError, BagUnreadableError, BagWriteError, DecodeError, ReplayError,
         TopicMissingError)


def planter(*args):
    """(exit code, stderr) of `planter args` run in this process."""
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return code, err.getvalue()


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    tmp = tmp_path_factory.mktemp('errors')
    (tmp / 'notes.mcap').write_text('not a bag at all\n')
    from std_msgs.msg import Float64
    with Recorder(tmp / 'foreign.mcap') as rec:              # valid, none of our topics
        rec.add_topic('/camera/rate', 'std_msgs/msg/Float64')
        rec.write_message('/camera/rate', Float64(data=1.0), 1)
    run = simulate_run(five_bar_design_message(), RunOptions(duration=6.0, seed=3))
    inputs = (interfaces.GROUND_SPEED, interfaces.JOINT_STATES)
    with Recorder(tmp / 'no_design.mcap') as rec:   # speed, joints, a design cut to nothing
        for topic in (*inputs, interfaces.DESIGN):
            rec.add_topic(topic.resolved(), topic.type_name, topic.recording_qos())
        rec.write(interfaces.DESIGN.resolved(), b'', 1)
        for stamp, topic, msg in run.messages():
            if topic in inputs:
                rec.write_message(topic.resolved(), msg, stamp)
    write_input_bag(run, tmp / 'whole.mcap', chunk_size=16_000)
    return tmp


CASES = {
    'missing.mcap': (BagUnreadableError, 'does not exist'),
    'notes.mcap': (BagUnreadableError, 'is not an MCAP file'),
    'foreign.mcap': (TopicMissingError, 'topics found: /camera/rate (std_msgs/msg/Float64)'),
    'no_design.mcap': (ReplayError, 'has no usable design message'),
}


@pytest.mark.parametrize('name', list(CASES))
def test_each_refusal_is_the_one_kind_a_user_acts_on_and_one_line_exit_2(bags, name):
    kind, words = CASES[name]
    with pytest.raises(RecordingError, match=re.escape(words)) as info:
        replay(bags / name)
    assert [k for k in KINDS if isinstance(info.value, k)] == [kind]
    code, err = planter('replay', bags / name)
    assert code == 2 and err.startswith('planter: error: ') and words in err
    assert err.count('\n') == 1 and 'Traceback' not in err


def test_a_bag_that_cannot_be_written_is_a_bag_write_error(bags, tmp_path):
    for refused, words in ((lambda: Recorder(bags / 'whole.mcap'), 'already exists'),
                           (lambda: Recorder(tmp_path / 'a.mcap',
                                             BagLayout(flush_period=0.0)),
                            'flush_period'),
                           (lambda: Recorder(tmp_path / 'b', BagLayout(split_size=-1)),
                            'split_size')):
        with pytest.raises(BagWriteError, match=words) as info:
            refused()
        assert '\n' not in str(info.value)
    rec = Recorder(tmp_path / 'c.mcap')
    rec.close()
    with pytest.raises(BagWriteError, match='is closed'):
        rec.write('/x', b'', 1)


def test_damage_is_read_around_and_raised_only_by_the_low_level_readers(bags, tmp_path):
    path = bags / 'whole.mcap'
    with open(path, 'rb') as f:
        chunks = sorted(make_reader(f).get_summary().chunk_indexes,
                        key=lambda c: c.chunk_start_offset)
    hit = chunks[len(chunks) // 2]
    data = bytearray(path.read_bytes())
    data[hit.chunk_start_offset + hit.chunk_length // 2] ^= 0xFF
    bad = tmp_path / 'bad.mcap'
    bad.write_bytes(bytes(data))
    # the fast reader refuses the file, naming the chunk ...
    with IndexedFile(bad) as indexed, pytest.raises(BagDamagedError,
                                                    match=f'byte {hit.chunk_start_offset}'):
        indexed.messages(set(indexed.channels))
    # ... the careful one names the record and where it is ...
    with pytest.raises(BagDamagedError) as info:
        recovery.record_at(data, hit.chunk_start_offset)
    assert info.value.at == hit.chunk_start_offset and info.value.reason
    assert str(info.value).startswith(f'record at byte {hit.chunk_start_offset}: ')
    # ... and replay reads every other chunk, the loss a warning
    result = replay(bad)
    assert len(result.plants) > 0
    assert any('damaged chunk' in w for w in result.warnings), result.warnings
