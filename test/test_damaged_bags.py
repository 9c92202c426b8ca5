"""Damaged bags lose only what is damaged: every intact chunk is read (by the chunk index, or by
resynchronising on the next chunk in a file without summary), each loss is a warning with its
log-time range, no plant is invented across a lost part, undecodable messages are skipped and
counted, a split file missing from a bag directory is reported, and a file with no valid record
is refused after a bounded scan."""
import contextlib
import io
import shutil

from mcap.reader import make_reader
import numpy as np
import pytest

from planter_ros import interfaces
from planter_ros.cli.main import main
from planter_ros.prediction import PLANT_FIELDS
from planter_ros.recording import recovery
from planter_ros.recording.recorder import Recorder
from planter_ros.recording.errors import BagUnreadableError
from planter_ros.recording.replay import replay
from planter_ros.sim.bags import write_input_bag
from planter_ros.sim.runs import RunOptions, five_bar_design_message, simulate_run

from cli_helpers import REPO

TOMATO_BAG = REPO / 'bags' / 'sample_tomato.mcap'
TOMATO_SCENE = REPO / 'config' / 'tomato_five_bar.yaml'


def chunk_index(path):
    with open(path, 'rb') as f:
        return sorted(make_reader(f).get_summary().chunk_indexes,
                      key=lambda c: c.chunk_start_offset)


