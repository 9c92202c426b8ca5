"""Five-bar reverse design against the paper, the exact relation and mpmath references."""
import math

import mpmath
import numpy as np
import pytest

from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.five_bar import (
    GearedChain, chain_kinematics, design_five_bar, dyad_closure, dyad_positions, hole_geometry,
    hole_ratio_limit, psi_minus_sin, soil_trajectory, soil_velocity, solve_psi,
    static_trajectory, sun_bar_speed)

TOMATO = dict(depth=0.045, spacing=0.200, hole_ratio=0.05)


def test_paper_method_reproduces_published_tomato_lengths():
    d = design_five_bar(**TOMATO, method='paper')
    published_mm = dict(l1=114, l2=146, l3=365, l4=391, l5=339)
    for name, value in published_mm.items():
        assert getattr(d, name) * 1000 == pytest.approx(value, abs=1.0), name


def test_exact_method_tomato_values_and_hole_equals_request():
    d = design_five_bar(**TOMATO)
    assert d.l1 * 1000 == pytest.approx(112.94, abs=0.01)
    assert d.l2 * 1000 == pytest.approx(144.77, abs=0.01)
    assert d.hole_width == pytest.approx(0.05 * 0.045, rel=1e-12)
    assert d.l2 - d.l1 == pytest.approx(0.2 / (2 * math.pi), rel=1e-12)


def test_paper_method_designs_a_smaller_hole_than_asked():
    paper = design_five_bar(**TOMATO, method='paper')
    err = (paper.hole_width - paper.requested_hole) / paper.requested_hole
    assert -0.02 < err < -0.015          # about -1.8 % for the tomato case


def test_field_test_point_sun_bar_speed():
    v = 0.72 / 3.6                        # 0.72 km/h
    omega = 60 * 2 * math.pi / 60         # 60 r/min
    assert sun_bar_speed(v, 0.2) == pytest.approx(omega, rel=1e-12)
    assert design_five_bar(**TOMATO).sun_bar_speed(v) == pytest.approx(omega, rel=1e-12)


@pytest.mark.parametrize('c', [1e-14, 1e-9, 1e-5, 1e-3, 0.1, 0.5, 1.0, 2.0, 3.0, 3.14, 3.1415])
def test_solve_psi_matches_mpmath(c):
    mpmath.mp.dps = 40
    ref = mpmath.findroot(lambda p: p - mpmath.sin(p) - mpmath.mpf(c), mpmath.cbrt(6 * c) * 1.01)
    assert solve_psi(c) == pytest.approx(float(ref), rel=4e-16)
    assert solve_psi(np.array([c]))[0] == pytest.approx(float(ref), rel=4e-16)


@pytest.mark.parametrize('psi', [1e-8, 1e-4, 0.3, 0.99, 1.0, 1.01, 2.5, math.pi])
def test_psi_minus_sin_full_relative_precision(psi):
    mpmath.mp.dps = 40
    ref = mpmath.mpf(psi) - mpmath.sin(mpmath.mpf(psi))
    assert psi_minus_sin(psi) == pytest.approx(float(ref), rel=1e-15)


def test_batch_equals_scalar():
    depth = np.array([0.02, 0.045, 0.1, 0.3])
    spacing = np.array([0.1, 0.2, 0.5, 1.5])
    k = np.array([0.05, 0.1, 0.3, 0.02])
    batch = design_five_bar(depth, spacing, k)
    for i in range(4):
        one = design_five_bar(float(depth[i]), float(spacing[i]), float(k[i]))
        for name in ('l1', 'l2', 'l3', 'l4', 'l5', 'hole_width', 'min_transmission_angle'):
            assert getattr(batch, name)[i] == pytest.approx(getattr(one, name), rel=1e-14)
        assert bool(batch.assemblable[i]) == one.assemblable


@pytest.mark.parametrize('kwargs, needle', [
    (dict(depth=0.045, spacing=0.2, hole_ratio=5.0), 'hole_ratio'),
    (dict(depth=0.045, spacing=0.2, hole_ratio=2.0), 'l1 > 0'),
    (dict(depth=-0.045, spacing=0.2), 'depth'),
    (dict(depth=0.045, spacing=float('nan')), 'spacing'),
    (dict(depth=0.045, spacing=float('inf')), 'spacing'),
    (dict(depth=0.045, spacing=0.2, hole_ratio=0.0), 'hole_ratio'),
    (dict(depth=0.045, spacing=0.2, method='guess'), 'method'),
])
def test_infeasible_input_raises_one_line_error_naming_the_limit(kwargs, needle):
    with pytest.raises(DesignError) as info:
        design_five_bar(**kwargs)
    text = str(info.value)
    assert needle in text and 'allowed' in text and '\n' not in text


def test_hole_ratio_limit_is_the_feasibility_edge():
    k_max = hole_ratio_limit(0.045, 0.2)
    assert k_max == pytest.approx(1.5377, abs=1e-3)
    design_five_bar(0.045, 0.2, k_max * (1 - 1e-9))
    with pytest.raises(DesignError):
        design_five_bar(0.045, 0.2, k_max * (1 + 1e-9))


def test_batch_error_names_the_bad_index():
    with pytest.raises(DesignError, match='batch index 1'):
        design_five_bar(np.array([0.045, 0.045]), 0.2, np.array([0.05, 9.0]))


def test_designed_trajectory_has_zero_horizontal_speed_at_the_bottom():
    d = design_five_bar(**TOMATO)
    omega = 2 * math.pi
    vx, vy = soil_velocity(d.l1, d.l2, math.pi, omega, d.advance * omega)
    assert abs(vx) < 1e-12 and abs(vy) < 1e-12


