"""Replay's vectorised paths give the live monitor's numbers bit for bit: the plausibility filters
run over a whole recording, the map's fix track fed every fix at once, the messages read packed
from the chunks, a bag's plants table built from the arrays; and `planter analyze` hands every
bag to exactly one task."""
import numpy as np
import pytest

from planter_ros.sensing.plant_map import FixTrack, MapSettings
from planter_ros.sensing.row_speed import RowSpeedStream, motion_samples


def one_by_one(t, v, w, offsets, yaw):
    stream = RowSpeedStream(offsets, None, None, yaw)
    kept = [s for s in map(stream.motion, t.tolist(), v.tolist(), w.tolist()) if s is not None]
    if not kept:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    return tuple(np.asarray(c) for c in zip(*kept))


@pytest.mark.parametrize('seed', range(4))
def test_the_filters_over_a_recording_keep_what_the_live_stream_keeps(seed):
    """Speed spikes, NaN, too fast, negative, repeated and late stamps, steps that become
    plausible only after a while, yaw-rate glitches: the same samples, the same yaw rate held or
    timed out, to the bit."""
    rng = np.random.default_rng(seed)
    for trial in range(300):
        n = int(rng.integers(0, 700))
        t = np.cumsum(rng.choice([0.05, 0.0, -0.01, 0.6, 2.0], n,
                                 p=[0.9, 0.02, 0.02, 0.03, 0.03]))
        v = np.abs(0.3 + np.cumsum(rng.normal(0, 0.03, n)))
        w = rng.normal(0, 0.2, n)
        for values in (t, v, w):
            k = rng.integers(0, max(n, 1), size=int(rng.integers(0, 8)))
            if n:
                values[k] = rng.choice([np.nan, np.inf, 25.0, -0.2, 5.0, 0.0], size=k.size)
        if n and rng.random() < 0.3:
            v[rng.integers(n):] *= rng.uniform(0, 4)          # a step
        offsets = [0.0] if rng.random() < 0.3 else [0.5, -0.5]
        yaw = (None, True, False)[trial % 3]
        got = motion_samples((t, v, w), offsets, yaw=yaw)
        want = one_by_one(t, v, w, offsets, yaw)
        for a, b in zip(got, want):
            assert a.shape == b.shape and np.array_equal(a, b, equal_nan=True)


def test_the_fix_track_fed_every_fix_at_once_is_the_live_track():
    """Moving, creeping and standing (windows of hundreds of fixes: the running sums rebased),
    fixes of every σ: the same transforms, the same first heading, the same state after."""
    rng = np.random.default_rng(3)
    rebases = 0
    for _ in range(60):
        m = int(rng.integers(1, 1500))
        settings = MapSettings(track_length=float(rng.choice([0.2, 3.0, 10.0])),
                               fix_window=float(rng.choice([1.0, 60.0, 200.0])))
        t = 1000.0 + np.cumsum(rng.uniform(0.05, 0.15, m))
        speed = rng.choice([0.0, 0.001, 0.3], m, p=[0.3, 0.3, 0.4])
        x = np.cumsum(speed * 0.1)
        y, psi = rng.normal(0, 0.01, m), rng.normal(0, 0.05, m)
        e, n = x * 0.8 + rng.normal(0, 0.02, m), x * 0.6 + rng.normal(0, 0.02, m)
        sigma = rng.uniform(0.001, 0.5, m)
        antenna = tuple(rng.uniform(-1, 1, 2).tolist())
        live = FixTrack(settings, antenna, keep_all=True)
        live.anchor(52.0, 5.0)
        for k in range(m):
            live.add(t[k], 52.0, 5.0, sigma[k], (x[k], y[k], psi[k]), (e[k], n[k]))
        batch = FixTrack(settings, antenna, keep_all=True)
        batch.anchor(52.0, 5.0)
        batch.add_all(t, sigma, (x, y, psi), (e, n))
        assert batch.times == live.times and batch.transforms == live.transforms
        assert batch.first_heading == live.first_heading and batch.fixes == live.fixes
        assert (batch._t, batch._path, batch._sums, batch._first, batch._phi) == \
            (live._t, live._path, live._sums, live._first, live._phi)
        rebases += live._path[0] > 0.0 if live._path else 0
    assert rebases > 0                    # the rebase was exercised
    with pytest.raises(ValueError):
        FixTrack(MapSettings(), (0.0, 0.0)).add_all(t, t, (t, t, t), (t, t))


