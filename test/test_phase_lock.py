"""The phase-locked speed law, without ROS or CAN: limits, bad samples, stale speed, and a
closed-loop simulation showing spacing stays bounded where speed-only control drifts."""
import math

import numpy as np

import pytest

from planter_ros.control.phase_lock import ControlConfigError, PhaseLock, PhaseLockConfig
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
from planter_ros.sim.closed_loop import (
    DriveModel, DriveSchedule, SpeedSensor, run_comparison, simulate)
from planter_ros.sim.field import field_profile
from planter_ros.sim.spacing import plant_positions, spacing_stats

D = 0.2            # tomato spacing (m)


def tracking_law(v=0.2, limits=None, **cfg):
    law = PhaseLock(PhaseLockConfig(**cfg), limits)
    law.set_design(D, 1, 0.0)
    law.feedback(0.0, 0.0, 0.0)
    law.ground_speed(v, 0.0)
    return law


def run_constant(law, v, t0, t1, dt=0.02, angle=None):
    """Feed samples at v and feedback that follows the command exactly; return last command."""
    theta = angle if angle is not None else 0.0
    cmd = 0.0
    t = t0
    while t < t1:
        t += dt
        law.ground_speed(v, t)
        theta += cmd * dt
        law.feedback(theta, cmd, t)
        cmd = law.command(t)
    return cmd, theta


def test_speed_tracks_paper_relation_v_equals_d_omega_over_2pi():
    for n, v in ((1, 0.2), (1, 0.35), (3, 0.6)):
        law = PhaseLock(PhaseLockConfig(max_speed=50.0))
        law.set_design(D, n, 0.0)
        law.feedback(0.0, 0.0, 0.0)
        cmd, _ = run_constant(law, v, 0.0, 5.0)
        assert cmd == pytest.approx(2 * math.pi * v / (n * D), rel=1e-3)


def test_speed_and_acceleration_limits():
    law = tracking_law(v=0.0, max_speed=5.0, max_acceleration=10.0)
    law.ground_speed(0.001, 0.01)
    law.command(0.01)
    law.ground_speed(0.04, 0.02)        # slow ramp so the spike check lets it through
    cmds = [law.command(0.02)]
    t = 0.02
    for v in [0.05 + 0.05 * i for i in range(20)]:
        t += 0.02
        law.ground_speed(v, t)
        cmds.append(law.command(t))
    steps = [b - a for a, b in zip(cmds, cmds[1:])]
    assert max(steps) <= 10.0 * 0.02 + 1e-12
    cmd, _ = run_constant(law, 1.0, t, t + 3.0)
    assert cmd == pytest.approx(5.0)    # 2π·1.0/0.2 = 31 rad/s asked, limited to 5


def test_command_never_negative_when_machine_stops_or_reverses():
    law = tracking_law()
    cmd, theta = run_constant(law, 0.2, 0.0, 2.0)
    assert cmd > 5.0
    # mechanism far ahead of the distance: a phase-locked law would want to turn back
    law.feedback(theta + 2.0, 0.0, 2.0)
    t = 2.0
    for v in (0.15, 0.1, 0.05, 0.0, -0.02, -0.05, -0.05):
        t += 0.05
        law.ground_speed(v, t)
        assert law.command(t) >= 0.0
    assert law.rejected['negative'] == 3
    assert law.feed_forward(t) == 0.0
    s = law.travelled(t)
    law.ground_speed(-0.05, t + 0.05)
    assert law.travelled(t + 0.1) == s          # reversing is not integrated backwards


@pytest.mark.parametrize('bad,reason', [(math.nan, 'non_finite'), (math.inf, 'non_finite'),
                                        (-math.inf, 'non_finite'), (25.0, 'too_fast'),
                                        (1.2, 'spike'), (-0.5, 'spike')])
def test_bad_samples_rejected_counted_and_not_followed(bad, reason):
    law = tracking_law()
    cmd, _ = run_constant(law, 0.2, 0.0, 2.0)
    assert law.ground_speed(bad, 2.01) == reason
    assert law.rejected[reason] == 1
    assert law.ground_speed_value == 0.2
    assert math.isfinite(law.command(2.01))
    assert law.command(2.02) == pytest.approx(cmd, abs=0.2)


