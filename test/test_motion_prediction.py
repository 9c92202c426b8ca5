"""Predictions from the motion the machine measured (planter_ros.prediction.motion): a cam bag
and a constant-speed bag both predict right, and a drive that lags the cam shows in the plants.

The recordings are made here from the cam's own θ(s) (planter_ros.cam), sampled as the drive's
feedback and the ground-speed topic are: joint states at 100 Hz with the measured shaft speed,
ground speed at 20 Hz, epoch time stamps."""
import math

import numpy as np
import pytest

from planter_ros.cam import CamMechanism, plan_cam
from planter_ros.kinematics.five_bar import design_five_bar
from planter_ros.kinematics.planting import FiveBarPlanting
from planter_ros.prediction import (PlantPredictor, Plants, PredictionSettings, RowInputs,
                                    predict_plants)

DESIGN = design_five_bar(0.045, 0.15, 0.05)        # a tomato mechanism built for 0.15 m
SPEED = 0.3                                        # m/s
EPOCH = 1.7e9                                      # s: stamps as a bag holds them


@pytest.fixture(scope='module')
def mech():
    return CamMechanism.from_design(DESIGN)


def recording(profile, spacing, seconds=8.0, tau=0.0, joint_rate=100.0, speed_rate=20.0):
    """(speed t, v, joint t, θ, ω) of a row driven at SPEED along the cam `profile`; with
    `tau` > 0 the shaft follows its targets as a first-order lag of time constant tau (s)."""
    jt = stamps(seconds, joint_rate)
    s = SPEED * (jt - EPOCH)
    theta = profile.values(s, 0)
    omega = profile.values(s, 1) * SPEED
    if tau > 0:
        fine = np.arange(0.0, seconds, 1e-4)
        target = profile.values(SPEED * fine, 0)
        a = math.exp(-1e-4 / tau)
        actual = np.empty_like(target)
        actual[0] = target[0]
        for n in range(1, fine.size):
            actual[n] = a * actual[n - 1] + (1 - a) * target[n]
        theta = np.interp(jt - EPOCH, fine, actual)
        omega = np.interp(jt - EPOCH, fine, (target - actual) / tau)
    st = stamps(seconds + 0.5, speed_rate)
    return st, np.full(st.size, SPEED), jt, theta, omega


def stamps(seconds, rate):
    """Sample times as a bag gives them: epoch seconds in float64 (0.24 µs apart at 1.7e9 s);
    the samples' values are taken at these very instants."""
    return np.arange(0.0, seconds, 1.0 / rate) + EPOCH


def model_for(spacing):
    return FiveBarPlanting(DESIGN.l1, DESIGN.l2, DESIGN.depth, spacing)


def test_a_constant_speed_recording_predicts_the_constant_ratio_figures(mech):
    """At constant speeds the measured arc is the constant-ratio model's: exactly where the
    extremes are the soil edges, to 0.2 µm where one lies inside the arc (overspeed)."""
    for d in (0.15, 0.3, 0.15 / 1.2):
        model = model_for(d)
        omega = 2 * math.pi * SPEED / d
        jt, st = stamps(6.0, 100.0), stamps(6.5, 20.0)
        plants = predict_plants(RowInputs(st, np.full(st.size, SPEED), jt, omega * (jt - EPOCH),
                                          np.full(jt.size, omega)), model)
        advance = np.full(len(plants), SPEED / omega)
        assert len(plants) >= 5
        np.testing.assert_allclose(plants.tip_sweep, model.tip_sweep(advance), atol=2e-7)
        np.testing.assert_allclose(plants.tilt, model.tilt(advance), atol=1e-9)


@pytest.mark.parametrize('rule', ['design_speed', 'zero_slip'])
def test_a_cam_recording_predicts_the_cams_own_hole_and_tilt(mech, rule):
    """Planted along the planned cam, each plant's sweep and tilt are the plan's, not those of
    the instantaneous speed ratio at the planting instant (which, for exact zero slip, says
    the design hole where the cam makes a point hole)."""
    for d in (0.25, 0.4):
        plan = plan_cam(mech, d, SPEED, rule=rule, top_speeds=False)
        profile = plan.profile
        model = model_for(d)
        plants = predict_plants(RowInputs(*recording(profile, d)), model)
        assert len(plants) >= 5
        # Hermite between 100 Hz feedback samples: a few µm on the cam's in-soil curve
        np.testing.assert_allclose(plants.tip_sweep, profile.tip_sweep, atol=1e-5)
        np.testing.assert_allclose(plants.tilt, profile.tilt, atol=2e-4)
        # plant instants by the chord between feedback samples: µm on the cam's curve
        np.testing.assert_allclose(plants.spacing[1:], d, atol=1e-5)
    if rule == 'zero_slip':
        # the instantaneous ratio at the bottom is the design ratio: it would say ~2 mm
        instant = model.tip_sweep(SPEED / plants.shaft_speed)
        assert np.all(instant > 1e-3) and np.all(plants.tip_sweep < 1e-4)