def test_packed_messages_decode_as_a_list_of_messages_does(tmp_path):
    """The indexed reader's packed messages and the same messages as separate bytes (what the
    careful reader gives) decode to the same stamps and values, every joint of every row."""
    from planter_ros import interfaces
    from planter_ros.recording.bag_reader import read_recording
    from planter_ros.recording.cdr import Packed, decode_joints, decode_navsatfix, decode_twist
    from planter_ros.sim.season import simulate_bag
    from planter_ros.sim.tray import TrayShares
    bag = tmp_path / 'run.mcap'
    simulate_bag(str(bag), 2, 1, 10.0, 3, TrayShares(0.2, 0.1))
    rec = read_recording(bag, (interfaces.GROUND_SPEED, interfaces.JOINT_STATES,
                               interfaces.GNSS_FIX, interfaces.SEEDLINGS))
    joints = [f'row_{k}/sun_bar' for k in (1, 2, 3)] + ['none', None]
    for topic, decode in ((interfaces.GROUND_SPEED, decode_twist),
                          (interfaces.GNSS_FIX, decode_navsatfix),
                          (interfaces.JOINT_STATES, lambda r: decode_joints(r, joints)),
                          (interfaces.SEEDLINGS, lambda r: decode_joints(r, joints))):
        packed = rec.topics[topic].raw
        assert isinstance(packed, Packed) and len(packed) > 10
        separate = [bytes(m) for m in packed]
        order = np.random.default_rng(1).permutation(len(packed))
        for a, b in ((packed, separate), (packed.take(order), [separate[i] for i in order])):
            for x, y in zip(decode(a), decode(b)):
                assert np.array_equal(x, y, equal_nan=True)
    stamps, positions, _ = decode_joints(rec.topics[interfaces.JOINT_STATES].raw, joints)
    assert np.all(stamps > 0) and np.isfinite(positions[:3]).all()
    assert np.isnan(positions[3:]).all()


def test_a_bags_plants_table_from_the_arrays_is_the_one_from_the_json(tmp_path):
    from planter_ros.analysis.tables import plants_arrays_table, plants_table
    from planter_ros.prediction import Plants
    from planter_ros.recording.replay import replay
    from planter_ros.sim.season import simulate_bag
    from planter_ros.sim.tray import TrayShares
    bag = tmp_path / 'run.mcap'
    simulate_bag(str(bag), 4, 2, 10.0, 2, TrayShares(0.2, 0.1))
    result = replay(bag)
    rows = [(r.index, r.label) for r in result.rows]
    plants = Plants.from_table(result.plants.table())
    assert plants_table('k', plants.rows(), rows).equals(
        plants_arrays_table('k', plants, rows), check_metadata=True)
    # values JSON makes null, codes out of range, a row without a name
    plants.speed_ratio[:3] = np.inf
    plants.status[:2] = 7
    plants.row[1] = np.nan
    plants.row[2] = 9
    plants.time[0] = np.nan
    assert plants_table('k', plants.rows(), rows).equals(
        plants_arrays_table('k', plants, rows), check_metadata=True)


@pytest.mark.parametrize('count, workers', [(0, 1), (1, 1), (7, 2), (200, 1), (200, 2),
                                            (1000, 16)])
def test_every_bag_goes_to_exactly_one_task_big_ones_first(count, workers):
    from planter_ros.analysis.season import BATCH_MAX, batches
    tasks = batches(count, workers)
    assert [i for task in tasks for i in task] == list(range(count))
    sizes = [len(task) for task in tasks]
    assert all(1 <= s <= BATCH_MAX for s in sizes)
    assert sizes == sorted(sizes, reverse=True)
    if count >= 200:
        assert len(tasks) < count / 3 and sizes[-1] == 1