def test_persistent_genuine_step_is_accepted_after_plausible_time():
    law = tracking_law(limits=GroundSpeedLimits(max_ground_acceleration=2.0,
                                                 ground_speed_tolerance=0.05))
    run_constant(law, 0.2, 0.0, 1.0)
    t, verdicts = 1.0, []
    for _ in range(20):                 # a real jump to 0.6 m/s, sampled at 50 Hz
        t += 0.02
        verdicts.append(law.ground_speed(0.6, t))
    assert verdicts[0] == 'spike'
    assert verdicts[-1] is None         # accepted once 0.05 + 2.0·Δt covers 0.4 m/s
    assert law.ground_speed_value == 0.6


def test_stale_ground_speed_ramps_to_zero_then_halts():
    law = tracking_law(ground_speed_timeout=0.5, max_acceleration=10.0)
    cmd, theta = run_constant(law, 0.2, 0.0, 2.0)
    assert law.state(2.0) == 'tracking'
    t, cmds = 2.0, []
    while t < 4.0:                      # no more samples
        t += 0.02
        theta += cmds[-1] * 0.02 if cmds else cmd * 0.02
        law.feedback(theta, cmds[-1] if cmds else cmd, t)
        cmds.append(law.command(t))
    assert law.stale(t)
    assert cmds[-1] == 0.0
    assert all(b <= a + 1e-12 for a, b in zip(cmds[25:], cmds[26:]))   # a ramp, no jump
    assert max(a - b for a, b in zip([cmd] + cmds, cmds)) <= 10.0 * 0.02 + 1e-12
    assert law.state(t) == 'halted (stale ground speed)'
    # travelled distance stopped growing at the timeout
    assert law.travelled(t) == pytest.approx(law.travelled(2.5))


def test_phase_correction_catches_up_a_lagging_mechanism_but_is_bounded():
    law = tracking_law(max_correction=1.0, phase_gain=4.0)
    run_constant(law, 0.2, 0.0, 2.0)
    ff = 2 * math.pi * 0.2 / D
    law.feedback(law.target_angle(2.1) - 0.1, ff, 2.1)      # 0.1 rad behind
    assert law.command(2.1) == pytest.approx(ff + 0.4, abs=1e-6)
    law.feedback(law.target_angle(2.2) - 2.0, ff, 2.2)      # far behind: correction saturates
    assert law.command(2.2) == pytest.approx(ff + 1.0, abs=1e-6)


def test_speed_only_mode_has_no_correction():
    law = tracking_law(phase_lock=False)
    run_constant(law, 0.2, 0.0, 2.0)
    law.feedback(law.target_angle(2.0) - 1.0, 0.0, 2.0)
    assert law.command(2.0) == pytest.approx(2 * math.pi * 0.2 / D)


def test_more_than_one_plant_behind_skips_whole_plants_keeping_the_grid():
    law = tracking_law()
    run_constant(law, 0.2, 0.0, 1.0)
    target = law.target_angle(1.0)
    law.feedback(target - 2 * math.pi * 2.3, 0.0, 1.0)   # a fault stopped it 2.3 plants back
    law.command(1.0)
    assert law.phase_slips == 2
    assert law.last_error == pytest.approx(0.3 * 2 * math.pi)


def test_invalid_config_is_refused_in_one_line():
    with pytest.raises(ControlConfigError, match='max_speed = -1'):
        PhaseLockConfig(max_speed=-1)
    with pytest.raises(ControlConfigError, match='plant_spacing'):
        PhaseLock().set_design(math.nan, 1, 0.0)


def test_plant_positions_of_a_perfect_mechanism_are_on_the_grid():
    import numpy as np
    t = np.linspace(0.0, 10.0, 10001)
    s = 0.2 * t
    theta = 2 * math.pi * s / D
    pos = plant_positions(theta, s, 2 * math.pi)
    assert len(pos) == 10
    assert np.allclose(np.diff(pos), D)
    stats = spacing_stats(pos, D)
    assert stats.max_abs_drift < 1e-9


