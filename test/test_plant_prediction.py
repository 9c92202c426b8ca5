"""Per-plant prediction model: sync behaviour, hole and tilt against λ, streaming = batch."""
import functools
import math

from hypothesis import example, given, settings, strategies as st
import numpy as np
import pytest

from planter_ros.design import from_dict
from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.five_bar import design_five_bar
from planter_ros.kinematics.planting import FiveBarPlanting, PathPlanting
from planter_ros.prediction import (
    PLANT_FIELDS, PlantPredictor, Plants, PredictionSettings, RowInputs, plant_values,
    planting_model_from_design, predict_plants)
from planter_ros.sim.runs import RunOptions, five_bar_design_message, simulate_run

TOMATO = design_five_bar(0.045, 0.2, 0.05)


def tomato_model(nozzle_width=0.0):
    return FiveBarPlanting(TOMATO.l1, TOMATO.l2, 0.045, 0.2, nozzle_width=nozzle_width)


def constant_run(lam, v=0.2, duration=5.0, rate=100.0, theta0=0.3):
    """Measured samples of a machine at constant speed ratio λ (ω = λ v / (l2 - l1))."""
    model = tomato_model()
    omega = lam * v / model.sync_advance
    t = np.arange(0.0, duration, 1.0 / rate)
    return t, np.full_like(t, v), t, theta0 + omega * t, np.full_like(t, omega)


def test_perfect_sync_gives_the_designed_hole_zero_tilt_and_exact_spacing():
    model = tomato_model(nozzle_width=0.03)
    plants = predict_plants(RowInputs(*constant_run(1.0)), model, PredictionSettings())
    assert len(plants) == 5
    assert np.allclose(plants.speed_ratio, 1.0, rtol=1e-12)
    # the tip (a point) sweeps the designed hole; the soil sees it widened by the nozzle
    assert np.allclose(plants.tip_sweep, TOMATO.hole_width, rtol=1e-9)
    assert np.allclose(plants.hole_width, TOMATO.hole_width + 0.03, rtol=1e-9)
    assert np.allclose(plants.tilt, 0.0, atol=1e-12)
    assert np.all(plants.upright == 1.0)
    assert np.allclose(plants.spacing_error[1:], 0.0, atol=1e-9)
    # the plant is set where the shaft passes π: θ0 + ω t = π + 2πk
    omega = 0.2 / model.sync_advance
    assert plants.time[0] == pytest.approx((math.pi - 0.3) / omega, rel=1e-9)
    assert math.isnan(plants.spacing[0])


def test_dragging_widens_the_hole_monotonically_and_tilts_forward():
    model = tomato_model()
    lams = np.array([0.3, 0.5, 0.7, 0.9, 0.99, 1.0])
    ratio, _, hole, tilt, _ = plant_values(model, PredictionSettings(), lams * 0.2 /
                                           model.sync_advance, np.full(lams.size, 0.2))
    assert np.allclose(ratio, lams, rtol=1e-12)
    assert np.all(np.diff(hole) < 0)                 # narrower as λ rises towards 1
    assert np.all(tilt[:-1] > 0) and tilt[-1] == pytest.approx(0.0, abs=1e-15)
    assert np.all(np.diff(tilt) < 0)                 # |tilt| grows with |λ - 1|


def test_overspeed_first_narrows_the_hole_then_widens_it_and_tilts_backward():
    """The issue asked 'hole width grows monotonically with |λ - 1|'; the kinematics say
    otherwise just above λ = 1 (the backward loop pulls entry and exit together): minimum near
    λ ≈ 1.05, monotone on both sides of it. The tilt is monotone in |λ - 1| throughout."""
    model = tomato_model()
    lams = np.linspace(1.0, 2.0, 2001)
    _, _, hole, tilt, _ = plant_values(model, PredictionSettings(),
                                       lams * 0.2 / model.sync_advance, np.full(lams.size, 0.2))
    i = int(np.argmin(hole))
    assert 1.01 < lams[i] < 1.1
    assert np.all(np.diff(hole[:i]) < 0) and np.all(np.diff(hole[i + 1:]) > 0)
    assert hole[-1] > hole[0]
    assert np.all(tilt[1:] < 0) and np.all(np.diff(tilt) < 0)


