"""Every planting instant accounted for: the seedling sensor's empty cups and doubles and the
instants inside input gaps are counted exactly, in the plants, the indices and the tables."""
import numpy as np
import pytest

from planter_ros.prediction import (
    PLANT_FIELDS, Plants, SeedlingAccount, seedling_spacings, spacing_quality, status_counts,
    summarize)
from planter_ros.recording.replay import replay
from planter_ros.sim.field import Curve
from planter_ros.sim.season import Glitch, RunPlan, machine_rows, simulate_plan, write_monitor_bag

pytestmark = pytest.mark.realtime          # (test/conftest.py)

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
    drop-out: every sensed instant carries its own reading, also inside the gap; the statuses,
    the ISO misses and multiples and the instants in the gap equal what was injected, live and
    in replay."""
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
        # the instants inside the drop-out: flagged, none lost, and each still counted by its
        # own reading (the cup sensor has no gap)
        in_gap = (times > gap_lo) & (times < gap_hi)
        assert in_gap.sum() >= 1
        assert np.array_equal(plants.input_gap[mine] == 1, in_gap)
        assert np.all(plants.reason[mine][in_gap] == 0)
        for k in np.flatnonzero(in_gap).tolist():
            assert plants.seedlings[mine][k] == own[k]
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


def test_the_live_monitor_reads_the_seedling_sensor_as_replay_does(ros):
    """monitor_node fed a run and its cup sensor's readings (one per cycle, half a cycle before
    the planting angle: 1, 0, 1, 2, 1, ...) marks each instant as replay's arithmetic does."""
    import math

    from geometry_msgs.msg import TwistStamped
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    from planter_ros.design import to_json
    from planter_ros.nodes.monitor_node import MonitorNode
    from planter_ros.prediction import (PredictionSettings, RowInputs, design_spacing_of,
                                        planting_model_from_design, predict_plants)
    from planter_ros.sim.runs import RunOptions, five_bar_design_message, simulate_run
    design = five_bar_design_message()
    run = simulate_run(design, RunOptions(duration=24.0, seed=7))
    model = planting_model_from_design(design)
    theta = np.maximum.accumulate(run.joint_pos)
    ks = np.arange(math.ceil((theta[0] - model.planting_phase) / (2 * math.pi)),
                   math.floor((theta[-1] - model.planting_phase) / (2 * math.pi)) + 1)
    sense = model.planting_phase + (ks - 0.5) * 2 * math.pi
    read_t = run.joint_t[np.minimum(np.searchsorted(theta, sense), theta.size - 1)]
    counts = np.array([1, 0, 1, 2, 1, 1])[np.arange(read_t.size) % 6]
    events = ([(t, 0, i) for i, t in enumerate(run.speed_t)]
              + [(t, 1, i) for i, t in enumerate(run.joint_t)]
              + [(t, 2, i) for i, t in enumerate(read_t)])
    node = MonitorNode(context=ros.context, parameter_overrides=[Parameter('record', value=False)])
    try:
        node._on_design(String(data=to_json(design)), run.speed_t[0] - 1.0, 0)
        for t, kind, i in sorted(events):
            if kind == 0:
                msg = TwistStamped()
                msg.twist.linear.x = float(run.speed_v[i])
                node._on_speed(msg, t, 0)
            elif kind == 1:
                node._on_joint(JointState(name=['sun_bar'], position=[float(run.joint_pos[i])],
                                          velocity=[float(run.joint_vel[i])]), t, 0)
            else:
                node._on_seedlings(JointState(name=['sun_bar'], position=[float(counts[i])]),
                                   t, 0)
        live = Plants.from_table(np.vstack(node._tables))
        quality = node.spacing_quality()
    finally:
        node.destroy_node()
    offline = predict_plants(RowInputs(run.speed_t, run.speed_v, run.joint_t, run.joint_pos,
                                       run.joint_vel), model, PredictionSettings())
    account = SeedlingAccount()
    for t, c in zip(read_t, counts):
        account.add_reading(0, t, c)
    offline = account.apply(offline, design_spacing_of(offline, model.spacing))
    n = min(len(live), len(offline))
    assert n > 15 and len(offline) - len(live) <= 1
    np.testing.assert_array_equal(live.status[:n], offline.status[:n])
    np.testing.assert_allclose(live.spacing[:n], offline.spacing[:n], rtol=0, atol=1e-12,
                               equal_nan=True)
    assert {1.0, 2.0} <= set(live.status.tolist())
    machine = dict(quality)[-1]                  # the monitor's running ISO indices
    spacings = machine['spacings']
    assert round(machine['multiple_index'] * spacings) == np.count_nonzero(live.status == 2)
    assert round(machine['miss_index'] * spacings) == \
        np.count_nonzero(live.spacing > 1.5 * model.spacing) > 0


