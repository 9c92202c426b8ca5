"""Every planting instant accounted for: the seedling sensor's empty cups and doubles and the
instants inside input gaps are counted exactly, in the plants, the indices and the tables."""
import numpy as np

from planter_ros.prediction import (
    PLANT_FIELDS, Plants, SeedlingAccount, seedling_spacings, spacing_quality, status_counts,
    summarize)
from planter_ros.recording.replay import replay
from planter_ros.sim.field import Curve
from planter_ros.sim.season import Glitch, RunPlan, machine_rows, simulate_plan, write_monitor_bag

D = 0.2


def instants(n, row=0, t0=100.0, spacing=D):
    table = np.full((n, len(PLANT_FIELDS)), np.nan)
    plants = Plants.from_table(table)
    plants.index[:] = np.arange(n)
    plants.time[:] = t0 + np.arange(n)
    plants.position[:] = spacing * np.arange(n)
    plants.spacing[:] = np.concatenate(([np.nan], np.full(n - 1, spacing)))
    plants.spacing_error[:] = plants.spacing - D
    plants.row[:] = row
    plants.input_gap[:] = 0.0
    return plants


def test_empty_cups_and_doubles_become_misses_and_multiples():
    counts = [1, 1, 0, 1, 2, 1, 0, 0, 1, 1]
    plants = instants(len(counts))
    account = SeedlingAccount()
    for k, c in enumerate(counts):
        account.add_reading(0, 99.5 + k, c)             # half a cycle before each instant
    out = account.apply(plants, np.full(len(plants), D))
    assert [int(s) for s in out.status] == [0, 0, 1, 0, 2, 0, 1, 1, 0, 0]
    assert np.all(out.reason == 0)
    # spacing between the seedlings in the ground: over one empty 2d, over two empties 3d
    np.testing.assert_allclose(out.spacing, [np.nan, D, np.nan, 2 * D, D, D, np.nan, np.nan,
                                             3 * D, D], equal_nan=True)
    x, x_d = seedling_spacings(out, D)
    quality = spacing_quality(x, x_d)
    n = quality['spacings']
    assert n == 6 + 1                                    # 6 spacings and the double's 0
    assert round(quality['miss_index'] * n) == 2        # the two runs of empties
    assert round(quality['multiple_index'] * n) == 1    # the double
    counted = status_counts(out)
    assert (counted['planted'], counted['empty'], counted['double'], counted['unknown']) == \
        (6, 3, 1, 0)
    assert counted['seedlings'] == 6 + 2
    # no sensor: unknown, taken as one seedling each: the kinematic indices
    bare = SeedlingAccount().apply(instants(len(counts)), np.full(len(counts), D))
    assert np.all(bare.status == 3) and np.all(bare.reason == 1)
    assert summarize(bare, D)['spacing_quality']['miss_index'] == 0.0
    # a cycle the sensor missed: unknown with its reason, the next one read again
    account = SeedlingAccount()
    for k in (0, 1, 3):
        account.add_reading(0, 99.5 + k, 1)
    partial = account.apply(instants(4), np.full(4, D))
    assert [int(r) for r in partial.reason] == [0, 0, 2, 0]


def test_injected_losses_in_a_simulated_run_are_counted_exactly(tmp_path):
    """A two-row run with a tray of 10 % empty cells and 5 % doubles and a 1.2 s ground-speed
    drop-out: every sensed instant carries its own reading; the statuses, the ISO misses and
    multiples and the instants in the gap equal what was injected, live and in replay."""
    rows = 2
    plan = RunPlan(index=1, seed=21, duration=30.0, rows=machine_rows(rows), cruise=0.3,
                   change=1.0, curves=(Curve(40.0, 41.0, 20.0),),
                   glitches=(Glitch('dropout', 14.0, length=1.2),), drive_lag=0.05,
                   empty_rate=0.1, double_rate=0.05)
    plan = RunPlan(**{**plan.__dict__, 'curves': ()})
    run = simulate_plan(plan)
    summary = write_monitor_bag(run, tmp_path / 'run.mcap')
    result = replay(tmp_path / 'run.mcap', with_recorded=True)
    plants = result.plants
    live = result.recorded_plants
    order = np.lexsort((plants.index, plants.row))
    live_order = np.lexsort((live[:, 0], live[:, PLANT_FIELDS.index('row')]))
    np.testing.assert_allclose(plants.table()[order], live[live_order], rtol=0, atol=1e-12,
                               equal_nan=True)
    injected = summary['events']
    assert injected['empty_cells'] > 3 and injected['double_cells'] > 1
    t0 = plan.start_time
    k = int(np.argmax(np.diff(run.speed_t) > 0.5))          # the drop-out in the samples
    gap_lo, gap_hi = t0 + run.speed_t[k], t0 + run.speed_t[k + 1]
    assert 1.1 < gap_hi - gap_lo < 1.4
    misses = multiples = 0
    for r in range(rows):
        mine = np.flatnonzero(plants.row == r)
        times = plants.time[mine]
        readings = [(t0 + t, c) for row, t, c in run.seedlings if row == r]
        # each instant's own reading: the last one before it and after the one before it
        own = {}
        for t, c in readings:
            k = int(np.searchsorted(times, t, side='left'))
            if k < len(times):
                own[k] = c
        sensed = plants.reason[mine] == 0
        assert set(own) >= set(np.flatnonzero(sensed).tolist())
        for k in np.flatnonzero(sensed).tolist():
            assert plants.seedlings[mine][k] == own[k]
        # the instants inside the drop-out: flagged, unknown, none lost
        in_gap = (times > gap_lo) & (times < gap_hi)
        assert in_gap.sum() >= 1
        assert np.array_equal(plants.input_gap[mine] == 1, in_gap)
        assert np.all(plants.reason[mine][in_gap] == 3)
        # expected ISO counts from the injected cells: a double is a multiple, a run of empty
        # cells between two seedlings of one sequence a miss
        status = plants.status[mine].astype(int)
        multiples += int(np.count_nonzero(status == 2))
        seen = pending = False               # a seedling since the sequence began; empties
        for k in range(len(mine)):
            if in_gap[k] or (k and in_gap[k - 1]):          # the sequence starts again
                seen = pending = False
                if in_gap[k]:
                    continue
            if status[k] == 1:
                pending = seen
            else:
                misses += pending
                seen, pending = True, False
    quality = result.summary['spacing_quality']
    n = quality['spacings']
    assert round(quality['multiple_index'] * n) == multiples == \
        int(np.count_nonzero(plants.status == 2))
    assert round(quality['miss_index'] * n) == misses > 0
    counted = result.summary['instants']
    assert counted['empty'] == int(np.count_nonzero(plants.status == 1))
    assert counted['input_gap'] == int(np.count_nonzero(plants.input_gap == 1))
    assert counted['planted'] + counted['empty'] + counted['double'] + counted['unknown'] == \
        len(plants)