# ---------------------------------------------------------------- closed loop
def test_spacing_bounded_through_speed_step_and_drive_lag_where_speed_only_drifts():
    """A speed change 0.2 -> 0.3 m/s, and half-way the drive gets four times slower (load)."""
    cfg = PhaseLockConfig()
    slow = DriveModel(time_constant=0.2, max_acceleration=15.0)
    res = run_comparison(cfg, D, 1, field_profile(30.0, 0.2),
                         DriveSchedule(changes=((12.0, slow),)), SpeedSensor())
    locked, speed_only = res['phase_locked'], res['speed_only']
    assert locked.plants >= 30
    # within 15 mm (7.5 % of d) of the grid throughout: a P phase loop keeps an error of about
    # (acceleration · drive lag / gain) while the speed ramps, and nothing accumulates
    assert locked.max_abs_drift < 0.015
    assert speed_only.max_abs_drift > 2 * locked.max_abs_drift
    assert speed_only.max_abs_spacing_error > locked.max_abs_spacing_error


def test_speed_scale_error_accumulates_without_phase_lock_only():
    """A drive that turns 3 % slower than asked (gear-ratio parameter off, loaded speed loop)."""
    res = run_comparison(PhaseLockConfig(), D, 1, field_profile(30.0, 0.2),
                         DriveModel(speed_scale=0.97), SpeedSensor())
    assert res['phase_locked'].max_abs_drift < 0.01
    assert res['speed_only'].max_abs_drift > 0.1       # > half a plant spacing lost


def test_simulated_run_survives_bad_and_missing_samples():
    law = PhaseLock(PhaseLockConfig())
    law.set_design(D, 1, 0.0)
    base = field_profile(20.0, 0.2)

    def sensor(t, v):                   # drops out for 0.8 s and spikes now and then
        if 8.0 < t < 8.8:
            return math.nan
        return 5.0 if int(t * 20) % 37 == 0 else v

    sim = simulate(law, base, 20.0, sensor=SpeedSensor(read=sensor))
    assert law.rejected['non_finite'] > 0 and law.rejected['too_fast'] > 0
    assert all(math.isfinite(x) for x in sim.command) and min(sim.command) >= 0.0


# ---------------------------------------------------------------- design changes
def drive_through_design_change(d_new, t_change, planting, v=0.2, duration=8.0, dt=0.005,
                                lag=0.05):
    """The law against a first-order drive at constant v; d changes to d_new at t_change.
    Returns (plant positions, target angle just before and after each step, switch time)."""
    law = PhaseLock(PhaseLockConfig())
    law.set_design(D, 1, 0.0, planting)
    law.feedback(0.0, 0.0, 0.0)
    theta = omega = 0.0
    t, times, angles, jumps, switched = 0.0, [], [], [], None
    while t < duration:
        t += dt
        law.ground_speed(v, t)
        if abs(t - t_change) < dt / 2:
            law.set_design(d_new, 1, t)
        before = law.target_angle(t)
        cmd = law.command(t)
        jumps.append(abs(law.target_angle(t) - before))
        if switched is None and law.spacing == d_new:
            switched = t
        omega += (cmd - omega) * dt / lag
        theta += omega * dt
        law.feedback(theta, omega, t)
        times.append(t)
        angles.append(theta)
    positions = plant_positions(angles, v * np.asarray(times), 2 * math.pi,
                                release=planting.phase if planting else math.pi)
    return law, positions, max(jumps), switched


def test_a_new_design_takes_effect_at_the_next_planting_instant_and_the_grid_goes_on():
    from planter_ros.control.phase_lock import PlantingAngles
    planting = PlantingAngles(math.pi, 0.6, 0.6)     # plants at the bottom, θ = π + 2πk
    law, positions, jump, switched = drive_through_design_change(0.3, 3.31, planting)
    # the old grid puts plants at 0.1 + 0.2·k m; the change comes at s = 0.662 m, so the
    # plant at 0.7 m is still the old design's and from there plants follow every 0.3 m
    assert np.allclose(positions[1:], [0.3, 0.5, 0.7, 1.0, 1.3, 1.6], atol=0.003)
    assert switched == pytest.approx(0.7 / 0.2, abs=0.011)   # at that plant's instant
    # the target angle is continuous: between two commands it moves by no more than one
    # step's distance at the faster of the two rates
    assert jump <= 2 * math.pi * 0.2 * 0.005 * (1 / D - 1 / 0.3) * 1.01
    assert not law.design_pending and law.phase_slips == 0