def test_tilt_is_the_slip_over_the_exit_climb_against_depth():
    model = tomato_model()
    lam = 0.5
    advance = model.sync_advance / lam
    _, _, _, tilt, _ = plant_values(model, PredictionSettings(), np.array([0.2 / advance]),
                                    np.array([0.2]))
    slip = (advance - model.sync_advance) * model.exit_angle
    assert tilt[0] == pytest.approx(math.atan2(slip, 0.045), rel=1e-12)


def test_upright_threshold_is_the_stem_angle_to_the_ground():
    model = tomato_model()
    lams = np.array([0.05, 0.2, 0.5, 1.0])
    omega = lams * 0.2 / model.sync_advance
    v = np.full(lams.size, 0.2)
    _, _, _, tilt, upright = plant_values(model, PredictionSettings(), omega, v)
    to_ground = 0.5 * math.pi - np.abs(tilt)
    assert np.array_equal(upright, (to_ground >= math.radians(30)).astype(float))
    assert upright[0] == 0.0 and upright[-1] == 1.0
    _, _, _, _, strict = plant_values(model,
                                      PredictionSettings(upright_threshold=math.radians(80)),
                                      omega, v)
    assert strict.sum() < upright.sum()


def test_rolling_uprightness_rate_counts_the_last_window_plants():
    model = tomato_model()
    # stall: the shaft crawls through one planting angle at λ = 0.05 (fallen), then recovers
    t = np.arange(0.0, 12.0, 0.01)
    omega = np.where((t > 2.4) & (t < 6.0), 0.05, 1.0) * 0.2 / model.sync_advance
    theta = 0.3 + np.concatenate(([0.0], np.cumsum(0.5 * (omega[1:] + omega[:-1]) * 0.01)))
    plants = predict_plants(RowInputs(t, np.full_like(t, 0.2), t, theta, omega), model,
                            PredictionSettings(window=3))
    fallen = np.nonzero(plants.upright == 0)[0]
    assert fallen.size == 1
    k = fallen[0]
    expected = [np.mean(plants.upright[max(0, i - 2):i + 1]) for i in range(len(plants))]
    assert np.allclose(plants.uprightness_rate, expected)
    assert plants.uprightness_rate[k] == pytest.approx(2 / 3)


def test_live_stream_gives_the_same_plants_as_the_batch_model():
    run = simulate_run(five_bar_design_message(), RunOptions(duration=20.0, seed=3))
    model = planting_model_from_design(run.design)
    rng = np.random.default_rng(7)
    # messy inputs: a NaN, a repeated stamp and an out-of-order sample in each stream
    st, sv = run.speed_t.copy(), run.speed_v.copy()
    jt, jp, jw = run.joint_t.copy(), run.joint_pos.copy(), run.joint_vel.copy()
    sv[50] = np.nan
    st[60] = st[59]
    jt[300] = jt[290]
    jw[400] = np.nan
    batch = predict_plants(RowInputs(st, sv, jt, jp, jw), model)
    # delivery: joint feedback arrives 0-30 ms late (in its own order), interleaved with the
    # speed samples
    late = np.maximum.accumulate(run.joint_t + rng.uniform(0, 0.03, jt.size))
    arrivals = sorted([(t, 0, i) for i, t in enumerate(run.speed_t)]
                      + [(t, 1, i) for i, t in enumerate(late)])
    live = PlantPredictor(model)
    parts = [live.add_speed(st[i], sv[i]) if kind == 0 else live.add_joint(jt[i], jp[i], jw[i])
             for _, kind, i in arrivals]
    streamed = Plants.concatenate(parts)
    assert len(batch) > 15
    assert np.allclose(streamed.table(), batch.table(), rtol=0, atol=1e-12, equal_nan=True)