def test_general_chain_reduces_to_the_static_ellipse_and_derivatives_are_consistent():
    d = design_five_bar(**TOMATO)
    alpha = np.linspace(0, 2 * math.pi, 50)
    (x, y), (vx, vy), (ax, ay) = chain_kinematics(alpha, 3.0, GearedChain(d.l1, d.l2))
    sx, sy = static_trajectory(d.l1, d.l2, alpha)
    np.testing.assert_allclose(x, sx, atol=1e-15)
    np.testing.assert_allclose(y, sy, atol=1e-15)
    # velocity and acceleration against central differences in time, for another gear ratio
    h = 1e-6
    omega = 2.5
    for ratio in (-2.0, 1.5):
        chain = GearedChain(d.l1, d.l2, ratio, 0.3, -0.2)
        p0 = chain_kinematics(alpha, omega, chain)
        pp = chain_kinematics(alpha + omega * h, omega, chain)
        pm = chain_kinematics(alpha - omega * h, omega, chain)
        for i in range(2):
            np.testing.assert_allclose((pp[0][i] - pm[0][i]) / (2 * h), p0[1][i], atol=1e-6)
            np.testing.assert_allclose((pp[1][i] - pm[1][i]) / (2 * h), p0[2][i], atol=1e-5)


def _sampled_hole(d, advance, n=400001):
    psi = hole_geometry(d.l1, d.l2, d.depth, advance).psi
    theta = np.linspace(math.pi - psi, math.pi + psi, n)
    x, _ = soil_trajectory(d.l1, d.l2, theta, advance)
    return x.max() - x.min()


@pytest.mark.parametrize('lam', [0.3, 0.8, 0.97, 1.0, 1.03, 1.3, 3.0, 50.0])
def test_hole_geometry_matches_dense_sampling_for_any_speed_ratio(lam):
    d = design_five_bar(**TOMATO)
    advance = (d.l2 - d.l1) / lam
    hole = hole_geometry(d.l1, d.l2, d.depth, advance)
    assert hole.width == pytest.approx(_sampled_hole(d, advance), rel=1e-6, abs=1e-9)
    assert hole.width >= hole.entry_exit - 1e-15


def test_hole_width_against_speed_ratio_has_its_minimum_just_above_sync():
    """Dragging (λ < 1) always widens the hole; a slight overspeed first narrows it.

    Below the surface the path is h(φ) = advance·φ - a sin φ: at λ slightly above 1 the small
    backward loop at the bottom pulls entry and exit together, so the swept extent is smallest
    near λ* ≈ 1.05 (tomato), about a quarter of the zero-speed hole, and grows beyond it. Zero
    speed at the bottom (λ = 1) is what keeps the seedling upright, not what minimises the hole.
    """
    d = design_five_bar(**TOMATO)
    a = d.l2 - d.l1
    below = hole_geometry(d.l1, d.l2, d.depth, a / np.array([0.5, 0.7, 0.9, 0.99, 1.0])).width
    assert below[-1] == pytest.approx(d.hole_width, rel=1e-12)
    assert np.all(np.diff(below) < 0)
    lams = np.linspace(1.0, 1.5, 5001)
    widths = hole_geometry(d.l1, d.l2, d.depth, a / lams).width
    i_min = int(np.argmin(widths))
    assert 1.01 < lams[i_min] < 1.1
    assert widths[i_min] < 0.3 * d.hole_width
    assert np.all(np.diff(widths[:i_min]) < 0) and np.all(np.diff(widths[i_min + 1:]) > 0)
    assert widths[-1] > d.hole_width


def test_stopped_machine_hole_is_the_static_ellipse_width():
    d = design_five_bar(**TOMATO)
    hole = hole_geometry(d.l1, d.l2, d.depth, 0.0)
    assert hole.width == pytest.approx(2 * (d.l2 - d.l1) * math.sin(hole.psi), rel=1e-12)


def test_dyad_closure_closed_form_matches_sampled_cycle():
    d = design_five_bar(**TOMATO)
    theta = np.linspace(0, 2 * math.pi, 200001)
    _, _, mu = dyad_positions(d, theta)
    sampled = np.min(np.minimum(mu, math.pi - mu))
    assert d.assemblable
    assert d.min_transmission_angle == pytest.approx(sampled, abs=1e-8)


def test_dyad_points_keep_link_lengths_over_the_cycle():
    d = design_five_bar(**TOMATO)
    theta = np.linspace(0, 2 * math.pi, 361)
    dx, dy, _ = dyad_positions(d, theta)
    cx, cy = static_trajectory(d.l1, d.l2, theta)
    np.testing.assert_allclose(np.hypot(dx - cx, dy - cy), d.l3, rtol=1e-12)
    np.testing.assert_allclose(np.hypot(dx + d.l5, dy), d.l4, rtol=1e-12)
    # no branch flip: D moves continuously
    assert np.max(np.hypot(np.diff(dx), np.diff(dy))) < 0.05 * d.l3


def test_short_dyad_is_reported_not_assemblable():
    d = design_five_bar(**TOMATO, dyad_ratios=(0.5, 0.5, 1.3))
    assert d.assemblable is False and d.min_transmission_angle == 0.0
    ok, mu = dyad_closure(d.l1, d.l2, d.l3, d.l4, d.l5)
    assert ok is False and mu == 0.0
    with pytest.raises(DesignError, match='dyad'):
        dyad_positions(d, np.linspace(0, 2 * math.pi, 10))