def test_without_planting_angles_a_new_design_applies_at_once_without_a_phase_jump():
    law, positions, jump, switched = drive_through_design_change(0.3, 3.31, None)
    assert switched == pytest.approx(3.31, abs=0.006)
    assert jump < 1e-9 and law.phase_slips == 0
    gaps = np.diff(positions)
    # the gap in progress stretches between d and the new d, then the new spacing
    assert np.allclose(gaps[-2:], 0.3, atol=0.006) and gaps[1:].min() > 0.195 and gaps.max() < 0.31


def test_distance_has_no_lag_behind_the_samples_through_a_speed_change():
    # the demo's speed change 0.2 -> 0.3 m/s over 1 s, sampled at 20 Hz: the distance the
    # mechanism is locked to is the trapezoid of the samples (what replay places plants at),
    # not the samples held (which fell 25 ms behind: 2.5 mm for every plant after the change)
    law = tracking_law()
    v = lambda t: 0.2 + 0.1 * min(max(t - 1.0, 0.0), 1.0)      # noqa: E731
    exact = lambda t: 0.2 * t + 0.05 * min(max(t - 1.0, 0.0), 1.0) ** 2 \
        + 0.1 * max(t - 2.0, 0.0)                                    # noqa: E731
    worst = 0.0
    for k in range(1, 81):
        t = 0.05 * k
        law.ground_speed(v(t), t)
        for h in (0.0, 0.02, 0.049):             # between samples it runs on, continuous
            worst = max(worst, abs(law.travelled(t + h) - exact(t + h)))
    assert abs(law.travelled(4.0) - exact(4.0)) < 1e-9
    assert worst < 0.3e-3
    held = 0.05 * sum(v(0.05 * k) for k in range(0, 80))      # the samples held: behind
    assert exact(4.0) - held == pytest.approx(0.5 * 0.1 * 0.05, rel=0.05)


def test_distance_runs_on_the_trapezoid_of_noisy_samples_without_adding_up_their_noise():
    rng = np.random.default_rng(3)
    law = tracking_law()
    t = np.arange(1, 601) * 0.05
    v = 0.2 + rng.normal(0.0, 0.005, t.size)
    trapezoid = np.cumsum(np.diff(np.concatenate(([0.0], t))) * 0.5
                          * (v + np.concatenate(([0.2], v[:-1]))))
    off = []
    for ti, vi, s in zip(t, v, trapezoid):
        law.ground_speed(vi, ti)
        off.append(law.travelled(ti) - s)
    assert max(abs(x) for x in off) < 1e-3          # 30 s of samples: bounded, no random walk
    assert abs(off[-1]) < 0.5e-3


def test_distance_and_feed_forward_never_run_backwards_when_the_machine_stops():
    law = tracking_law(v=0.3)
    t, last = 0.0, 0.0
    for v in (0.3, 0.2, 0.1, 0.0, 0.0, 0.0):
        t += 0.05
        law.ground_speed(v, t)
        for h in (0.0, 0.025):
            assert law.travelled(t + h) >= last
            assert law.feed_forward(t + h) >= 0.0
            last = law.travelled(t + h)


def test_a_sample_soon_after_a_gap_does_not_rush_the_gaps_correction():
    # 0.4 s without samples across a 0.2 -> 0.3 m/s change, then samples every 50 ms: the
    # gap's trapezoid correction (10 mm) goes in over the gap's length, not the next 50 ms
    law = tracking_law()
    t, fastest = 0.0, 0.0
    for k in range(20):
        t = 0.05 * (k + 1)
        law.ground_speed(0.2, t)
    before = law.travelled(t)
    for t_next in [t + 0.4] + [t + 0.4 + 0.05 * k for k in range(1, 20)]:
        law.ground_speed(0.3, t_next)
        for h in (0.0, 0.02, 0.04):
            fastest = max(fastest, law.feed_forward(t_next + h) * D / (2 * math.pi))
    assert fastest <= 0.3 + 0.5 * 0.1 + 1e-9            # 10 mm over 0.4 s: 25 mm/s more at most
    assert law.travelled(t + 1.5) == pytest.approx(            # all of it, in the end
        before + 0.5 * (0.2 + 0.3) * 0.4 + 0.3 * 1.1, abs=1e-9)