def test_spacing_error_stays_bounded_through_a_speed_step_when_phase_locked():
    design = five_bar_design_message()
    locked = simulate_run(design, RunOptions(duration=30.0, step=1.4, seed=4))
    free = simulate_run(design, RunOptions(duration=30.0, step=1.4, seed=4, phase_gain=0.0))
    model = planting_model_from_design(design)

    def drift(run):
        p = predict_plants(RowInputs(run.speed_t, run.speed_v, run.joint_t, run.joint_pos,
                                     run.joint_vel), model)
        k = np.round((p.position - 0.1) / 0.2)
        return p, np.abs(p.position - (0.1 + 0.2 * k))

    p_locked, d_locked = drift(locked)
    p_free, d_free = drift(free)
    cruise = (p_locked.time - p_locked.time[0] > 3) & (p_locked.time - p_locked.time[0] < 27)
    assert np.nanmax(np.abs(p_locked.spacing_error[cruise])) < 0.05 * 0.2
    assert d_locked[cruise].max() < 0.05 * 0.2
    assert d_free.max() > 2 * d_locked[cruise].max()


def test_three_plants_per_revolution_are_set_at_each_arms_planting_angle():
    """The generic tip-path model (three-arm plug-in) finds 3 plants per shaft revolution and
    reproduces the five-bar's closed form when given the five-bar's own path."""
    a, b = TOMATO.l2 - TOMATO.l1, TOMATO.l1 + TOMATO.l2
    phi = np.linspace(0.0, 2 * math.pi, 720, endpoint=False)
    path = PathPlanting((phi, a * np.sin(phi), b * np.cos(phi)), 1, 0.045, 0.2)
    closed = tomato_model()
    assert path.planting_phase == pytest.approx(math.pi, abs=1e-9)
    assert path.exit_angle == pytest.approx(closed.exit_angle, rel=1e-9)
    assert path.release_advance == pytest.approx(closed.release_advance, rel=1e-6)
    adv = np.linspace(-0.02, 0.2, 12)
    assert np.allclose(path.tip_sweep(adv), closed.tip_sweep(adv), rtol=1e-6)
    # the same tip path too, relative to the planting point
    around = np.linspace(-math.pi, math.pi, 37)
    assert np.allclose(np.column_stack(path.tip_path(around)),
                       np.column_stack(closed.tip_path(around)), atol=1e-9)
    assert np.allclose(closed.tip_path(0.0), 0.0, atol=1e-15)

    three = planting_model_from_design(from_dict({
        'mechanism': 'three_arm', 'plants_per_revolution': 3, 'plant_spacing': 0.2,
        'planting_depth': 0.03, 'nozzle_width': 0.02,
        'tip_path': {'angle': phi.tolist(), 'x': (0.1 * np.sin(phi)).tolist(),
                     'y': (0.2 * np.cos(phi)).tolist()}}))
    t = np.arange(0.0, 3.0, 0.01)
    omega = 2 * math.pi / 3 * 0.2 / 0.2          # in sync: ω = 2π v / (3 d)
    plants = predict_plants(RowInputs(t, np.full_like(t, 0.2), t, omega * t,
                                      np.full_like(t, omega)), three)
    assert np.allclose(np.diff(plants.time), 1.0, rtol=1e-9)   # one plant per 1/3 rev
    assert np.allclose(plants.spacing[1:], 0.2, rtol=1e-9)
    assert np.allclose(plants.speed_ratio, 1.0)
    assert np.allclose(plants.hole_width - plants.tip_sweep, 0.02)


@pytest.mark.parametrize('design, word', [
    ({'mechanism': 'five_bar', 'plant_spacing': 0.2, 'planting_depth': 0.045,
      'nozzle_width': 0.04}, 'l1'),
    ({'mechanism': 'five_bar', 'l1': 0.1, 'l2': 0.13, 'plant_spacing': -0.2,
      'planting_depth': 0.045, 'nozzle_width': 0.04}, 'plant_spacing'),
    ({'mechanism': 'three_arm', 'plant_spacing': 0.2, 'planting_depth': 0.03,
      'nozzle_width': 0.04}, 'tip_path'),
    ({'mechanism': 'five_bar', 'l1': 0.1, 'l2': 0.13, 'plant_spacing': 0.2,
      'planting_depth': 0.045}, 'nozzle_width'),
    ({'mechanism': 'five_bar', 'l1': 0.1, 'l2': 0.13, 'plant_spacing': 0.2,
      'planting_depth': 0.045, 'nozzle_width': 0.7}, 'nozzle_width'),
    ([1, 2], 'design'),
])
def test_unusable_designs_are_one_line_errors(design, word):
    with pytest.raises(DesignError) as err:
        planting_model_from_design(from_dict(design))
    assert word in str(err.value) and '\n' not in str(err.value)


