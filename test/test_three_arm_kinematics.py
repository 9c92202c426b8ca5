"""Three-arm gear train: closure, mating curves, the arms' invariants (paper 2 §3)."""
import math

import mpmath
import numpy as np
import pytest

from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.three_arm import PitchCurve, ThreeArmMechanism, solve_centre_distance


TWO_PI = 2 * math.pi


def test_closure_matches_mpmath_reference(mech):
    curve, a = mech.train.curve, mech.a
    mpmath.mp.dps = 30
    ends = [float(e) for e in curve.pieces]
    total = mpmath.fsum(mpmath.quad(lambda t: curve(float(t)) / (a - curve(float(t))),
                                    [ends[i], ends[i + 1]]) for i in range(len(ends) - 1))
    assert abs(float(total) / TWO_PI - 1.0) < 1e-12
    assert mech.train.closure.residual < 1e-13


def test_paper_one_degree_sum_is_the_less_accurate_method(mech):
    paper = solve_centre_distance(mech.train.curve, 'paper')
    assert paper.residual > 10 * mech.train.closure.residual
    assert abs(paper.a - mech.a) / mech.a < 1e-6      # same gear, a small error


def test_mating_curves_close(mech):
    u = np.linspace(0.0, TWO_PI, 257)
    psi, radius = mech.train.conjugate_curve(256)
    assert np.allclose(radius + mech.train.curve(u), mech.a, rtol=0, atol=1e-15)
    assert psi[-1] - psi[0] == pytest.approx(TWO_PI, abs=1e-12)       # total angle 2π
    assert np.all(np.diff(psi) > 0)


def test_mesh_maps_are_inverse_and_tabulated_accurately(mech):
    rng = np.random.default_rng(3)
    u = rng.uniform(-10, 10, 200)
    assert np.allclose(mech.train.theta(mech.train.psi(u)), u, atol=1e-10)
    curve, a = mech.train.curve, mech.a
    for t in rng.uniform(0, TWO_PI, 5):
        ref = mpmath.quad(lambda s: curve(float(s)) / (a - curve(float(s))),
                          [0.0] + [float(e) for e in curve.pieces if 0 < e < t] + [t])
        assert float(mech.train.psi(t)) == pytest.approx(float(ref), abs=1e-9)


def test_each_arm_returns_to_its_start_pose_after_one_turn(mech):
    theta = np.linspace(0, TWO_PI, 37)
    for arm in range(3):
        x0, y0 = mech.tip(theta, arm)
        x1, y1 = mech.tip(theta + TWO_PI, arm)
        assert np.allclose(x1, x0, atol=1e-12) and np.allclose(y1, y0, atol=1e-12)
        assert np.allclose(mech.attitude(theta + TWO_PI, arm), mech.attitude(theta, arm),
                           atol=1e-10)
        assert mech.planet_relative_angle(TWO_PI, arm) == pytest.approx(TWO_PI, abs=1e-10)


def test_arms_are_the_same_curve_shifted_by_120_degrees(mech):
    theta = np.linspace(0, TWO_PI, 91)
    x0, y0 = mech.tip(theta, 0)
    for arm in (1, 2):
        shift = arm * TWO_PI / 3
        x, y = mech.tip(theta + shift, arm)
        assert np.allclose(x, x0, atol=1e-12) and np.allclose(y, y0, atol=1e-12)
        # carrier frame: the same loop turned by 120°·k
        xr, yr = mech.tip_relative(theta, arm)
        xr0, yr0 = mech.tip_relative(theta - shift, 0)
        c, s = math.cos(shift), math.sin(shift)
        assert np.allclose(xr, c * xr0 - s * yr0, atol=1e-12)
        assert np.allclose(yr, s * xr0 + c * yr0, atol=1e-12)


def test_cycle_equals_per_arm_evaluation(mech):
    theta, tips, alphas = mech.cycle(90)
    for arm in range(3):
        x, y = mech.tip(theta, arm)
        assert np.allclose(tips[arm, 0], x) and np.allclose(tips[arm, 1], y)
        assert np.allclose(alphas[arm], mech.attitude(theta, arm))


def test_pitch_points_coincide_at_both_meshes(mech):
    """Sun–intermediate and intermediate–planet pitch points lie on the lines of centres."""
    for th in (0.0, 1.0, 2.5):
        (o2x, o2y), (o3x, o3y) = mech.centres(th)
        # planet pitch point: radius ρ(w) from O3 towards O2
        w = float(mech.planet_mesh_angle(th))
        r_p = float(mech.train.curve(w))
        r_i = mech.a - r_p
        assert math.hypot(o3x - o2x, o3y - o2y) == pytest.approx(r_p + r_i, abs=1e-15)
        ang = math.atan2(o2y - o3y, o2x - o3x)
        phi3 = float(mech.attitude(th)) + mech.beta0
        assert math.remainder(phi3 - w - ang, TWO_PI) == pytest.approx(0.0, abs=1e-12)


def test_trigonometric_interpolant_is_swappable(params):
    p = dict(params, interpolant='trigonometric')
    mech = ThreeArmMechanism.from_parameters(p)
    assert mech.train.closure.residual < 1e-12
    assert np.allclose(mech.train.curve(np.array(p['control_angles'])), p['control_radii'],
                       atol=1e-12)


@pytest.mark.parametrize('change, word', [
    ({'control_radii': [0.02] * 11}, 'control_angles'),
    ({'control_radii': [0.02] * 11 + [-0.01]}, 'control_radii'),
    ({'pusher_offset': 0.2}, 'pusher_offset'),
    ({'arm_length': 0.0}, 'arm_length'),
    ({'interpolant': 'bezier'}, 'interpolant'),
    ({'control_radii': [0.001, 0.08] * 6}, 'control_radii'),    # spline dips through 0
])
def test_bad_parameters_raise_one_line_design_error(params, change, word):
    with pytest.raises(DesignError) as err:
        ThreeArmMechanism.from_parameters(dict(params, **change))
    assert word in str(err.value) and '\n' not in str(err.value)


def test_missing_parameter_is_named(params):
    p = dict(params)
    del p['arm_length']
    with pytest.raises(DesignError, match='arm_length'):
        ThreeArmMechanism.from_parameters(p)


def test_pitch_curve_passes_through_control_points(params):
    curve = PitchCurve(params['control_radii'], params['control_angles'])
    assert np.allclose(curve(np.array(params['control_angles'])), params['control_radii'],
                       atol=1e-15)
