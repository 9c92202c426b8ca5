"""The machine's law without ROS: each row on its own speed v − ω_z·y through a curve (the
issue's quality bar on the closed-loop simulation), the bias without compensation, yaw-rate
plausibility, a row that would turn backwards holds, section control off/on, a three-arm
machine, and replay of a multi-row recording row by row."""
import math

import numpy as np
import pytest

from planter_ros.control.machine_law import Machine, TurnConfig
from planter_ros.control.phase_lock import PlantingAngles, stop_angle
from planter_ros.prediction import planting_model_from_design
from planter_ros.rows import Row
from planter_ros.sensing.row_speed import row_speed_samples
from planter_ros.sim.closed_loop import (
    LoopTiming, MotionSensor, RowDesign, RowEvents, SimMachine, curve_comparison, curve_figures,
    simulate_rows)
from planter_ros.sim.field import Curve, demo_curves, field_profile
from planter_ros.sim.runs import five_bar_design_message
from planter_ros.sim.spacing import plant_positions

FAST = LoopTiming(dt=0.002)          # s: a coarser integration step than the default
EXACT = MotionSensor(noise=0.0, yaw_noise=0.0)   # the sensor reads the truth

D = 0.2
TWO_PI = 2 * math.pi


@pytest.fixture(scope='module')
def curves():
    return curve_comparison(timing=FAST)


def test_with_compensation_every_row_follows_its_own_speed_and_keeps_its_spacing(curves):
    for row in curves['compensated']:
        for c in row['curves']:
            assert c['plants'] >= 4
            assert abs(c['median_speed_ratio'] - 1.0) <= 0.03, (row['lateral_offset'], c)
            assert c['rms_spacing_error'] <= 0.02 * D, (row['lateral_offset'], c)


def test_without_compensation_outer_and_inner_rows_show_the_y_over_r_bias(curves):
    for row in curves['uncompensated']:
        for c in row['curves']:
            bias = c['uncompensated_bias']             # −y·d/R: ±15 mm at 0.75 m, ±5 mm at 0.25
            assert c['mean_spacing_error'] == pytest.approx(bias, abs=0.2 * abs(bias) + 5e-4)
            # and the speed follows the machine's v, not the row's: ratio 1/(1 − y/R)
            assert c['median_speed_ratio'] == pytest.approx(
                1.0 / (1.0 - row['lateral_offset'] / c['radius']), abs=0.01)
    outer = [row for row in curves['uncompensated'] if abs(row['lateral_offset']) == 0.75]
    assert all(row['rms_spacing_error'] > 0.05 * D for row in outer)


def test_two_rows_on_a_curve_land_on_their_own_grids():
    """A steady 10 m turn: each row's plants are d apart along the row's own travelled
    distance, so the outer row, travelling farther, plants more often."""
    profile = field_profile(24.0, 0.25, change=1.0, curves=[Curve(3.0, 20.0, 10.0)])
    runs = simulate_rows(SimMachine([0.75, -0.75], timing=FAST), profile, 21.0, RowDesign(D),
                         EXACT)
    figures = [curve_figures(run, profile, D)['curves'][0] for run in runs]
    for f in figures:
        assert f['plants'] >= 15 and f['rms_spacing_error'] < 0.005 * D
    inner, outer = runs                              # left turn: +y is inside
    t_inner = plant_positions(inner.angle, inner.t, TWO_PI, release=math.pi)
    t_outer = plant_positions(outer.angle, outer.t, TWO_PI, release=math.pi)
    steady = (t_outer > 6.0) & (t_outer < 18.0)
    # the outer row travels 1.15× as far, so it plants 1.15× as often
    period_outer = np.median(np.diff(t_outer)[steady[1:]])
    period_inner = np.median(np.diff(t_inner)[(t_inner[1:] > 6.0) & (t_inner[1:] < 18.0)])
    assert period_inner / period_outer == pytest.approx((10.0 + 0.75) / (10.0 - 0.75), rel=0.01)