def test_a_small_simulated_season_accounts_for_every_injected_cell(tmp_path):
    """Three short runs with a tray of empty cells and doubles, one with a ground-speed drop-out
    long enough to hold planting instants: analysed as `planter analyze` does (the worker's
    task, Parquet rows), every cell the cup sensors read is counted at its instant or named
    where it went (before the first placed instant, after the last), kind by kind, exactly;
    the instants in the gap keep their readings; the ISO misses and multiples are the runs of
    empty cells, the doubles and the kinematic ones."""
    import pyarrow as pa

    from planter_ros.analysis import losses
    from planter_ros.analysis.tables import plant_columns
    from planter_ros.analysis.task import BagTask, analyze_bag, model_version
    from planter_ros.sim.season import draw_plan
    from planter_ros.sim.tray import TrayShares
    total = losses.empty_account()
    misses = multiples = 0
    for k in range(3):
        plan = draw_plan(7, k, 10.0, 2, tray=TrayShares(0.15, 0.08))
        if k == 0:
            plan = RunPlan(**{**plan.__dict__, 'glitches': (Glitch('dropout', 5.0, length=1.3),)})
        path = tmp_path / f'run_{k}.mcap'
        summary = write_monitor_bag(simulate_plan(plan), path)
        row, table = analyze_bag(BagTask(str(path), path.name, (0, 0), '{}'), {}, None,
                                 model_version())
        assert row['status'] == 'ok'
        readings = replay(path).seedling_readings
        one = losses.account(readings, losses.Instants.of(
            *plant_columns(table, losses.INSTANT_COLUMNS)))
        # the cup sensors read what the tray put in
        assert one['injected']['empty'] == summary['events']['empty_cells']
        assert one['injected']['double'] == summary['events']['double_cells']
        assert losses.is_exact(one), one
        if k == 0:
            assert sum(one['in_gap'].values()) >= 1 and one['gap_unknown'] == 0
        n = row['summary.spacing_quality.spacings']
        misses += round(row['summary.spacing_quality.miss_index'] * n)
        multiples += round(row['summary.spacing_quality.multiple_index'] * n)
        losses.add(total, one)
        assert isinstance(table, pa.Table)
    assert total['injected']['empty'] >= 5 and total['injected']['double'] >= 2
    assert total['counted']['empty'] + total['counted']['double'] > 0
    assert misses == total['misses_of_empties'] + total['misses_kinematic']
    assert total['misses_of_empties'] > 0
    assert multiples == total['multiples_of_doubles'] + total['multiples_kinematic']
    assert total['multiples_of_doubles'] == total['counted']['double']
    text = '\n'.join(losses.lines(total, 3, misses, multiples))
    assert 'exact' in text and 'NOT exact' not in text