def flip(data, chunk):
    """A copy of `data` with one byte in the middle of `chunk` flipped."""
    out = bytearray(data)
    out[chunk.chunk_start_offset + chunk.chunk_length // 2] ^= 0xFF
    return bytes(out)


@pytest.fixture(scope='module')
def chunked(tmp_path_factory):
    """A 20 s input bag written in small chunks, and its replay."""
    tmp = tmp_path_factory.mktemp('chunked')
    run = simulate_run(five_bar_design_message(), RunOptions(duration=20.0, seed=8))
    write_input_bag(run, tmp / 'ok.mcap', chunk_size=16_000)
    return run, tmp / 'ok.mcap', replay(tmp / 'ok.mcap')


def assert_gap_respected(damaged, full, lo, hi):
    """Replay of the damaged bag = the full replay outside the lost range; every planting
    instant inside it is still there, flagged `input_gap` (its time and position interpolated);
    the first plant after it starts a new sequence (no spacing)."""
    flagged = damaged.plants.input_gap == 1
    inside = (damaged.plants.time > lo) & (damaged.plants.time < hi)
    assert np.all(flagged[inside]) and flagged.sum() >= 1
    plain = ~flagged
    distance = np.abs(full.plants.time[:, None] - damaged.plants.time[plain][None, :])
    lost = distance.min(axis=1) > 1e-9
    assert lost.sum() == flagged.sum()                     # every instant accounted for
    assert np.all((full.plants.time[lost] > lo - 1.0) & (full.plants.time[lost] < hi + 1.0))
    np.testing.assert_allclose(damaged.plants.time[plain], full.plants.time[~lost], rtol=0,
                               atol=1e-9)
    after = int(np.argmax(plain & (damaged.plants.time > hi)))
    assert np.isnan(damaged.plants.spacing[after])
    # the very first, the flagged ones and the first after them
    assert np.isnan(damaged.plants.spacing).sum() == 2 + flagged.sum()
    # before the gap the same plants; after it the same spacing (the distance travelled
    # across the gap is unknown, so positions there are estimates)
    kept = full.plants.table()[~lost]
    first = int(np.argmax(flagged))
    np.testing.assert_allclose(damaged.plants.table()[:first], kept[:first], rtol=0,
                               atol=1e-9, equal_nan=True)
    np.testing.assert_allclose(damaged.plants.spacing[after + 1:],
                               full.plants.spacing[~lost][after + 1 - flagged.sum():], rtol=0,
                               atol=1e-9)


def test_a_damaged_middle_chunk_costs_that_chunk_only(chunked, tmp_path):
    _, path, full = chunked
    chunks = chunk_index(path)
    hit = chunks[len(chunks) // 2]
    (tmp_path / 'bad.mcap').write_bytes(flip(path.read_bytes(), hit))
    bad = replay(tmp_path / 'bad.mcap')
    lost = [w for w in bad.warnings if 'damaged chunk' in w]
    assert len(lost) == 1 and 'after the start are lost' in lost[0], bad.warnings
    t0 = chunks[0].message_start_time
    assert f'{(hit.message_start_time - t0) * 1e-9:.3f} s to ' in lost[0]
    assert f'{(hit.message_end_time - t0) * 1e-9:.3f} s' in lost[0]
    assert_gap_respected(bad, full, hit.message_start_time * 1e-9, hit.message_end_time * 1e-9)
    lost_messages = full.messages['total_read'] - bad.messages['total_read']
    assert 0 < lost_messages < full.messages['total_read'] / len(chunks) * 2


def test_a_file_without_summary_resynchronises_after_damage(chunked, tmp_path):
    _, path, full = chunked
    chunks = chunk_index(path)
    hit = chunks[3]
    # the recorder was killed inside its last chunk, and an early chunk is damaged
    cut = flip(path.read_bytes(), hit)[:chunks[-1].chunk_start_offset + 50]
    (tmp_path / 'cut.mcap').write_bytes(cut)
    bad = replay(tmp_path / 'cut.mcap')
    assert any('not finalised' in w for w in bad.warnings)
    assert any('damaged bytes' in w and ' s to ' in w for w in bad.warnings), bad.warnings
    assert any('cut off' in w and 'logged after' in w for w in bad.warnings), bad.warnings
    lo, hi = hit.message_start_time * 1e-9, hit.message_end_time * 1e-9
    end = chunks[-2].message_end_time * 1e-9
    flagged = bad.plants.input_gap == 1                         # interpolated in the gap
    assert np.all(flagged[(bad.plants.time > lo) & (bad.plants.time < hi)])
    assert np.any(bad.plants.time > hi + 1.0)                  # read on past the damage
    expected = full.plants.time[((full.plants.time < lo) | (full.plants.time > hi))
                                & (full.plants.time < end)]
    # every plant read is one of the full replay's; a plant next to the lost range or the cut
    # may be lost too (the joint sample after its instant was in the lost bytes), no other
    distance = np.abs(bad.plants.time[~flagged][:, None] - expected[None, :])
    assert np.all(distance.min(axis=1) <= 1e-9)
    missing = expected[distance.min(axis=0) > 1e-9]
    assert missing.size <= 2, missing
    assert all(lo - 1.0 <= t <= hi + 1.0 or t >= end - 1.0 for t in missing), (missing, lo, hi)


def test_a_flipped_byte_in_the_first_chunk_keeps_the_other_fourteen(tmp_path):
    """The design is in the first chunk: replay says so in one line, and with the run's scene
    replays every other chunk."""
    chunks = chunk_index(TOMATO_BAG)
    assert len(chunks) == 15
    (tmp_path / 'first.mcap').write_bytes(flip(TOMATO_BAG.read_bytes(), chunks[0]))
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(['replay', str(tmp_path / 'first.mcap')])
    assert code == 2 and err.getvalue().count('\n') == 1
    assert 'no design message' in err.getvalue() and '--scene' in err.getvalue()
    assert 'messages logged 0.000 s to' in err.getvalue()
    from planter_ros.design import design_for_scene
    from planter_ros.scene import load_scene
    design = design_for_scene(load_scene(TOMATO_SCENE, 'design_node'))
    full = replay(TOMATO_BAG)
    bad = replay(tmp_path / 'first.mcap', fallback_design=design)
    with open(TOMATO_BAG, 'rb') as f:
        counts = make_reader(f).get_summary().statistics.channel_message_counts
    # everything but the first chunk's messages was read: 14 of 15 chunks
    assert bad.messages['total_read'] < full.messages['total_read']
    assert bad.messages[interfaces.GROUND_SPEED.name] >= counts[2] * 13 // 15
    # the same plants (positions count from the first speed sample read, hence not compared)
    np.testing.assert_allclose(bad.plants.time, full.plants.time, rtol=0, atol=1e-9)
    same = [i for i, f in enumerate(PLANT_FIELDS) if i >= 3 and f != 'hole_width']
    np.testing.assert_allclose(bad.plants.table()[:, same], full.plants.table()[:, same],
                               rtol=0, atol=1e-9, equal_nan=True)
    # the bag predates the nozzle width in the design (its monitor recorded 0 m); the scene
    # today gives its nozzle, and the holes are the tip sweep plus that
    np.testing.assert_allclose(bad.plants.hole_width,
                               full.plants.tip_sweep + design.nozzle_width, rtol=0, atol=1e-12)
    np.testing.assert_allclose(full.plants.hole_width, full.plants.tip_sweep, rtol=0, atol=0)


@pytest.mark.parametrize('with_metadata', [True, False])
def test_a_missing_split_file_is_reported_and_not_bridged(tmp_path, with_metadata):
    run = simulate_run(five_bar_design_message(), RunOptions(duration=12.0, seed=6))
    write_input_bag(run, tmp_path / 'whole.mcap')
    rec = write_input_bag(run, tmp_path / 'split', split_duration=3.0)
    assert len(rec.files) >= 4
    full = replay(tmp_path / 'whole.mcap')
    with open(rec.files[1], 'rb') as f:
        stats = make_reader(f).get_summary().statistics
    rec.files[1].unlink()
    if not with_metadata:
        (tmp_path / 'split' / 'metadata.yaml').unlink()
    bad = replay(tmp_path / 'split')
    lost = [w for w in bad.warnings if 'split_1.mcap is missing' in w]
    assert len(lost) == 1 and 'after the start are lost' in lost[0], bad.warnings
    assert ' s to ' in lost[0]
    lo, hi = stats.message_start_time * 1e-9, stats.message_end_time * 1e-9
    assert_gap_respected(bad, full, lo, hi)


def test_undecodable_design_messages_are_skipped_and_counted(tmp_path):
    run = simulate_run(five_bar_design_message(), RunOptions(duration=6.0, seed=2))
    path = tmp_path / 'odd.mcap'
    with Recorder(path) as rec:
        topics = (interfaces.DESIGN, interfaces.GROUND_SPEED, interfaces.JOINT_STATES)
        for topic in topics:
            rec.add_topic(topic.resolved(), topic.type_name, topic.recording_qos())
        first = min(stamp for stamp, _, _ in run.messages())
        design = interfaces.DESIGN.resolved()
        rec.write(design, b'', first - 3)                                    # empty
        rec.write(design, b'\x00\x01\x00\x00\x05\x00\x00\x00\xff\xfe\xfa\xfb\x00', first - 2)
        rec.write(design, b'\x00\x01\x00\x00', first - 1)                    # cut short
        for stamp, topic, msg in run.messages():
            if topic in topics:
                rec.write_message(topic.resolved(), msg, stamp)
    result = replay(path)
    assert len(result.plants) >= 3
    counted = [w for w in result.warnings if 'could not be decoded' in w]
    assert counted == ['3 design message(s) could not be decoded (empty, cut short or not '
                       'UTF-8 text): skipped']


def test_a_file_of_magic_and_zeros_is_refused_without_reading_it(tmp_path):
    zeros = tmp_path / 'zeros.mcap'
    with open(zeros, 'wb') as f:                # 1 GiB, sparse: no disk space used
        f.write(b'\x89MCAP0\r\n')
        f.truncate(1 << 30)
    with pytest.raises(BagUnreadableError,
                       match='no valid MCAP record in its first 16777224 bytes'):
        replay(zeros)
    # the scan is bounded: a valid chunk beyond the first 16 MiB of garbage is not looked for
    late = tmp_path / 'late.mcap'
    with open(late, 'wb') as f:
        f.write(b'\x89MCAP0\r\n' + bytes(recovery.SCAN_LIMIT + 1024))
        f.write(TOMATO_BAG.read_bytes()[8:])
    with pytest.raises(BagUnreadableError, match='no valid MCAP record'):
        replay(late)
    early = tmp_path / 'early.mcap'           # garbage within the bound is skipped
    data = TOMATO_BAG.read_bytes()
    early.write_bytes(data[:8] + bytes(4096) + data[8:])
    assert len(replay(early).plants) == len(replay(TOMATO_BAG).plants)


def test_the_sample_bags_still_read_the_fast_way(tmp_path):
    shutil.copy(TOMATO_BAG, tmp_path / 'copy.mcap')
    assert replay(tmp_path / 'copy.mcap').warnings == []
