"""The electronic cam's core (planter_ros.cam): C2 and periodic profiles, zero slip in the soil,
the design hole at every spacing, the loads and their physics, the limit report."""
import math

import numpy as np
import pytest

from planter_ros.cam import (CamInputError, CamMechanism, CamSpec, DriveLimits, build_profile,
                             constant_law, constant_profile, plan_cam, rule_law,
                             rule_top_speed, sampled_tip_sweep)
from planter_ros.cam.drive import GRAVITY
from planter_ros.cam.plan import BLEND_HEADROOM
from planter_ros.kinematics.five_bar import design_five_bar, hole_geometry
from planter_ros.kinematics.planting import FiveBarPlanting
from planter_ros.prediction import PredictionSettings, plant_values

TOMATO_015 = design_five_bar(0.045, 0.15, 0.05)      # the mechanism the issue designs for 0.15 m
TOMATO_020 = design_five_bar(0.045, 0.2, 0.05)       # the paper's tomato design


@pytest.fixture(scope='module')
def mech():
    return CamMechanism.from_design(TOMATO_015)


@pytest.fixture(scope='module')
def plans(mech):
    """The design-speed and zero-slip cams at 0.3 m/s over the issue's spacings."""
    return {(rule, d): plan_cam(mech, d, 0.3, rule=rule, top_speeds=False)
            for rule in ('design_speed', 'zero_slip') for d in (0.15, 0.2, 0.3, 0.4, 0.5)}


def jumps_at_breaks(profile):
    """Largest |left − right| of θ, θ′, θ″ at the period's inner breaks and across its ends
    (the next period starts 2π further on), each over its own scale."""
    p = profile.period
    worst = [0.0, 0.0, 0.0]
    for i in range(1, p.breaks.size - 1):
        b = p.breaks[i]
        x = b - p.breaks[i - 1]
        c = p.coeffs[i - 1]
        left = (np.polyval(c[::-1], x), np.polyval(np.polyder(c[::-1]), x),
                np.polyval(np.polyder(c[::-1], 2), x))
        right = p.coeffs[i][0], p.coeffs[i][1], 2 * p.coeffs[i][2]
        for k in range(3):
            worst[k] = max(worst[k], abs(left[k] - right[k]))
    end = p.at(p.end)
    start = p.at(p.start)
    for k, shift in enumerate((2 * math.pi, 0.0, 0.0)):
        worst[k] = max(worst[k], abs(end[k] - start[k] - shift))
    return worst


def test_every_profile_is_c2_at_every_break_and_across_the_period(plans):
    for (rule, d), plan in plans.items():
        p = plan.profile
        scale = (1.0, max(abs(p.values(np.linspace(0, d, 2001), 1)).max(), 1.0),
                 max(abs(p.values(np.linspace(0, d, 2001), 2)).max(), 1.0))
        jumps = jumps_at_breaks(p)
        assert all(j <= 1e-9 * s for j, s in zip(jumps, scale)), (rule, d, jumps)


def test_the_profile_is_periodic_per_plant_and_plants_at_the_bottom(plans):
    rng = np.random.default_rng(3)
    for (_, d), plan in plans.items():
        p = plan.profile
        for s in rng.uniform(-3.0, 30.0, 50):
            a, b = p.evaluate(s), p.evaluate(s + d)
            assert b[0] - a[0] == pytest.approx(2 * math.pi, abs=1e-9)
            assert b[1] == pytest.approx(a[1], rel=1e-9, abs=1e-9)
            assert b[2] == pytest.approx(a[2], rel=1e-7, abs=1e-6)
        for k in (-3, 0, 1, 7, 1000):
            assert p.evaluate(k * d)[0] == pytest.approx(math.pi + 2 * math.pi * k, abs=1e-9)


def test_scalar_evaluation_matches_scipy_on_the_same_function_far_down_the_row(plans):
    p = plans[('zero_slip', 0.3)].profile
    s = np.concatenate((np.linspace(-0.5, 0.8, 2001), 5000.0 + np.linspace(0, 0.3, 301)))
    got = np.array([p.evaluate(x) for x in s])
    for order in range(3):
        assert np.max(np.abs(got[:, order] - p.values(s, order))) <= 1e-9 * (1 + order * 1e3)


def test_exact_zero_slip_holds_the_tip_still_in_the_soil(mech, plans):
    for d in (0.15, 0.3, 0.5):
        p = plans[('zero_slip', d)].profile
        s = np.linspace(-p.entry, p.entry, 4001)
        x, y = mech.tip(p.values(s), s)
        assert np.all(y <= mech.depth * (1 + 1e-9))
        assert np.ptp(x) <= 1e-9                              # a point hole
        assert p.tip_sweep == 0.0
        assert sampled_tip_sweep(p, 200_000) <= 1e-9