@pytest.mark.parametrize('kwargs', [dict(max_input_gap=0.0), dict(max_input_gap=math.nan),
                                    dict(upright_threshold=2.0), dict(window=0)])
def test_settings_out_of_range_are_refused(kwargs):
    with pytest.raises(DesignError):
        PredictionSettings(**kwargs)


def test_stopped_machine_and_reversing_give_finite_figures():
    model = tomato_model()
    ratio, _, hole, tilt, upright = plant_values(model, PredictionSettings(),
                                                 np.array([6.0, 6.0]), np.array([0.0, -0.1]))
    assert ratio[0] == math.inf and ratio[1] < 0
    assert np.all(np.isfinite(hole)) and np.all(np.isfinite(tilt))
    assert np.all(tilt < 0)                  # nozzle moves backwards relative to the soil


def test_implausible_ground_speed_samples_do_not_move_plants_live_or_in_replay():
    """A 25 m/s spike, a NaN and a reversing blip must not shift the plants' positions: the
    monitor believes the same samples as the sync node (sensing.ground_speed_filter)."""
    model = tomato_model()
    clean = constant_run(1.0, duration=6.0)
    speed_t, speed_v = clean[0].copy(), clean[1].copy()
    speed_v[150] = 25.0           # a spike
    speed_v[300] = math.nan       # a dropout
    speed_v[450] = 3.5            # faster than any transplanter
    batch_clean = predict_plants(RowInputs(*clean), model)
    batch = predict_plants(RowInputs(speed_t, speed_v, *clean[2:]), model)
    assert len(batch) == len(batch_clean) == 6
    np.testing.assert_allclose(batch.position, batch_clean.position, atol=0.002)
    assert np.max(np.abs(batch.spacing_error[1:])) < 0.002
    live = PlantPredictor(model)
    rows = []
    for i in range(speed_t.size):
        rows.append(live.add_joint(clean[2][i], clean[3][i], clean[4][i]))
        rows.append(live.add_speed(speed_t[i], speed_v[i]))
    np.testing.assert_allclose(Plants.concatenate(rows).table(), batch.table(), rtol=1e-12,
                               atol=1e-12)


def test_three_arm_design_topic_carries_what_the_monitor_needs():
    """The rice scene's design JSON builds a three-plants-per-turn path model whose planting
    instants are the arms' lowest points (paper Table 1: arm I plants near 191°)."""
    from pathlib import Path

    from planter_ros.design import design_for_scene, from_json, to_json
    from planter_ros.scene import load_scene

    scene = load_scene(Path(__file__).resolve().parents[1] / 'config' / 'rice_three_arm.yaml')
    design = from_json(to_json(design_for_scene(scene)))           # as it travels on the topic
    model = planting_model_from_design(design)
    assert isinstance(model, PathPlanting) and model.plants_per_revolution == 3
    assert abs(math.degrees(model.planting_phase) - 191.0) < 6.0
    assert min(design.tip_path.y) == pytest.approx(float(model._y(model.planting_phase)), abs=1e-4)
    # one carrier turn at the synchronous speed sets three plants, d apart
    omega = 2 * math.pi
    v = model.sync_advance * omega
    t = np.arange(0.0, 1.5, 0.005)
    plants = predict_plants(RowInputs(t, np.full_like(t, v), t, omega * t, np.full_like(t, omega)),
                            model)
    assert len(plants) == 4
    np.testing.assert_allclose(plants.spacing[1:], design.plant_spacing, rtol=1e-6)
    assert np.all(np.isfinite(plants.hole_width)) and np.all(np.isfinite(plants.tilt))


def _live(model, settings, st, sv, jt, jp, jw):
    """Feed the live predictor in arrival order (speed and joint samples interleaved), then
    end it as the monitor ends a run (`finish`: a plant still waiting for a later sample, e.g.
    one in a gap the last samples closed, is completed)."""
    live = PlantPredictor(model, settings)
    arrivals = sorted([(t, 0, i) for i, t in enumerate(st)]
                      + [(t, 1, i) for i, t in enumerate(jt)])
    return Plants.concatenate([live.add_speed(st[i], sv[i]) if kind == 0 else
                               live.add_joint(jt[i], jp[i], jw[i]) for _, kind, i in arrivals]
                              + [live.finish()])