def test_yaw_rate_samples_are_judged_like_speed_and_held_then_dropped():
    m = Machine([1.0])
    m.set_design(D, 1, 0.0)
    t = 0.0
    for _ in range(10):
        m.sample(0.2, 0.05, t)
        t += 0.05
    assert m.laws[0].ground_speed_value == pytest.approx(0.15)
    for bad in (0.4, math.nan, math.inf, 5.0):         # spike, non finite, too fast
        m.sample(0.2, bad, t)
        assert m.laws[0].ground_speed_value == pytest.approx(0.15)   # the last one held
        t += 0.05
    yaw = m.filter.yaw
    assert yaw.rejected == {'non_finite': 2, 'too_fast': 1, 'spike': 1}
    for _ in range(12):                                # 0.6 s without a believable yaw rate
        m.sample(0.2, math.nan, t)
        t += 0.05
    assert m.laws[0].ground_speed_value == pytest.approx(0.2)     # taken as straight
    m.configure(m.laws[0].config, m.filter.speed.limits, yaw.limits,
                TurnConfig(turn_compensation=False))
    m.sample(0.2, 0.05, t)
    assert m.laws[0].ground_speed_value == pytest.approx(0.2)


def test_a_row_that_would_turn_backwards_holds_and_keeps_its_grid():
    """A row 12 m left of the reference point on a 10 m left turn moves backwards: it holds
    (command 0, distance not integrated) and resumes on its old grid."""
    m = Machine([12.0, 0.0])
    law = m.laws[0]
    m.set_design(D, 1, 0.0)
    law.feedback(0.0, 0.0, 0.0)
    t, theta = 0.0, 0.0
    commands = []
    for i in range(220):                     # 0.5 s straight, 0.7 s turning, 1 s straight
        turning = 50 <= i < 120
        if i % 5 == 0:
            m.sample(0.2, 0.02 if turning else 0.0, t)
        cmd = law.command(t)
        commands.append((turning, cmd))
        theta += cmd * 0.01
        law.feedback(theta, cmd, t)
        t += 0.01
    ramp = [c for _, c in commands[50:120]]
    assert min(ramp) >= 0.0                                  # never backwards
    assert all(b <= a for a, b in zip(ramp, ramp[1:]))       # ramps down at its limit ...
    assert max(ramp[-20:]) == 0.0                            # ... and holds
    assert law.phase_slips == 0
    s = law.travelled(t)
    assert s == pytest.approx(0.2 * 1.5, abs=0.02)           # nothing while turning
    assert abs(law.phase_error(t)) < 0.3                     # back on its old grid


def _tomato_angles():
    model = planting_model_from_design(five_bar_design_message())
    return PlantingAngles(model.planting_phase, model.entry_angle, model.exit_angle)


def test_stop_angle_parks_out_of_the_soil_and_sets_only_a_plant_already_committed():
    angles = PlantingAngles(math.pi, 0.6, 0.6)
    a, w = 20.0, 2 * math.pi                    # braking distance w²/2a ≈ 0.99 rad
    # just after a plant (rising): parks at the top, half a pitch after the plant
    assert stop_angle(math.pi + 0.7, w, a, TWO_PI, angles) == pytest.approx(TWO_PI)
    # past the top (falling): the soonest stop, before the soil (entry at π − 0.6)
    assert stop_angle(0.5, w, a, TWO_PI, angles) == pytest.approx(0.5 + w * w / 40)
    # too close to the soil to stop in front of it: that plant is set, then the next park
    assert stop_angle(1.8, w, a, TWO_PI, angles) == pytest.approx(TWO_PI)
    # no planting angles known: simply the soonest stop
    assert stop_angle(1.8, w, a, TWO_PI) == pytest.approx(1.8 + w * w / 40)