def test_the_design_speed_cam_makes_the_design_hole_with_no_tilt_at_every_spacing(mech, plans):
    hole = mech.design_hole
    assert hole == pytest.approx(0.05 * 0.045, rel=1e-9)
    for d in (0.15, 0.2, 0.3, 0.4, 0.5):
        plan = plans[('design_speed', d)]
        assert plan.exact and plan.feasible
        p = plan.profile
        s = np.linspace(-p.entry, p.entry, 101)
        assert np.allclose(p.values(s, 1), 1.0 / mech.a, rtol=1e-12)     # θ′ = 1/(l2 − l1)
        assert p.tip_sweep == pytest.approx(hole, rel=1e-9)
        assert abs(sampled_tip_sweep(p) - hole) <= 2e-7
        assert abs(p.tilt) <= 1e-12
    # constant speed at the other spacings: the drag the issue measured grows with d
    sweeps = [constant_profile(mech, d).tip_sweep for d in (0.15, 0.2, 0.3, 0.4, 0.5)]
    assert sweeps[0] == pytest.approx(hole, rel=1e-9) and np.all(np.diff(sweeps) > 0.01)


def test_the_sweep_is_the_five_bar_hole_and_the_tilt_the_monitors_model(mech):
    for d in (0.12, 0.2, 0.45):
        law = constant_law(d)
        assert law.tip_sweep(mech) == pytest.approx(
            hole_geometry(mech.l1, mech.l2, mech.depth, d / (2 * math.pi)).width, rel=1e-12)
        model = FiveBarPlanting(mech.l1, mech.l2, mech.depth, d)
        omega, v = 5.0, 5.0 * d / (2 * math.pi)
        tilt = plant_values(model, PredictionSettings(), omega, v)[3]
        assert law.tilt(mech) == pytest.approx(float(tilt), rel=1e-12)
    # a blend's sweep, in closed form, against the sampled tip path
    zero, design = rule_law(mech, 'zero_slip'), rule_law(mech, 'design_speed')
    for beta, other in ((0.3, design), (0.6, constant_law(0.4))):
        p = build_profile(CamSpec(mech, 0.4, 0.3, DriveLimits(), 'zero_slip'),
                          zero.blend(other, beta), beta)
        assert abs(sampled_tip_sweep(p) - p.tip_sweep) <= 5e-7


def test_the_zero_slip_edge_acceleration_is_the_issues_991_v2(mech):
    """The issue's figure for D = 45 mm is the paper's tomato design (d = 0.2 m): θ″ at the soil
    edge is sin ψ / (a² cos³ ψ)."""
    m20 = CamMechanism.from_design(TOMATO_020)
    psi, a = m20.psi, m20.a
    edge = math.sin(psi) / (a * a * math.cos(psi) ** 3)
    assert 985 < edge < 995
    p = build_profile(CamSpec(m20, 0.3, 0.3, DriveLimits(), 'zero_slip'),
                      rule_law(m20, 'zero_slip'), 1.0)
    for v in (0.2, 0.3, 0.5):
        assert p.figures(v).peak_acceleration == pytest.approx(edge * v * v, rel=1e-6)


def test_the_design_speed_cam_needs_several_times_less_acceleration_than_zero_slip(plans):
    for d in (0.2, 0.3, 0.4, 0.5):
        cam = plans[('design_speed', d)].figures.peak_acceleration
        zero = plans[('zero_slip', d)].figures.peak_acceleration
        assert 3.0 < zero / cam < 8.0


def test_loads_scale_with_speed_as_the_cam_is_a_function_of_distance(plans):
    p = plans[('design_speed', 0.4)].profile
    slow, fast = p.figures(0.2), p.figures(0.4)
    assert fast.peak_speed == pytest.approx(2 * slow.peak_speed, rel=1e-12)
    assert fast.peak_acceleration == pytest.approx(4 * slow.peak_acceleration, rel=1e-12)
    assert fast.peak_jerk == pytest.approx(8 * slow.peak_jerk, rel=1e-12)


def test_the_mechanism_torque_does_no_net_work_over_a_plant(mech, plans):
    """The load model is conservative (inertia and weight): over one periodic plant the sun
    bar's torque does no net work, ∮T dθ = 0, and with the weight alone it is m g L sin θ."""
    drive = DriveLimits()
    for key in (('design_speed', 0.4), ('zero_slip', 0.2)):
        p = plans[key].profile
        s = np.linspace(0.0, p.spacing, 400_001)
        th, d1, d2 = (p.values(s, k) for k in range(3))
        v = 0.4
        torque = drive.sun_bar_torque(mech, th, v * d1, v * v * d2)
        work = np.trapezoid(torque * d1, s)
        scale = np.trapezoid(np.abs(torque * d1), s)
        assert abs(work) <= 1e-6 * scale
    still = drive.sun_bar_torque(mech, np.array([0.5 * math.pi]), 0.0, 0.0)[0]
    assert still == pytest.approx(-drive.tip_mass * GRAVITY * mech.total, rel=1e-12)


def test_the_out_of_soil_arc_never_reverses_the_sun_bar(plans):
    for (rule, d), plan in plans.items():
        rate = plan.profile.values(np.linspace(0.0, d, 200_001), 1)
        assert rate.min() >= -1e-9 * rate.max(), (rule, d, rate.min())