def test_a_gap_in_the_inputs_reports_every_instant_inside_it_flagged_and_restarts_the_spacing():
    """Joint states lost for 1.4 s and, later, ground speed lost for 1.2 s: every planting
    instant inside either gap is still reported (the shaft angle says how many), flagged
    `input_gap`, with no hole, tilt, upright or spacing; the first plant after each has no
    spacing; live and replay agree."""
    run = simulate_run(five_bar_design_message(), RunOptions(duration=20.0, seed=3))
    model = planting_model_from_design(run.design)
    settings = PredictionSettings()
    full = predict_plants(RowInputs(run.speed_t, run.speed_v, run.joint_t, run.joint_pos,
                                    run.joint_vel), model, settings)
    t0 = run.speed_t[0]
    j_gap, s_gap = (t0 + 6.0, t0 + 7.4), (t0 + 12.0, t0 + 13.2)
    jk = (run.joint_t < j_gap[0]) | (run.joint_t > j_gap[1])
    sk = (run.speed_t < s_gap[0]) | (run.speed_t > s_gap[1])
    inputs = (run.speed_t[sk], run.speed_v[sk], run.joint_t[jk], run.joint_pos[jk],
              run.joint_vel[jk])
    cut = predict_plants(RowInputs(*inputs), model, settings)
    assert len(cut) == len(full) and not np.any(full.input_gap)       # none lost
    flagged = cut.input_gap == 1
    inside = np.zeros(len(full), dtype=bool)
    for kept in (run.joint_t[jk], run.speed_t[sk]):      # between the samples around a gap
        k = int(np.argmax(np.diff(kept)))
        inside |= (full.time > kept[k]) & (full.time < kept[k + 1])
    assert inside.sum() >= 2 and np.array_equal(flagged, inside)
    for field in ('hole_width', 'tilt', 'upright', 'spacing', 'speed_ratio'):
        assert np.all(np.isnan(getattr(cut, field)[flagged])), field
    assert np.all(cut.reason[flagged] == 3) and np.all(cut.status == 3)
    # interpolated: in the joint gap the instant within a sample interval's share of the gap
    assert np.max(np.abs(cut.time[flagged] - full.time[flagged])) < 0.5
    assert np.max(np.abs(cut.position[flagged] - full.position[flagged])) < 0.1
    # outside the gaps the same plants, at the same instants
    np.testing.assert_allclose(cut.time[~flagged], full.time[~flagged], rtol=0, atol=1e-9)
    after = [int(np.argmax(cut.time > hi)) for _, hi in (j_gap, s_gap)]
    assert np.all(np.isnan(cut.spacing[[0] + after]))
    assert np.isnan(cut.spacing).sum() == 3 + flagged.sum()
    assert np.all(np.diff(cut.index) == 1)                            # numbering goes on
    np.testing.assert_allclose(_live(model, settings, *inputs).table(), cut.table(), rtol=0,
                               atol=1e-12, equal_nan=True)


def test_a_gap_shorter_than_the_setting_is_interpolated_as_before():
    run = simulate_run(five_bar_design_message(), RunOptions(duration=10.0, seed=4))
    model = planting_model_from_design(run.design)
    t = run.joint_t - run.joint_t[0]
    keep = (t < 4.0) | (t > 4.3)                               # 0.3 s without joint states
    inputs = (run.speed_t, run.speed_v, run.joint_t[keep], run.joint_pos[keep],
              run.joint_vel[keep])
    plants = predict_plants(RowInputs(*inputs), model, PredictionSettings(max_input_gap=0.5))
    assert np.isnan(plants.spacing).sum() == 1
    strict = predict_plants(RowInputs(*inputs), model, PredictionSettings(max_input_gap=0.2))
    assert np.isnan(strict.spacing).sum() >= 2 or len(strict) < len(plants)


@functools.lru_cache(maxsize=1)
def _gap_run():
    """The run the gaps are cut into: made once, by the process that runs the test (not at
    collection, which every test process does)."""
    return simulate_run(five_bar_design_message(), RunOptions(duration=20.0, seed=5))


