"""Season analysis rows: `planter analyze` of a simulated season with 1 and 2 local workers.

The season: `planter simulate`'s runs (4 rows, one minute each, varied speeds, stops, glitches,
stalls, curves, GNSS, a tray with empty cells and doubles; written in parallel on the local
cluster, its own row) in a temporary directory, each run copied to reach the season's size (the
analysis reads and replays every file; the copies cost what distinct runs of the same kind
would). Each analysis is the command's own code path (analysis.season.run on
analysis.engine.cluster) into fresh tables, timed from the first task submitted to the last
result written; the cluster's start and the workers' imports (once per worker) are timed apart.

Wall clock and CPU time side by side, because the machine is shared: the load average before
each run; bags/s and × real time (bag seconds over wall seconds) in total and per worker; the
workers' own wall and CPU time per bag (the bags table); the CPU time of this process (client
and scheduler) per bag; and from those the CPU-time throughput per core, bag seconds over all
the CPU seconds the analysis took (workers, client, scheduler), which other processes on the
cores do not inflate. Scaling 1 → 2 workers both ways: wall clock (rate with 2 over twice the
rate with 1: what this machine gave, other load included) and CPU (CPU per bag with 1 over CPU
per bag with 2: what two free cores would give, i.e. whether a second worker makes each bag
dearer). The targets are judged on each worker count's fastest repeat, the one least disturbed
by other processes (as timeit's best of N), and the note gives the median's figures too. A last
row times empty tasks through the same cluster: Dask's own cost per task.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import ExitStack, contextmanager
import math
import os
from pathlib import Path
import shutil
import statistics
import tempfile
import time
from typing import Any

import pyarrow.dataset as ds
import pyarrow.parquet as pq

from planter_ros.analysis import losses, season as seasons
from planter_ros.analysis.bags import find_bags, identity
from planter_ros.analysis.engine import check_workers, cluster, completed
from planter_ros.analysis.tables import load_pyarrow, plant_columns, plant_dicts
from planter_ros.analysis.task import model_version, warm_up
from planter_ros.recording.replay import replay
from planter_ros.sim.season import BagSummary, bag_name, simulate_bag
from planter_ros.sim.tray import TrayShares

from ..registry import BenchContext, Row, Target, bench_case
from ..timing import from_samples

WHAT = 'season analysis (planter analyze)'
REAL_TIME_TARGET = 3000.0       # × real time per worker (per core)
EFFICIENCY_TARGET = 0.8         # 1 -> 2 local workers
ERROR_OF = ('max |Parquet value − planter replay --json value| over every field of every '
            'plant of one bag (checked on the first bag of the season)')
ROWS = 4
TRAY = (0.02, 0.01)        # empty cells, doubles: planter simulate's defaults


def _noop(i: int) -> int:
    return i


@contextmanager
def _cluster(workers: int | None, shared: Any, in_process: bool = False
             ) -> Iterator[Any]:                                   # a distributed.Client
    """`shared` (--quick: the client of the case's one 2-worker cluster; the figures of a quick
    run mean nothing, a cluster's start is seconds of CPU) or a local cluster of its own
    (`in_process`: the scheduler and its one worker in this process, no worker process
    started)."""
    if shared is not None:
        yield shared
        return
    with cluster(workers=workers, in_process=in_process) as client:
        yield client


def _simulate(directory: Path, runs: int, duration: float, shared: Any = None
              ) -> tuple[float, int]:
    """Simulate `runs` runs into `directory` on the local cluster: (seconds, workers)."""
    with _cluster(None, shared) as client:
        workers = check_workers(client, warm_up, model_version(), 'the local cluster')
        started = time.monotonic()
        arguments = [(str(directory / bag_name(0, k)), 0, k, duration, ROWS, TrayShares(*TRAY))
                     for k in range(runs)]
        for _, _, error in completed(client, simulate_bag, arguments):
            if error is not None:
                raise error
        seconds = time.monotonic() - started
    return seconds, workers


def _analyse(bags: Sequence[str | Path], out: Path, workers: int, shared: Any = None
             ) -> tuple[Any, float, float, float, float]:        # report: analysis.season's
    """One analysis of `bags` into fresh tables at `out` with `workers` local workers:
    (report, seconds to start the cluster and warm the workers up, CPU seconds during the
    analysis of this process (the client and the scheduler) and of the worker processes, load
    average before it)."""
    version = model_version()
    started = time.monotonic()
    # --quick (`shared` given): the 1-worker analysis on an in-process cluster, not two more
    # processes (a nanny and its worker) each loading Dask and the analysis (seconds of CPU)
    in_process = shared is not None and workers == 1
    with _cluster(workers, shared if workers == 2 else None, in_process) as client:
        check_workers(client, warm_up, version, 'the local cluster')
        startup = time.monotonic() - started
        root = seasons.analysed_root([Path(bags[0]).parent])
        load_pyarrow()                   # what run() loads before its clock starts
        load = os.getloadavg()[0]
        with seasons.Season(out, root) as season:
            # the bench's season is copies of a few runs, and a bag is its content (a real
            # season's copies are one bag: season.plan): each copy is analysed as a bag here
            options = seasons.options_key({}, None)
            keys = []
            for path, name in seasons.bag_keys(bags, root).items():
                size, mtime_ns = identity(path)
                keys.append(seasons.BagKey(name, size, mtime_ns, version, options, path,
                                           f'bench-copy:{name}'))
            before = client.run(time.process_time)
            cpu = time.process_time()
            report = seasons.run(season, client, keys, {}, None)
            cpu = time.process_time() - cpu
            after = client.run(time.process_time)
    # every CPU second of the worker processes (all their threads: the bags, Dask's comms);
    # an in-process worker's are this process's, already in `cpu`
    workers_cpu = 0.0 if in_process else sum(after[w] - before[w] for w in before)
    return report, startup, cpu, workers_cpu, load


def _task_overhead(count: int, shared: Any = None) -> float:
    """Seconds per empty task through a 2-worker local cluster (submit → result gathered)."""
    with _cluster(2, shared) as client:
        list(completed(client, _noop, [(i,) for i in range(50)]))       # warm
        started = time.monotonic()
        done = sum(1 for _ in completed(client, _noop, [(i,) for i in range(count)]))
        return (time.monotonic() - started) / done


def _replay_error(bag: str | Path, out: Path) -> float:
    """Max |Parquet − replay JSON| over the plants of `bag` (None-for-None must match)."""
    expected = replay(str(bag)).plants.rows()         # as replay --json gives them
    table = ds.dataset(out / 'plants').to_table(filter=ds.field('bag') == Path(bag).name)
    got = plant_dicts(table)
    if len(got) != len(expected):
        raise RuntimeError(f'{bag}: {len(got)} plants in the table, replay finds '
                           f'{len(expected)}')
    worst = 0.0
    for a, b in zip(got, expected):
        if a.keys() != b.keys():
            raise RuntimeError(f'{bag}: plant fields differ from replay: {sorted(a)}')
        for key in a:
            if (a[key] is None) != (b[key] is None):
                raise RuntimeError(f'{bag}: {key} null in one and not the other')
            mine, theirs = a[key], b[key]
            if mine is not None and theirs is not None:
                worst = max(worst, abs(mine - theirs) if math.isfinite(theirs) else 0.0)
    return worst


QUICK_CLUSTER = 'local Dask cluster, 2 workers'


def _two_workers() -> Any:
    return cluster(workers=2)


@bench_case('analyze')
def season_analysis(ctx: BenchContext) -> Iterator[Row]:
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    # --quick: one 2-worker cluster for the simulation, the 2-worker analysis and the empty
    # tasks, and for the 'losses' case (a full run starts one for each, its start timed apart)
    shared = ctx.shared(QUICK_CLUSTER, _two_workers) if ctx.quick else None
    yield from _season_rows(ctx, shared)


def _season_rows(ctx: BenchContext, shared: Any) -> Iterator[Row]:
    count, runs = ctx.n(200, 8), ctx.n(20, 2)
    duration = ctx.n(60.0, 10.0)
    repeats = ctx.n(3, 1)
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        made, season_dir = tmp / 'runs', tmp / 'season'
        made.mkdir()
        season_dir.mkdir()
        ctx.progress(f'  simulating {runs} runs of {duration:.0f} s ...')
        seconds, sim_workers = _simulate(made, runs, duration, shared)
        originals = sorted(made.glob('*.mcap'))
        per_worker = runs * duration / seconds / sim_workers
        yield Row(WHAT, f'planter simulate: {runs} runs of {duration:.0f} s, {ROWS} rows',
                  runs, 'bag', from_samples([seconds]),
                  note=f'{runs * duration / seconds:.0f}× real time on {sim_workers} workers '
                       f'({per_worker:.0f}× per worker), closed loop + monitor model + MCAP',
                  extra={'times_real_time': runs * duration / seconds, 'workers': sim_workers,
                         'times_real_time_per_worker': per_worker})
        for k in range(count):
            shutil.copyfile(originals[k % runs], season_dir / f'bag_{k:04d}.mcap')
        bags = find_bags([season_dir])
        size = sum(b.stat().st_size for b in bags)
        rates, cpu_per_bag = {}, {}
        for workers in (1, 2):
            ctx.progress(f'  analysing {count} bags with {workers} worker(s) ...')
            walls, startups, runs_of = [], [], []
            for rep in range(repeats):
                out = tmp / f'out_{workers}_{rep}'
                report, startup, client_cpu, workers_cpu, load = _analyse(bags, out, workers,
                                                                          shared)
                if report.analysed != count:
                    raise RuntimeError(f'{report.analysed} of {count} bags analysed: '
                                       f'{report.failures[:1] or report.not_done[:1]}')
                walls.append(report.seconds)
                startups.append(startup)
                runs_of.append((report.seconds, out, report, client_cpu, workers_cpu, load))
                ctx.progress(f'    {report.seconds:.2f} s, load average {load:.2f}')
            timing = from_samples(walls)
            best, out, report, client_cpu, workers_cpu, load = min(runs_of, key=lambda r: r[0])
            loads = [r[5] for r in runs_of]
            table = pq.read_table(out / 'bags', columns=[
                'analysis_seconds', 'analysis_cpu_seconds']).to_pydict()
            worker_s = statistics.median(table['analysis_seconds'])
            worker_cpu = statistics.median(table['analysis_cpu_seconds'])
            bag_cpu = statistics.mean(table['analysis_cpu_seconds'])
            bag_seconds = report.data_seconds
            speed = bag_seconds / best
            median_speed = bag_seconds / timing.median
            rates[workers] = count / best
            # every CPU second of the analysis: the worker processes', this process's (client
            # and scheduler); bag seconds per CPU second = × real time per core
            cpu_per_bag[workers] = (workers_cpu + client_cpu) / count
            cpu_speed = bag_seconds / count / cpu_per_bag[workers]
            # the same run's wall time shared among its workers, less their own time per bag
            overhead = workers * best / count - statistics.mean(table['analysis_seconds'])
            targets = [Target(f'≥ {REAL_TIME_TARGET:.0f}× real time per worker (run: '
                              f'{speed / workers:.0f}× wall clock; {cpu_speed:.0f}× per core '
                              'by CPU time)', speed / workers >= REAL_TIME_TARGET)]
            efficiency = cpu_efficiency = None
            if workers == 2:
                efficiency = rates[2] / (2 * rates[1])
                cpu_efficiency = cpu_per_bag[1] / cpu_per_bag[2]
                targets.append(Target(f'≥ 80 % efficiency 1 → 2 workers (run: '
                                      f'{efficiency:.0%} wall clock, {cpu_efficiency:.0%} by '
                                      'CPU time)', efficiency >= EFFICIENCY_TARGET))
            error = _replay_error(bags[0], out) if workers == 1 else None
            yield Row(WHAT, f'{count} bags of {duration:.0f} s, {workers} local worker(s)',
                      count, 'bag', timing, error=error, error_of=ERROR_OF if error is not None
                      else '', targets=targets,
                      note=f'fastest of {len(walls)}: {speed:.0f}× real time '
                           f'({speed / workers:.0f}× per worker), median {median_speed:.0f}×; '
                           f'load average before the runs {min(loads):.1f}-{max(loads):.1f} '
                           f'(2 cores shared); CPU per bag {cpu_per_bag[workers] * 1e3:.1f} ms '
                           f'(worker processes {workers_cpu / count * 1e3:.1f}, of which the '
                           f'bags themselves {bag_cpu * 1e3:.1f}; client and scheduler '
                           f'{client_cpu / count * 1e3:.1f}) = {cpu_speed:.0f}× real time per '
                           f'core; worker wall per bag {worker_s * 1e3:.1f} ms (median; CPU '
                           f'{worker_cpu * 1e3:.1f} ms, the rest waiting for a core), other '
                           f'cost per bag {overhead * 1e3:.1f} ms; '
                           f'{size / count / 1e6:.2f} MB per bag, read at '
                           f'{size / best / 1e6:.0f} MB/s; cluster start + imports '
                           f'{statistics.median(startups):.1f} s (not in the time)'
                           + (f'; scaling efficiency {efficiency:.0%} wall clock, '
                              f'{cpu_efficiency:.0%} by CPU time' if efficiency else '')
                           + ('; --quick: the worker in this process, its CPU under client '
                              'and scheduler' if shared is not None and workers == 1 else ''),
                      extra={'workers': workers, 'bags': count, 'bag_seconds': bag_seconds,
                             'bytes': size, 'times_real_time': speed,
                             'times_real_time_per_worker': speed / workers,
                             'times_real_time_median': median_speed,
                             'times_real_time_per_core_cpu': cpu_speed,
                             'cpu_seconds_per_bag': cpu_per_bag[workers],
                             'client_cpu_seconds_per_bag': client_cpu / count,
                             'worker_process_cpu_seconds_per_bag': workers_cpu / count,
                             'worker_seconds_per_bag': worker_s,
                             'worker_cpu_seconds_per_bag': worker_cpu,
                             'other_seconds_per_bag': overhead,
                             'load_average': loads,
                             'startup_seconds': statistics.median(startups),
                             'read_bytes_per_second': size / best,
                             'scaling_efficiency': efficiency,
                             'scaling_efficiency_cpu': cpu_efficiency})
    tasks = ctx.n(2000, 200)
    ctx.progress(f'  {tasks} empty tasks ...')
    per_task = _task_overhead(tasks, shared)
    yield Row(WHAT, f'Dask alone: {tasks} empty tasks, 2 local workers', 1, 'task',
              from_samples([per_task]),
              note=f'{1 / per_task:.0f} tasks/s: the scheduler and client cost of one bag',
              extra={'tasks_per_second': 1 / per_task})


LOSSES = 'injected losses (planter simulate → planter analyze)'
LOSS_TRAY = (0.05, 0.03)        # empty cells, doubles: enough of both in short runs


def _simulate_season(directory: Path, count: int, duration: float, rows: int,
                     tray: tuple[float, float], shared: Any = None) -> dict[str, BagSummary]:
    """`count` distinct runs of `duration` s on the local cluster: {bag name: summary}."""
    names = [bag_name(1, k) for k in range(count)]
    out: dict[str, BagSummary] = {}
    with _cluster(None, shared) as client:
        check_workers(client, warm_up, model_version(), 'the local cluster')
        arguments = [(str(directory / name), 1, k, duration, rows, TrayShares(*tray))
                     for k, name in enumerate(names)]
        for i, summary, error in completed(client, simulate_bag, arguments):
            if error is not None:
                raise error
            out[names[i]] = summary
    return out


@bench_case('losses')
def injected_losses(ctx: BenchContext) -> Iterator[Row]:
    """A season simulated with a tray of empty cells and doubles and the usual glitches (speed
    drop-outs among them), analysed by `planter analyze`'s code path; each bag's plants from
    the Parquet table against what its cup sensors read (analysis.losses): injected against
    counted, every difference by its place, and the ISO misses and multiples by their cause."""
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    count, duration = ctx.n(200, 4), ctx.n(15.0, 12.0)
    with ExitStack() as stack:
        # --quick: the 2-worker cluster of 'analyze' for the simulation and the analysis
        shared = ctx.shared(QUICK_CLUSTER, _two_workers) if ctx.quick else None
        name = stack.enter_context(tempfile.TemporaryDirectory())
        tmp = Path(name)
        season_dir = tmp / 'season'
        season_dir.mkdir()
        ctx.progress(f'  simulating {count} runs of {duration:.0f} s with a tray of '
                     f'{LOSS_TRAY[0]:.0%} empty cells, {LOSS_TRAY[1]:.0%} doubles ...')
        started = time.monotonic()
        summaries = _simulate_season(season_dir, count, duration, ROWS, LOSS_TRAY, shared)
        simulated = time.monotonic() - started
        bags = find_bags([season_dir])
        ctx.progress(f'  analysing {count} bags ...')
        report, _, _, _, _ = _analyse(bags, tmp / 'out', 2, shared)
        ctx.progress('  accounting ...')
        plants = ds.dataset(tmp / 'out' / 'plants').to_table()
        table = pq.read_table(tmp / 'out' / 'bags', columns=[
            'bag', 'summary.spacing_quality.miss_index',
            'summary.spacing_quality.multiple_index',
            'summary.spacing_quality.spacings']).to_pylist()
        total, misses, multiples, dropouts, sensor = losses.empty_account(), 0, 0, 0, True
        for entry in table:
            mine = plants.filter(ds.field('bag') == entry['bag'])
            readings = replay(season_dir / entry['bag']).seedling_readings
            one = losses.account(readings, losses.Instants.of(
                *plant_columns(mine, losses.INSTANT_COLUMNS)))
            losses.add(total, one)
            n = entry['summary.spacing_quality.spacings'] or 0
            misses += round((entry['summary.spacing_quality.miss_index'] or 0.0) * n)
            multiples += round((entry['summary.spacing_quality.multiple_index'] or 0.0) * n)
            events = summaries[entry['bag']]['events']
            dropouts += sum(g['kind'] == 'dropout' for g in events['glitches'])
            sensor &= (events['empty_cells'] == one['injected']['empty']
                       and events['double_cells'] == one['injected']['double'])
        exact = losses.is_exact(total) and sensor
        iso = (misses == total['misses_of_empties'] + total['misses_kinematic']
               and multiples == total['multiples_of_doubles'] + total['multiples_kinematic'])
        text = losses.lines(total, report.analysed, misses, multiples)
        for line in text:
            ctx.progress(line)
        yield Row(LOSSES, f'{count} bags of {duration:.0f} s, {ROWS} rows', count, 'bag',
                  from_samples([simulated + report.seconds]),
                  targets=[Target('injected empty cells and doubles = counted + read outside '
                                  'the planting instants, exactly', exact),
                           Target('ISO misses and multiples = runs of empty cells, doubles '
                                  'and the kinematic ones, exactly', iso)],
                  note=' / '.join(line.strip() for line in text)
                  + f'; {dropouts} ground-speed drop-outs injected (every instant inside one '
                    'reported, interpolated, flagged input_gap); the simulated tray reads '
                    'what the simulation says it put in (events: empty_cells, double_cells): '
                  + ('yes' if sensor else 'NO'),
                  extra={'accounting': total, 'iso_misses': misses,
                         'iso_multiples': multiples, 'dropouts': dropouts, 'exact': exact})
