"""The command path's targets (doc/command.md), measured on whole runs of the real processes.

* command-latency: ground-speed sample → CAN frame, 8 rows, quiet and with two CPU-bound
  processes beside it (one in --quick). The demo's command path (`demo.sync_process`: the sync
  node's shell, its command process at its real-time priority, the simulated drives in a
  process of their own) in profile velocity, where a sample sends its rows' frames at once (in
  CSP the next SYNC step sends them, up to one SYNC period later), fed 50 Hz samples by this
  process over DDS. The
  figure is the command process's own: from the shell's receive time of a sample (the same
  monotonic clock in both processes), across the channel, to the last row's RPDO sent. DDS
  delivery to the shell comes on top and is not in it.
* demo-runs under load: `planter demo` of the 4-row scene (CSP, SYNC 10 ms, the field run's
  speed change, turns and stop), `--runs` times (default 10), two CPU hogs beside each run
  (one in --quick).
  Per run: the verdict, the drives' watchdog trips, each row's spacing error RMS from the
  replay of the run's bag (the plants where the monitor places them: the distance integrated
  from the recorded ground speed; not the command process's own view), and the SYNC interval
  as the command process sent it (p1 and p99 of every interval, the largest) next to the
  largest SYNC gap the drives saw on their own clock.

The hogs: bench.hogs. The host's load average is noted with each run: timings on a
shared host say little without it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
import io
import math
import os
from pathlib import Path
import tempfile
import time
from typing import Any, TypedDict
import uuid

from geometry_msgs.msg import TwistStamped
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import String

from planter_ros import interfaces
from planter_ros.control.loop_timing import PeriodStats
from planter_ros.demo.options import DemoOptions
from planter_ros.demo.run import DemoResult, prepare
from planter_ros.demo.sync_process import SyncProcess, SyncProcessSettings
from planter_ros.design import to_json
from planter_ros.host.dds_domain import claim_private_domain
from planter_ros.recording.replay import replay
from planter_ros.scene import default_scene_path
from planter_ros.sim.runs import five_bar_design_message

from ..hogs import QUICK_HOG_NICENESS, cpu_hogs
from ..registry import BenchContext, Row, Target, bench_case
from .sync import row_parameters
from ..timing import Timing, from_samples

RATE = 50.0                     # Hz, ground-speed samples of the latency case
LATENCY_ROWS = 8
LATENCY_TARGET = 1e-3           # s, p99
SETTLE = 1.0                    # s between the design taking effect and the first sample
QUICK_SETTLE = 0.3              # --quick: the angles take tens of ms; the figures mean nothing
WHAT_LATENCY = (f"command path, {LATENCY_ROWS} rows, profile velocity: ground-speed sample "
                "(shell's receive) → last row's CAN frame sent")
WHAT_RUNS = '4-row demo in CSP (SYNC 10 ms), CPU hogs beside each run'
SCENE = 'tomato_4row.yaml'
RUNS = 10
SPACING_TARGET = 0.005          # spacing error RMS per row, fraction of d
SYNC_TOLERANCE = 1e-3           # s: SYNC interval p1 and p99 within the period ± this


def load_average() -> float | None:
    """The host's 1-minute load average (None where /proc/loadavg is not there)."""
    try:
        with open('/proc/loadavg', encoding='ascii') as f:
            return float(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def _load(before: float | None, after: float | None) -> str:
    if before is None or after is None:
        return 'load average unknown'
    return f'load average {before:.1f}→{after:.1f}'


def latency_timing(histogram: dict[str, Any]) -> tuple[Timing, int, float]:
    """Timing (median = p50, p10–p90, p99) and (count, max) of a PeriodStats histogram of
    single latencies."""
    stats = PeriodStats.from_histogram(histogram)
    if not stats.gaps:
        raise RuntimeError('the command process timed no ground-speed sample')
    q = stats.quantile
    return (Timing(q(0.5), q(0.1), q(0.9), stats.gaps, 1, q(0.99)),
            stats.gaps, stats.max_gap)


def latency_run(seconds: float, rows: int = LATENCY_ROWS, hogs: int = 0,
                timeout: float = 120.0, parameters: Sequence[tuple[str, object]] = (),
                quick: bool = False
                ) -> dict[str, Any]:              # the command process's report (JSON)
    """One run of the demo's command path with `rows` rows in profile velocity, fed RATE Hz
    ground-speed samples for `seconds` s (`hogs` CPU hogs beside it meanwhile; `parameters`:
    more (name, value) of the sync node; `quick`: the smoke run's shorter settling and hogs at
    the lowest priority, bench.hogs); returns the command process's final report."""
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    domain = claim_private_domain()
    channel = f'planter-bench-latency-{uuid.uuid4().hex[:8]}'
    sync = SyncProcess(SyncProcessSettings(
        domain, channel, tuple(range(1, rows + 1)), interfaces.NAMESPACE,
        tuple(row_parameters(rows).items()) + (
            ('can_interface', 'virtual'), ('can_channel', channel),
            ('operation_mode', 'velocity')) + tuple(parameters), 'error'))
    context = Context()
    rclpy.init(context=context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    node = Node('latency_source', context=context, namespace=interfaces.NAMESPACE)
    speed_pub = interfaces.GROUND_SPEED.publisher(node)
    design_pub = interfaces.DESIGN.publisher(node)
    try:
        sync.wait_for('ready', timeout)
        design_pub.publish(String(data=to_json(five_bar_design_message(spacing=0.2))))
        deadline = time.monotonic() + timeout
        while sync.status.spacing is None:          # the design is in force
            if time.monotonic() > deadline:
                raise TimeoutError(f'the sync node took no design within {timeout:g} s')
            sync.poll(0.05)
        msg = TwistStamped()
        # the design's planting angles are worked out in a thread of the command process
        # (tens of ms, once): not what is measured here
        time.sleep(QUICK_SETTLE if quick else SETTLE)
        with cpu_hogs(hogs, QUICK_HOG_NICENESS if quick else 0):
            start = next_pub = time.monotonic()
            k = 0
            while next_pub < start + seconds:
                time.sleep(max(next_pub - time.monotonic(), 0.0))
                msg.twist.linear.x = 0.2 + 0.001 * (k % 50)
                speed_pub.publish(msg)
                k += 1
                next_pub += 1.0 / RATE
                sync.poll(0.0)
    finally:
        final = sync.stop()
        report = final.flat() if final is not None else {}
        node.destroy_node()
        context.try_shutdown()
    if not report.get('sample_to_frame_histogram'):
        raise RuntimeError('the command process sent no final report')
    return report


@bench_case('command-latency')
def command_latency(ctx: BenchContext) -> Iterator[Row]:
    # --quick: 1.5 s at 50 Hz is 76 samples per run (the smoke test wants > 50)
    seconds = ctx.n(20.0, 1.5)
    for hogs in (0, ctx.hogs):
        ctx.progress(f'  {LATENCY_ROWS} rows, {seconds:g} s of {RATE:g} Hz samples, '
                     f'{hogs} CPU hogs beside it ...')
        before = load_average()
        report = latency_run(seconds, hogs=hogs, quick=ctx.quick)
        timing, count, worst = latency_timing(report['sample_to_frame_histogram'])
        trips = len(report.get('watchdog_trips', []))
        yield Row(WHAT_LATENCY, 'quiet' if not hogs else f'{hogs} CPU hogs beside it', 1,
                  'sample', timing, error_of='no error defined: timings only',
                  # the target is set beside the hogs (quiet, an idle core's wake-up shows:
                  # printed for comparison, not judged)
                  targets=[Target('p99 ≤ 1 ms', timing.tail <= LATENCY_TARGET)] if hogs else [],
                  note=f'{count} samples: p50 {timing.median * 1e3:.2f} ms, p99 '
                       f'{timing.tail * 1e3:.2f} ms, max {worst * 1e3:.2f} ms; {trips} watchdog '
                       f'trip(s); {_load(before, load_average())}',
                  extra={'hogs': hogs, 'rows': LATENCY_ROWS, 'samples': count,
                         'p50_s': timing.median, 'max_s': worst, 'watchdog_trips': trips,
                         'load_average': before})


class RunFigures(TypedDict):
    """One demo run's figures (s; spacing RMS as a fraction of d per row label)."""

    passed: bool
    verdict: str
    trips: int
    rows: dict[str, float]
    sync: PeriodStats
    period: float
    drive_sync_max: float
    cpu: float                   # s of this process's CPU in the run (demo_runs)


def run_figures(result: DemoResult, bag: str, cpu: float) -> RunFigures:
    """One demo run's figures: verdict, trips, each row's spacing error RMS over d from the
    replay of its bag, the SYNC intervals (a PeriodStats), the drives' largest SYNC gap and
    `cpu` (s of the demo process's CPU in the run)."""
    report = result.report or {}
    rows: dict[str, float] = {}
    try:
        replayed = replay(bag)
    except Exception as exc:         # noqa: BLE001 - a run without a usable bag is a figure too
        replayed, rows = None, {'(replay)': math.nan}
        result.verdict.reasons.append(f'replay: {exc}')
    if replayed is not None:
        for row, summary in zip(replayed.rows, replayed.row_summaries):
            mean, sigma = summary['spacing_error_mean'], summary['spacing_error_std']
            if row.enabled:
                rows[row.label] = (math.nan if mean is None or sigma is None else
                                   math.hypot(mean, sigma) / summary['design_spacing'])
    sync = (PeriodStats.from_histogram(report['sync_histogram'])
            if report.get('sync_histogram') else PeriodStats())
    drives = [v for v in (report.get('drive_sync') or {}).values() if v.get('syncs')]
    return {'passed': result.verdict.passed, 'verdict': result.verdict.line(),
            'trips': len(report.get('watchdog_trips', [])), 'rows': rows, 'sync': sync,
            'period': next((v['period'] for v in drives if v.get('period')), 0.01),
            'drive_sync_max': max((v['gaps']['max'] for v in drives), default=math.nan),
            'cpu': cpu}


def _silent(text: str) -> None:
    pass


def demo_runs(runs: int, duration: float, hogs: int,
              progress: Callable[[str], None] = _silent, hog_niceness: int = 0
              ) -> list[tuple[float, RunFigures, tuple[float | None, float | None]]]:
    """`runs` 4-row demo runs of `duration` s, `hogs` CPU hogs (at `hog_niceness`) beside
    each; per run (seconds, figures, load average before and after). The figures' `cpu` is
    the CPU time of this process in the run: the demo's own graph (design node, monitor,
    simulated sensors), its report and the replay of its bag, not the command path's
    processes."""
    out: list[tuple[float, RunFigures, tuple[float | None, float | None]]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(runs):
            bag = str(Path(tmp) / f'run{k}.mcap')
            before = load_average()
            with cpu_hogs(hogs, hog_niceness):
                demo = prepare(DemoOptions(scene=str(default_scene_path(SCENE)),
                                           duration=duration, bag=bag),
                               out=io.StringIO(), install_signals=False, log_level='error')
                t0, cpu0 = time.perf_counter(), time.process_time()
                demo.run()
                seconds, cpu = time.perf_counter() - t0, time.process_time() - cpu0
            if demo.result is None:          # run() returns with its result made
                raise RuntimeError('the demo run gave no result')
            figures = run_figures(demo.result, bag, cpu)
            out.append((seconds, figures, (before, load_average())))
            progress(f'  run {k + 1}/{runs}: {"PASS" if figures["passed"] else "FAIL"}, '
                     f'{figures["trips"]} trip(s), spacing RMS '
                     + ', '.join(f'{100 * v:.2f}' for v in figures['rows'].values())
                     + ' % of d')
    return out


def _worst(values: Iterable[float]) -> float:
    """The largest of `values` (NaN if any is NaN or there are none)."""
    seen = list(values)
    return math.nan if not seen or any(math.isnan(v) for v in seen) else max(seen)


def _sync_text(stats: PeriodStats, period: float) -> str:
    if not stats.gaps:
        return 'no SYNC sent'
    return (f'SYNC interval p1 {stats.quantile(0.01) * 1e3:.1f} ms, p99 '
            f'{stats.quantile(0.99) * 1e3:.1f} ms, max {stats.max_gap * 1e3:.1f} ms '
            f'(period {period * 1e3:g} ms, {stats.gaps} intervals)')


def _sync_within(stats: PeriodStats, period: float) -> bool:
    return bool(stats.gaps) and (stats.quantile(0.01) >= period - SYNC_TOLERANCE
                                 and stats.quantile(0.99) <= period + SYNC_TOLERANCE)


@bench_case('demo-runs under load')
def demo_runs_under_load(ctx: BenchContext) -> Iterator[Row]:
    runs = ctx.runs or ctx.n(RUNS, 1)
    duration = ctx.n(30.0, 8.0)
    ctx.progress(f'  {runs} run(s) of {duration:g} s, {ctx.hogs} CPU hog(s) beside each ...')
    results = demo_runs(runs, duration, ctx.hogs, ctx.progress, ctx.hog_niceness)
    error_of = ("the run's worst row: spacing error RMS over d, replay of the run's bag")
    pooled = PeriodStats()
    for k, (seconds, fig, (before, after)) in enumerate(results):
        pooled.merge(fig['sync'])
        rms = ', '.join(f'{label} {100 * v:.2f} %' for label, v in fig['rows'].items())
        reason = '' if fig['passed'] else f" ({fig['verdict'].split(': ', 2)[-1]})"
        worst = _worst(fig['rows'].values())
        yield Row(WHAT_RUNS, f"run {k + 1}: {'PASS' if fig['passed'] else 'FAIL'}", 1, 'run',
                  from_samples([seconds]), error=worst, error_of=error_of,
                  targets=[Target('spacing RMS ≤ 0.5 % of d per row',
                                  worst <= SPACING_TARGET)],
                  note=f"verdict {'PASS' if fig['passed'] else 'FAIL'}{reason}; "
                       f"{fig['trips']} watchdog trip(s); spacing RMS of d: {rms}; "
                       f"{_sync_text(fig['sync'], fig['period'])}; the drives' largest SYNC "
                       f"gap {fig['drive_sync_max'] * 1e3:.1f} ms; the demo process's CPU "
                       f"{fig['cpu']:.1f} s (its own graph: the design node, the monitor, the "
                       f"simulated sensors; its report and replay); {_load(before, after)}",
                  extra={'run': k + 1, 'hogs': ctx.hogs, 'passed': fig['passed'],
                         'watchdog_trips': fig['trips'],
                         'spacing_rms_of_d': fig['rows'],
                         'sync_p1_s': fig['sync'].quantile(0.01),
                         'sync_p99_s': fig['sync'].quantile(0.99),
                         'sync_max_s': fig['sync'].max_gap,
                         'drive_sync_max_s': fig['drive_sync_max'],
                         'demo_process_cpu_s': fig['cpu'], 'load_average': before})
    figures = [fig for _, fig, _ in results]
    period = figures[0]['period']
    worst = _worst(_worst(f['rows'].values()) for f in figures)
    trips = sum(f['trips'] for f in figures)
    passed = sum(f['passed'] for f in figures)
    yield Row(WHAT_RUNS, f'all {runs} run(s)', runs, 'run',
              from_samples([seconds for seconds, _, _ in results]), error=worst,
              error_of=error_of,
              targets=[Target('0 watchdog trips', trips == 0),
                       Target(f'{runs}/{runs} PASS', passed == runs),
                       Target('spacing RMS ≤ 0.5 % of d per row', worst <= SPACING_TARGET),
                       Target('SYNC interval p99 within ±1 ms', _sync_within(pooled, period)
                              and all(_sync_within(f['sync'], period) for f in figures))],
              note=f'{ctx.hogs} CPU hog(s) beside each run; {passed}/{runs} PASS, {trips} '
                   f'watchdog trip(s), worst row spacing RMS '
                   f'{100 * worst:.2f} % of d; pooled {_sync_text(pooled, period)}',
              extra={'runs': runs, 'hogs': ctx.hogs, 'duration_s': duration, 'passed': passed,
                     'watchdog_trips': trips, 'worst_spacing_rms_of_d': worst,
                     'sync_p1_s': pooled.quantile(0.01), 'sync_p99_s': pooled.quantile(0.99),
                     'sync_max_s': pooled.max_gap})