@settings(max_examples=40, deadline=None)
@example(gaps=[], max_gap=0.09375)      # an exit just inside the gap, late joint feedback
@example(gaps=[('joint', 18.0, 2.0)], max_gap=1.0)   # a plant in a gap the last samples close
@example(gaps=[('joint', 16.25, 1.3046875)], max_gap=1.0)  # a plant at the gap's closing sample
@given(gaps=st.lists(st.tuples(st.sampled_from(['speed', 'joint']), st.floats(0.5, 18.0),
                               st.floats(0.05, 2.0)), max_size=4),
       max_gap=st.floats(0.06, 1.0))
@pytest.mark.slow
def test_live_and_replay_agree_on_any_gaps(gaps, max_gap):
    run = _gap_run()
    model = planting_model_from_design(run.design)
    prediction = PredictionSettings(max_input_gap=max_gap)
    sk = np.ones(run.speed_t.size, dtype=bool)
    jk = np.ones(run.joint_t.size, dtype=bool)
    for which, start, length in gaps:
        t, keep = (run.speed_t, sk) if which == 'speed' else (run.joint_t, jk)
        t = t - run.speed_t[0]
        keep &= ~((t > start) & (t < start + length))
    inputs = (run.speed_t[sk], run.speed_v[sk], run.joint_t[jk], run.joint_pos[jk],
              run.joint_vel[jk])
    batch = predict_plants(RowInputs(*inputs), model, prediction)
    np.testing.assert_allclose(_live(model, prediction, *inputs).table(), batch.table(),
                               rtol=0, atol=1e-12, equal_nan=True)
    # a plant inside a gap longer than the setting is flagged and has no figures, none other;
    # inside: on the segment the gap's two samples span, its closing sample included (an
    # instant there is found between them, its time interpolated across the gap)
    inside = np.zeros(len(batch), dtype=bool)
    for t in (inputs[0], inputs[2]):
        k = np.nonzero(np.diff(t) > max_gap)[0]
        for lo, hi in zip(t[k], t[k + 1]):
            inside |= (batch.time > lo) & (batch.time <= hi)
    assert np.array_equal(batch.input_gap == 1, inside)
    assert np.all(np.isnan(batch.hole_width[inside]))


def test_a_new_design_scores_plants_from_the_next_planting_instant_live_and_batch_alike():
    """The machine plants every 0.2 m up to the plant at 0.7 m, then every 0.3 m (the sync law
    switches at the first planting instant after the design message, here at s = 0.62 m)."""
    pepper = design_five_bar(0.045, 0.3, 0.05)
    new = FiveBarPlanting(pepper.l1, pepper.l2, 0.045, 0.3)
    v, rate = 0.2, 100.0
    t = np.arange(0.0, 12.0, 1.0 / rate)
    s = v * t
    theta = np.where(s <= 0.7, 2 * np.pi * s / 0.2, 7 * np.pi + 2 * np.pi * (s - 0.7) / 0.3)
    omega = np.where(s <= 0.7, 2 * np.pi * v / 0.2, 2 * np.pi * v / 0.3)
    t_msg = 0.62 / v
    stray = FiveBarPlanting(TOMATO.l1 * 2, TOMATO.l2 * 2, 0.045, 0.4)    # overtaken at once
    changes = [(t_msg - 0.05, stray), (t_msg, new)]
    batch = predict_plants(RowInputs(t, np.full_like(t, v), t, theta, omega), tomato_model(),
                           changes=changes)
    assert np.allclose(batch.position, [0.1, 0.3, 0.5, 0.7, 1.0, 1.3, 1.6, 1.9, 2.2],
                       atol=1e-9)
    # every gap against the design it was planted with: none looks 100 mm off
    assert np.allclose(batch.spacing_error[1:], 0.0, atol=1e-9)
    assert np.allclose(batch.hole_width[4:], pepper.hole_width, rtol=1e-6)
    assert np.allclose(batch.hole_width[:3], TOMATO.hole_width, rtol=1e-6)   # (the 4th: the
    # speed steps right at it, so its interpolated λ is off)
    assert list(batch.index) == list(range(len(batch)))             # one sequence
    # the live predictor given the same messages in arrival order agrees exactly
    live = PlantPredictor(tomato_model())
    parts, pending = [], list(changes)
    for i in range(t.size):
        while pending and pending[0][0] <= t[i]:
            live.change_model(pending[0][1], pending[0][0])
            pending.pop(0)
        parts += [live.add_joint(t[i], theta[i], omega[i]), live.add_speed(t[i], v)]
    streamed = Plants.concatenate(parts)
    assert np.allclose(streamed.table(), batch.table(), rtol=0, atol=1e-12, equal_nan=True)