@pytest.mark.parametrize('t_off', [8.0, 8.2, 8.45, 8.7, 8.95])
def test_a_row_switched_off_stops_within_a_pitch_and_on_starts_a_new_grid(t_off):
    angles = _tomato_angles()
    profile = field_profile(30.0, 0.2)
    t_on = t_off + 3.0
    runs = simulate_rows(SimMachine([0.5, -0.5], timing=FAST), profile, 18.0,
                         RowDesign(D, planting=angles), EXACT,
                         RowEvents(switches=[(t_off, 0, False), (t_on, 0, True)]))
    row, other = runs
    times = plant_positions(row.angle, row.t, TWO_PI, release=math.pi)
    where = plant_positions(row.angle, row.distance, TWO_PI, release=math.pi)
    i_off = np.searchsorted(row.t, t_off)
    theta_off, omega_off = row.angle[i_off], row.speed[i_off]
    # stops within one plant pitch of mechanism angle, and stays stopped
    rest = row.angle[np.searchsorted(row.t, t_on - 0.01)]
    assert rest - theta_off < TWO_PI
    assert row.angle[np.searchsorted(row.t, t_on - 1.5)] == pytest.approx(rest, abs=1e-3)
    # nothing planted while off, but a plant already committed when switched off: the
    # mechanism then could not stop in front of the soil
    during = times[(times > t_off) & (times < t_on)]
    committed = stop_angle(theta_off, omega_off, 20.0, TWO_PI, angles) > \
        angles.phase + TWO_PI * math.ceil((theta_off - angles.phase) / TWO_PI)
    assert len(during) == (1 if committed else 0)
    # switched on: a new grid from the switch-on point, no plant too close, then every d
    after = where[times > t_on]
    s_on = row.distance[np.searchsorted(row.t, t_on)]
    assert 0.0 < after[0] - s_on < D + 0.02
    before = where[times < t_on][-1]
    assert after[0] - before > D
    gaps = np.diff(after[:8])
    assert np.max(np.abs(gaps - D)) < 0.02 * D
    # the other row planted on through it all
    other_gaps = np.diff(plant_positions(other.angle, other.distance, TWO_PI, release=math.pi))
    assert np.max(np.abs(other_gaps[5:-2] - D)) < 0.03 * D


def test_a_three_arm_machine_with_rows_plants_three_per_turn_on_each_row():
    from planter_ros.design import design_for_scene
    from planter_ros.scene import load_scene
    from pathlib import Path
    scene = load_scene(Path(__file__).resolve().parents[1] / 'config' / 'rice_three_arm.yaml')
    design = design_for_scene(scene)
    d, n = design.plant_spacing, design.plants_per_revolution
    profile = field_profile(30.0, 0.4, change=1.0, curves=demo_curves(30.0))
    runs = simulate_rows(SimMachine([1.0, -1.0], timing=FAST), profile, 28.0, RowDesign(d, n))
    for run in runs:
        figures = curve_figures(run, profile, d, n)
        for c in figures['curves']:
            assert abs(c['median_speed_ratio'] - 1.0) <= 0.03
            assert c['rms_spacing_error'] <= 0.02 * d


