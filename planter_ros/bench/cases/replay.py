"""Replay rows: `replay()` of a generated input bag (throughput, × real time), of the same bag
with one chunk damaged (the careful reader), of files with no valid MCAP record (how soon they
are refused) and of the committed sample bags, whose live-monitor predictions give replay an
error to report.

The generated bag (`simulate_run` → `write_input_bag`, 100 Hz joint states, 20 Hz ground speed,
100 Hz speed command) goes to a temporary directory and is deleted. It holds no live
predictions, so its rows have no error; the sample bags were recorded by the real monitor node
and hold its per-plant table, which replay must reproduce.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
import os
from pathlib import Path
import tempfile

from mcap.reader import make_reader
import numpy as np

from planter_ros import interfaces
from planter_ros.recording.errors import BagUnreadableError
from planter_ros.recording.replay import ReplayResult, replay
from planter_ros.sim.bags import write_input_bag
from planter_ros.sim.runs import Run, RunOptions, five_bar_design_message, simulate_run

from ..registry import BenchContext, Row, Target, bench_case

WHAT = 'replay (planter replay)'
REAL_TIME_TARGET = 1000.0      # quality target: replay >= 1000x real time
BAGS = Path(__file__).resolve().parents[3] / 'bags'
ERROR_OF = ('max |replayed − live monitor prediction| over every field of every plant (SI: s, '
            'm, m/s, rad/s, rad), absolute; — for a generated bag (no live predictions in it)')


@dataclass(frozen=True)
class ReplayedBag:
    """A bag and what replay made of it: its path, the result, the messages it holds."""

    path: Path
    result: ReplayResult
    messages: int


def _replay_row(ctx: BenchContext, bag: ReplayedBag, label: str, error: float | None = None,
                target: bool = False, note: str = '') -> Row:
    path, result, bag_messages = bag.path, bag.result, bag.messages
    t = ctx.measure(lambda: replay(path))
    speed = result.duration / t.median
    targets = ([Target(f'≥ 1000× real time (run: {speed:.0f}×)', speed >= REAL_TIME_TARGET)]
               if target else [])
    used = sum(result.messages[t.name] for t in (interfaces.GROUND_SPEED,
                                                 interfaces.JOINT_STATES))
    extra: dict[str, object] = {'bag_duration_s': result.duration, 'bag_messages': bag_messages,
             'bag_bytes': os.path.getsize(path), 'messages_used': used,
             'plants': result.summary['plants'], 'times_real_time': speed,
             'used_messages_per_s': used / t.median}
    note = (f'{speed:.0f}× real time; {result.duration:.0f} s bag, {bag_messages} messages, '
            f'{os.path.getsize(path) / 1e6:.2f} MB, {result.summary["plants"]} plants; '
            f'{used / t.median / 1e3:.0f} k decoded input messages/s'
            + (f'; {note}' if note else ''))
    return Row(WHAT, label, bag_messages, 'message', t, error=error, error_of=ERROR_OF,
               targets=targets, note=note, extra=extra)


def _damaged_row(ctx: BenchContext, run: Run, tmp: Path, whole: ReplayResult) -> Row:
    """The generated run in chunks of 64 kB, the middle chunk's bytes zeroed: every other chunk
    is read."""
    path, damaged = tmp / 'chunked.mcap', tmp / 'damaged.mcap'
    bag_messages = write_input_bag(run, path, chunk_size=64_000).message_count
    with open(path, 'rb') as f:
        summary = make_reader(f).get_summary()
    if summary is None:                      # the bag was just written and closed
        raise RuntimeError(f'{path} has no summary')
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    data = bytearray(path.read_bytes())
    hit = chunks[len(chunks) // 2]
    middle = hit.chunk_start_offset + hit.chunk_length // 2
    data[middle:middle + 64] = bytes(64)
    damaged.write_bytes(bytes(data))
    result = replay(damaged)
    lost = (hit.message_end_time - hit.message_start_time) * 1e-9
    return _replay_row(ctx, ReplayedBag(damaged, result, bag_messages),
                       'the same run, its middle chunk damaged',
                       note=f'{len(chunks) - 1} of {len(chunks)} chunks read, {lost:.2f} s lost; '
                            f'{result.summary["plants"]} of {whole.summary["plants"]} plants')


def _garbage_rows(ctx: BenchContext, tmp: Path) -> Iterator[Row]:
    """Files that start like MCAP and hold no valid record: refused after a bounded scan."""
    zeros, noise = tmp / 'zeros.mcap', tmp / 'noise.mcap'
    size = int(ctx.n(1 << 30, 64 << 20))
    with open(zeros, 'wb') as f:          # sparse: no disk space used
        f.write(b'\x89MCAP0\r\n')
        f.truncate(size)
    noise.write_bytes(b'\x89MCAP0\r\n' + np.random.default_rng(0).bytes(64 << 20))
    for path, label in ((zeros, f'MCAP magic + {size >> 20} MiB of zeros'),
                        (noise, 'MCAP magic + 64 MiB of random bytes')):
        def refuse() -> None:
            try:
                replay(path)
            except BagUnreadableError:
                return
            raise RuntimeError(f'{label}: not refused')
        t = ctx.measure(refuse, repeats=5)
        yield Row(WHAT, f'refused: {label}', None, 'file', t,
                  targets=[Target(f'≤ 1 s (run: p90 {t.p90:.2g} s)', t.p90 <= 1.0)],
                  note='no valid record in the first 16 MiB: refused (exit 2)')


def _live_error(result: ReplayResult, path: Path) -> float:
    """Max |replayed − recorded live prediction| over the plant table (NaN must match NaN)."""
    # the fields this recording has (one made before tip_sweep and the map has fewer)
    columns = result.recorded_columns()
    replayed = result.plants.table()[:, columns]
    live = result.recorded_plants[:, columns]
    if live.shape != replayed.shape:
        raise RuntimeError(f'{path.name}: replay found {replayed.shape[0]} plants, the live '
                           f'monitor recorded {live.shape[0]}')
    if not np.array_equal(np.isnan(live), np.isnan(replayed)):
        raise RuntimeError(f'{path.name}: replay and the live monitor disagree on which fields '
                           'are undefined (NaN)')
    finite = ~np.isnan(live)
    return float(np.max(np.abs(replayed[finite] - live[finite]), initial=0.0))


@bench_case('replay')
def replay_throughput(ctx: BenchContext) -> Iterator[Row]:
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    duration = ctx.n(600.0, 20.0)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'bench.mcap'
        ctx.progress(f'  generating a {duration:.0f} s input bag ...')
        run = simulate_run(five_bar_design_message(), RunOptions(duration=duration))
        rec = write_input_bag(run, path)
        result = replay(path)
        yield _replay_row(ctx, ReplayedBag(path, result, rec.message_count),
                          f'generated {duration:.0f} s input bag', target=True,
                          note='tomato five-bar, speed step +25 %')
        yield _damaged_row(ctx, run, Path(tmp), result)
        yield from _garbage_rows(ctx, Path(tmp))
    samples = sorted(BAGS.glob('sample_*.mcap'))
    if not samples:
        yield Row(WHAT, 'sample bags', None, '', status='not available',
                  note=f'not available: no {BAGS}/sample_*.mcap')
    for path in samples:
        name = path.name
        result = replay(path, with_recorded=True)
        yield _replay_row(ctx, ReplayedBag(path, result, result.messages['total_read']),
                          f'bags/{name} (live monitor recording)',
                          error=_live_error(result, path))