def test_a_drive_lagging_the_cam_shows_in_the_holes_as_the_tip_really_moved(mech):
    """A drive following the cam with a 50 ms lag (first order) at 0.3 m/s: it enters the
    soil still catching up from the slower out-of-soil arc, so the hole widens. The predicted
    holes agree with the tip's true sweep (its path at 10 kHz) within 15 µm; the constant-
    ratio figure at the planting instant misses it by over 50 µm."""
    d, tau = 0.4, 0.05
    profile = plan_cam(mech, d, SPEED, rule='design_speed', top_speeds=False).profile
    model = model_for(d)
    on_time = predict_plants(RowInputs(*recording(profile, d)), model)
    late = predict_plants(RowInputs(*recording(profile, d, tau=tau)), model)
    true = true_sweeps(mech, profile, tau)[2:]           # after the start-up transient
    predicted = late.tip_sweep[1:]
    instant = model.tip_sweep(late.ground_speed / late.shaft_speed)[1:]
    assert predicted.min() > on_time.tip_sweep.max() + 3e-4
    assert abs(predicted.mean() - true.mean()) < 15e-6
    assert abs(instant.mean() - true.mean()) > 50e-6
    np.testing.assert_allclose(late.spacing[2:], d, atol=1e-4)


def true_sweeps(mech, profile, tau, seconds=8.0, dt=1e-4):
    """Each plant's tip sweep from the lagging shaft's path sampled every `dt`: the extent
    along the row of the tip's samples below the soil around each planting angle."""
    from planter_ros.kinematics.five_bar import soil_trajectory
    fine = np.arange(0.0, seconds, dt)
    target = profile.values(SPEED * fine, 0)
    a = math.exp(-dt / tau)
    actual = np.empty_like(target)
    actual[0] = target[0]
    for n in range(1, fine.size):
        actual[n] = a * actual[n - 1] + (1 - a) * target[n]
    x, y = soil_trajectory(mech.l1, mech.l2, actual, 0.0)
    x = x + SPEED * fine
    out = []
    k = math.ceil((actual[0] - math.pi) / (2 * math.pi))
    while actual[-1] > math.pi * (2 * k + 2):
        bottom = math.pi * (2 * k + 1)
        w = (actual > bottom - math.pi) & (actual < bottom + math.pi) & (y <= mech.depth)
        out.append(x[w].max() - x[w].min())
        k += 1
    return np.array(out)


def test_the_live_monitor_gives_the_same_cam_plants_as_replay(mech):
    """Sample by sample (joint feedback arriving late, interleaved with speed) the live
    predictor waits for each arc and then agrees with the batch to 1e-12."""
    d = 0.3
    profile = plan_cam(mech, d, SPEED, rule='zero_slip', top_speeds=False).profile
    st, sv, jt, theta, omega = recording(profile, d)
    model = model_for(d)
    batch = predict_plants(RowInputs(st, sv, jt, theta, omega), model)
    rng = np.random.default_rng(4)
    late = np.maximum.accumulate(jt + rng.uniform(0.0, 0.03, jt.size))
    arrivals = sorted([(t, 0, i) for i, t in enumerate(st)]
                      + [(t, 1, i) for i, t in enumerate(late)])
    live = PlantPredictor(model)
    parts = [live.add_speed(st[i], sv[i]) if kind == 0
             else live.add_joint(jt[i], theta[i], omega[i]) for _, kind, i in arrivals]
    streamed = Plants.concatenate(parts + [live.finish()])
    assert len(batch) >= 5
    np.testing.assert_allclose(streamed.table(), batch.table(), rtol=0, atol=1e-12,
                               equal_nan=True)


def test_an_arc_the_recording_does_not_cover_keeps_the_figures_at_the_instant(mech):
    """A recording that ends while the nozzle is still in the soil: the last plant is
    reported with the constant-ratio figures at its instant, not dropped and not invented."""
    d = 0.3
    profile = plan_cam(mech, d, SPEED, rule='zero_slip', top_speeds=False).profile
    st, sv, jt, theta, omega = recording(profile, d)
    model = model_for(d)
    full = predict_plants(RowInputs(st, sv, jt, theta, omega), model)
    # cut the joints just after the third plant's instant (its exit not yet reached)
    cut_t = full.time[2] + 0.01
    keep = jt <= cut_t
    cut = predict_plants(RowInputs(st, sv, jt[keep], theta[keep], omega[keep]), model)
    assert len(cut) == 3
    np.testing.assert_allclose(cut.tip_sweep[:2], full.tip_sweep[:2], atol=1e-12)
    at_instant = model.tip_sweep(SPEED / cut.shaft_speed[2])
    assert cut.tip_sweep[2] == pytest.approx(float(at_instant), abs=1e-12)
    assert cut.tip_sweep[2] > full.tip_sweep[2] + 1e-3
    settings = PredictionSettings()
    assert settings.max_input_gap > 0.05           # the cut is not an input gap