def _rows_of_a_machine(design, seed):
    """Five rows as a machine records them, each its own run (samples at their own instants),
    with what real rows have: a joint gap, lost shaft speeds (the arcs go linear), NaN
    angles, a section break, a row whose feedback never came."""
    from planter_ros.prediction import RowInputs
    from planter_ros.sim.runs import RunOptions, simulate_run
    rng = np.random.default_rng(seed)
    rows = []
    for r in range(5):
        run = simulate_run(design, RunOptions(duration=12.0, seed=seed * 10 + r,
                                              stall_at=4.0 if r == 1 else None))
        st, sv = run.speed_t, run.speed_v
        jt, jp, jw = run.joint_t, run.joint_pos.copy(), run.joint_vel.copy()
        t = jt - jt[0]
        breaks = ()
        if r == 0:                                  # 0.6 s without joint states
            keep = (t < 5.0) | (t > 5.6)
            jt, jp, jw = jt[keep], jp[keep], jw[keep]
        elif r == 2:                                # speeds lost, a few angles NaN
            jw[rng.random(jw.size) < 0.3] = np.nan
            jp[rng.integers(0, jp.size, 5)] = np.nan
        elif r == 3:                                # its section off for 1.5 s
            breaks = [(jt[0] + 6.0, jt[0] + 7.5)]
        elif r == 4:                                # no feedback at all
            jt, jp, jw = jt[:1], jp[:1], jw[:1]
        rows.append(RowInputs(st, sv, jt, jp, jw, row=r, breaks=breaks))
    return rows


@pytest.mark.parametrize('mechanism', ['five_bar', 'three_arm'])
def test_every_row_in_one_pass_predicts_what_each_row_alone_does(mechanism):
    """Replay predicts a machine's rows together (their measured arcs followed and their
    plants assembled in one pass over the rows' concatenated arrays): every plant of every row
    is the one the row predicted alone gives (rows one after the other), to 1e-12, whatever
    the row went through, with designs changing mid-run (a stray one overtaken at once) and
    with the arcs off."""
    from pathlib import Path

    from planter_ros.design import design_for_scene
    from planter_ros.prediction import (
        Plants, PredictionSettings, planting_model_from_design, predict_plants, predict_rows)
    from planter_ros.scene import load_scene
    from planter_ros.sim.runs import five_bar_design_message
    if mechanism == 'five_bar':
        design = five_bar_design_message()
        later = [five_bar_design_message(spacing=0.3), five_bar_design_message(spacing=0.25)]
    else:
        scene = load_scene(Path(__file__).resolve().parents[1] / 'config' /
                           'rice_three_arm.yaml')
        design = design_for_scene(scene)
        later = [design, design]
    model = planting_model_from_design(design)
    stray, new = (planting_model_from_design(d) for d in later)
    compared = 0
    for seed in range(3):
        rows = _rows_of_a_machine(design, seed)
        t0 = rows[0].joint_t[0]
        for changes in ([], [(t0 + 3.0, stray), (t0 + 3.01, new)], [(t0 + 8.0, new)]):
            for settings in (PredictionSettings(), PredictionSettings(measured_arc=False),
                             PredictionSettings(max_input_gap=0.3)):
                together = predict_rows(rows, model, settings, speed_filter=False,
                                        changes=changes)
                alone = [predict_plants(inputs, model, settings, speed_filter=False,
                                        changes=changes) for inputs in rows]
                assert len(alone[4]) == 0
                # the rows one after the other, each as predicted alone
                np.testing.assert_allclose(together.table(), Plants.concatenate(alone).table(),
                                           rtol=1e-12, atol=0, equal_nan=True)
                compared += len(together)
                covered = np.isfinite(together.tilt)
                assert covered.any() and not covered.all()
                assert set(together.row.tolist()) == {0.0, 1.0, 2.0, 3.0}
    assert compared > 500