def _one_at_a_time(readings, batches, sensors=None):
    """The seedling rule (module doc) applied plant by plant in plain Python: (seedlings,
    status, reason, spacing) of every plant of `batches` (Plants, in order); `sensors`: the
    rows' declared sensors ({row: bool}, a row not in it undeclared)."""
    sensors = sensors or {}
    last, out = {}, []
    for plants in batches:
        for row, t, model_spacing, gap, position in zip(
                plants.row.tolist(), plants.time.tolist(), plants.spacing.tolist(),
                plants.input_gap.tolist(), plants.position.tolist()):
            prev_t, last_pos = last.get(int(row), (-np.inf, np.nan))
            if not np.isfinite(model_spacing) or gap == 1:
                last_pos = np.nan
            times, counts = readings.get(int(row), ([], []))
            k = int(np.searchsorted(times, t, side='right')) - 1
            count, reason = None, 1                                   # no seedling sensor
            if k >= 0 and times[k] > prev_t and np.isfinite(counts[k]) and counts[k] >= 0:
                count, reason = counts[k], 0                          # sensed
            elif sensors.get(int(row)) is False:
                pass                                                  # declared without one
            elif gap == 1:
                reason = 3                                            # input gap
            elif k >= 0 or sensors.get(int(row)):
                reason = 2                                            # no sensor reading
            status = 3 if count is None else 1 if count < 0.5 else 2 if count >= 1.5 else 0
            spacing = np.nan
            if status != 1:
                spacing, last_pos = position - last_pos, position
            last[int(row)] = (t, last_pos)
            out.append((np.nan if count is None else count, status, reason, spacing))
    return np.array(out, dtype=float).reshape(-1, 4)


def test_a_rows_instants_at_once_are_accounted_as_one_after_the_other():
    """Rows interleaved, readings missing, repeated, NaN or negative, cups empty and double,
    restarts of the model's sequence (NaN spacing) and input gaps, plants given all at once
    (replay) or a few at a time (the live monitor): each plant's seedlings, status, reason and
    spacing are those of the rule applied plant by plant, to the bit."""
    rng = np.random.default_rng(11)
    for trial in range(200):
        n = int(rng.integers(1, 60))
        plants = instants(n)
        plants.row[:] = rng.integers(0, 3, n)
        plants.time[:] = 100.0 + np.cumsum(rng.uniform(0.1, 1.0, n))
        plants.position[:] = np.cumsum(rng.uniform(0.0, 0.4, n))
        plants.spacing[rng.random(n) < 0.15] = np.nan
        plants.input_gap[:] = (rng.random(n) < 0.15).astype(float)
        # every fourth trial declares the rows' sensors: row 0 has one, row 1 has none
        sensors = {0: True, 1: False} if trial % 4 == 3 else {}
        account = SeedlingAccount(sensors)
        readings = {}
        for row in range(3 if trial % 5 else 2):              # row 2 without a sensor at times
            m = int(rng.integers(0, 70))
            t = 100.0 + rng.uniform(-5.0, 60.0, m)
            same = rng.random(m) < 0.3                  # read at an instant's very time
            t[same] = rng.choice(plants.time, int(same.sum()))
            t = np.sort(t)
            t[rng.random(m) < 0.05] = np.nan
            counts = rng.choice([0.0, 1.0, 2.0, 3.0, np.nan, -1.0], m,
                                p=[0.15, 0.6, 0.1, 0.05, 0.05, 0.05])
            account.add_readings(row, t, counts)
        readings = {row: (list(t), list(c))
                    for row, (t, c) in account.readings().items()}
        d = rng.uniform(0.1, 0.3, n)
        if trial % 2:
            got = account.apply(plants, d)
            batches = [plants]
        else:                                  # the live monitor's batches of a few plants
            cuts = np.sort(rng.integers(0, n + 1, 4))
            batches = [Plants.from_table(plants.table()[lo:hi])
                       for lo, hi in zip(np.concatenate(([0], cuts)), np.concatenate((cuts, [n])))]
            got = Plants.concatenate([account.apply(b, d[b.index.astype(int)])
                                      for b in batches])
        want = _one_at_a_time(readings, batches, sensors)
        assert np.array_equal(np.column_stack((got.seedlings, got.status, got.reason,
                                               got.spacing)), want, equal_nan=True)
        assert np.array_equal(got.spacing_error, got.spacing - d, equal_nan=True)