def test_replay_predicts_a_machine_row_by_row_from_each_rows_own_distance(tmp_path):
    """A 2-row bag of a run without turn compensation: replay places each row's plants along
    the row's own travelled distance, so the outer row shows the longer gaps in the turn."""
    from planter_ros.recording.replay import replay
    from planter_ros.sim.bags import write_machine_bag
    design = five_bar_design_message()
    profile = field_profile(20.0, 0.25, change=1.0, curves=[Curve(3.0, 17.0, 10.0)])
    rows = [Row(0, 'left', 0.75, 1), Row(1, 'right', -0.75, 2)]
    runs = simulate_rows(SimMachine([r.lateral_offset for r in rows], compensation=False,
                                    timing=FAST), profile, 18.0, RowDesign(D), EXACT)
    bag = tmp_path / 'machine.mcap'
    write_machine_bag(rows, runs, profile, design, bag)
    result = replay(bag)
    assert [r.name for r in result.rows] == ['left', 'right']
    assert set(np.unique(result.plants.row)) == {0.0, 1.0}
    for row, summary in zip(rows, result.row_summaries):
        plants = result.plants.table()[result.plants.row == row.index]
        assert summary['plants'] == len(plants) >= 15
        t = plants[:, 1] - 1_700_000_000.0
        steady = (t[1:] > 5.0) & (t[:-1] > 5.0) & (t[1:] < 15.0)
        gaps = np.diff(plants[:, 2])[steady]
        # without compensation every row plants every d of the machine's travel: a row at y
        # gets d·(1 − y/R) along its own
        assert np.median(gaps) == pytest.approx(D * (1 - row.lateral_offset / 10.0), rel=0.01)
    as_json = result.as_json()
    assert [r['name'] for r in as_json['rows']] == ['left', 'right']
    assert as_json['rows'][0]['summary']['plants'] == result.row_summaries[0]['plants']
    from planter_ros.recording.replay_text import format_table
    from planter_ros.plots.replay import plot_replay
    text = format_table(result)
    assert text.splitlines()[1].startswith('row ') and '\nleft ' in text
    assert 'row right (y = -0.75 m): ' in text
    plot_replay(result, tmp_path / 'machine.png')
    assert (tmp_path / 'machine.png').stat().st_size > 10_000


def test_row_speeds_of_a_recording_follow_the_monitor_rule():
    t = np.arange(0.0, 1.0, 0.05)
    v = np.full(t.size, 0.2)
    v[5] = math.nan                                 # dropped
    v[8] = 3.5                                      # too fast: rejected
    w = np.full(t.size, 0.02)
    w[10] = math.nan                                # held
    kept, speeds = row_speed_samples((t, v, w), [0.75, -0.75, 20.0])
    assert kept.size == t.size - 2
    assert np.allclose(speeds[0], 0.2 - 0.015) and np.allclose(speeds[1], 0.2 + 0.015)
    assert np.all(speeds[2] == 0.0)                 # that row would go backwards: holds
    kept, speeds = row_speed_samples((t, -v, w), [-20.0])
    assert np.all(speeds == 0.0)                    # a machine reversing moves no row


def test_replay_of_a_three_arm_machine_reads_each_rows_carrier(tmp_path):
    from pathlib import Path
    from planter_ros.design import design_for_scene
    from planter_ros.recording.replay import replay
    from planter_ros.scene import load_scene
    from planter_ros.sim.bags import write_machine_bag
    scene = load_scene(Path(__file__).resolve().parents[1] / 'config' / 'rice_three_arm.yaml')
    design = design_for_scene(scene)
    d = design.plant_spacing
    profile = field_profile(16.0, 0.4, change=1.0, curves=[Curve(3.0, 13.0, -10.0)])
    rows = [Row(0, 'a', 1.0, 1), Row(1, 'b', -1.0, 2)]
    runs = simulate_rows(SimMachine([1.0, -1.0], timing=FAST), profile, 14.0, RowDesign(d, 3),
                         EXACT)
    write_machine_bag(rows, runs, profile, design, tmp_path / 'rice.mcap')
    result = replay(tmp_path / 'rice.mcap')
    for row, summary in zip(rows, result.row_summaries):
        plants = result.plants.table()[result.plants.row == row.index]
        assert summary['plants'] == len(plants) >= 25
        t = plants[:, 1] - 1_700_000_000.0
        steady = (t[1:] > 4.0) & (t[:-1] > 4.0) & (t[1:] < 12.0)
        # compensated: every row's plants d apart along its own distance, on the curve too
        assert np.median(np.abs(np.diff(plants[:, 2])[steady] - d)) < 0.01 * d