def test_a_section_switched_off_ends_the_spacing_sequence_live_and_in_replay():
    """A row's section off for 3 s (the sync node holds the shaft, the machine drives on): the
    first plant after it would read as a 0.6 m miss; with the sync node's on/off reports it has
    no spacing, in batch and live alike."""
    from types import SimpleNamespace as Obj

    from planter_ros.diagnostics import SECTION, section_states
    from planter_ros.prediction import section_breaks
    run = simulate_run(five_bar_design_message(), RunOptions(duration=20.0, seed=5))
    model = planting_model_from_design(run.design)
    settings = PredictionSettings()
    t0 = run.joint_t[0]
    off, on = t0 + 6.0, t0 + 9.0
    held = np.interp(off, run.joint_t, run.joint_pos)
    pos = np.where(run.joint_t < off, run.joint_pos, held)
    after = run.joint_t > on
    pos[after] = run.joint_pos[after] - (np.interp(on, run.joint_t, run.joint_pos) - held)
    vel = np.where((run.joint_t >= off) & (run.joint_t <= on), 0.0, run.joint_vel)
    inputs = (run.speed_t, run.speed_v, run.joint_t, pos, vel)

    blind = predict_plants(RowInputs(*inputs), model, settings)
    assert np.nanmax(blind.spacing) > 2.5 * model.spacing           # a miss that was no miss

    def report(name, state):
        return [Obj(name=f'sync_node: {name}',
                    values=[Obj(key='row speed', value='0.2'), Obj(key=SECTION,
                                                                   value=state)])]
    reports = [(t0 + 1.0, section_states(report('left', 'on'))),
               (off, section_states(report('left', 'off'))),
               (off + 1.0, section_states(report('left', 'off'))),
               (on, section_states(report('left', 'on')))]
    breaks = section_breaks(reports)
    assert breaks == {'left': [(on, on)]}
    plants = predict_plants(RowInputs(*inputs, breaks=breaks['left']), model, settings)
    first = int(np.argmax(plants.time > on))
    assert np.isnan(plants.spacing[first]) and np.isnan(plants.spacing).sum() == 2
    assert np.nanmax(np.abs(plants.spacing_error)) < 0.1 * model.spacing

    live = PlantPredictor(model, settings)
    arrivals = sorted([(t, 0, i) for i, t in enumerate(inputs[0])]
                      + [(t, 1, i) for i, t in enumerate(inputs[2])])
    out, told = [], False
    for t, kind, i in arrivals:
        if not told and t >= on:
            live.add_break(*breaks['left'][0])          # the monitor hears "on" at `on`
            told = True
        out.append(live.add_speed(inputs[0][i], inputs[1][i]) if kind == 0 else
                   live.add_joint(inputs[2][i], inputs[3][i], inputs[4][i]))
    np.testing.assert_allclose(Plants.concatenate(out).table(), plants.table(), rtol=0,
                               atol=1e-12, equal_nan=True)


def test_no_plants_is_what_an_empty_table_gives_each_field_an_array_of_its_own():
    empty, from_table = Plants.empty(), Plants.from_table(np.zeros((0, len(PLANT_FIELDS))))
    assert len(empty) == 0 and empty.table().shape == (0, len(PLANT_FIELDS))
    for f in PLANT_FIELDS:
        mine, theirs = getattr(empty, f), getattr(from_table, f)
        assert (mine.dtype, mine.shape, mine.flags.writeable) == \
            (theirs.dtype, theirs.shape, theirs.flags.writeable)
    assert len({id(getattr(empty, f)) for f in PLANT_FIELDS}) == len(PLANT_FIELDS)
    assert Plants.empty().index is not empty.index