def test_a_tight_limit_is_reported_and_the_closest_feasible_profile_returned(mech):
    drive = DriveLimits(max_speed=20.0)            # the design-speed cam needs 1/a·v in soil
    plan = plan_cam(mech, 0.3, 0.6, drive, top_speeds=False)
    assert not plan.rule_figures.feasible and plan.rule_figures.exceeded == ['speed']
    assert plan.binding == 'speed'
    assert plan.feasible and 0.0 < plan.blend < 1.0
    assert plan.blended_with == 'constant speed'
    # planned to the headroom a run-time change into it needs, not to the limit itself
    assert plan.figures.utilisation['speed'] == pytest.approx(BLEND_HEADROOM, abs=2e-3)
    # closer to the rule leaves less: the next β up passes the headroom
    law = rule_law(mech, 'design_speed').blend(constant_law(0.3), plan.blend + 2e-3)
    above = build_profile(CamSpec(mech, 0.3, 0.6, drive, 'design_speed'), law, plan.blend + 2e-3)
    assert above.figures(0.6).utilisation['speed'] > BLEND_HEADROOM
    # its sweep and tilt lie between the rule's and constant speed's
    const = constant_profile(mech, 0.3, drive)
    assert mech.design_hole < plan.profile.tip_sweep < const.tip_sweep
    assert 0.0 < plan.profile.tilt < const.tilt


def test_zero_slip_falls_back_through_the_design_speed_rule(mech):
    plan = plan_cam(mech, 0.3, 0.5, rule='zero_slip', top_speeds=False)
    assert not plan.rule_figures.feasible and 'jerk' in plan.rule_figures.exceeded
    assert plan.feasible and plan.blend_of == 'exact zero slip'
    assert plan.blended_with == 'design-speed rule'
    assert 0.0 <= plan.profile.tip_sweep < mech.design_hole


def test_nothing_feasible_returns_constant_speed_and_says_so(mech):
    drive = DriveLimits(max_speed=5.0)             # below 2πv/d even at constant speed
    plan = plan_cam(mech, 0.3, 0.5, drive, top_speeds=False)
    assert not plan.feasible and plan.blend == 0.0
    assert plan.blended_with == 'constant speed' and plan.profile.law.name == 'constant speed'
    assert plan.figures.exceeded == ['speed']


def test_the_top_speed_of_a_rule_is_where_its_limit_binds(mech):
    for rule in ('design_speed', 'zero_slip'):
        v, limit = rule_top_speed(mech, 0.3, rule, DriveLimits())
        assert 0.1 < v < 3.0
        law = rule_law(mech, rule)
        at = build_profile(CamSpec(mech, 0.3, v, DriveLimits(), rule), law, 1.0).figures(v)
        beyond = build_profile(CamSpec(mech, 0.3, 1.03 * v, DriveLimits(), rule), law,
                               1.0).figures(1.03 * v)
        assert at.feasible and not beyond.feasible
        assert limit in beyond.exceeded
    # the design-speed cam turns at 1/a in the soil: the sun-bar speed limit stops it
    v, limit = rule_top_speed(mech, 0.3, 'design_speed', DriveLimits())
    assert limit == 'speed'
    assert v == pytest.approx(DriveLimits().effective(mech).speed * mech.a, rel=1e-3)


def test_the_default_drive_is_the_named_servo_and_gearbox():
    d = DriveLimits()
    assert (d.motor_rated_torque, d.motor_peak_torque, d.rotor_inertia) == (2.39, 8.36, 1.59e-4)
    assert d.motor_max_speed == pytest.approx(6000 * 2 * math.pi / 60)
    assert d.gear_ratio == 20.0
    with pytest.raises(CamInputError, match='gear_ratio = 0.5 is out of range'):
        DriveLimits(gear_ratio=0.5)


def test_bad_mechanisms_and_spacings_are_refused_in_one_line(mech):
    cases = [(lambda: CamMechanism(0.1, 0.05, 0.04), 'l2 = 0.05'),
             (lambda: CamMechanism(0.1, 0.2, 0.7), 'depth = 0.7'),
             (lambda: CamMechanism(float('nan'), 0.2, 0.04), 'l1 = nan'),
             (lambda: plan_cam(mech, 0.01, 0.3), 'spacing = 0.01'),
             (lambda: plan_cam(mech, 0.3, 9.0), 'speed = 9'),
             (lambda: plan_cam(mech, 0.3, 0.3, rule='fast'), 'rule = fast'),
             (lambda: rule_law(CamMechanism(0.02, 0.05, 0.1), 'zero_slip'), 'depth = 0.1')]
    for make, text in cases:
        with pytest.raises(CamInputError) as err:
            make()
        assert text in str(err.value) and 'allowed' in str(err.value)
        assert '\n' not in str(err.value)
    # a spacing shorter than the rule's in-soil arc
    wide = CamMechanism.from_design(design_five_bar(0.1, 1.5, 0.3))
    with pytest.raises(CamInputError, match='spacing = 0.05 is out of range'):
        plan_cam(wide, 0.05, 0.3)
