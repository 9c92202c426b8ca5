"""Property tests over the whole agronomic domain: a finite design whose invariants hold, or the
documented DesignError — never NaN, never a silent wrong answer."""
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.five_bar import (
    design_five_bar, hole_geometry, hole_ratio_limit, soil_velocity)

depths = st.floats(0.001, 0.5)
spacings = st.floats(0.05, 2.0)
# fraction of the feasibility edge, dense near 0 and near 1
edge_fractions = st.one_of(st.floats(1e-9, 1.0 - 1e-9),
                           st.floats(0.999, 1.0 - 1e-12), st.floats(1e-12, 1e-3))


def _check_invariants(d, depth, spacing, k):
    lengths = [d.l1, d.l2, d.l3, d.l4, d.l5, d.hole_width, d.psi, d.min_transmission_angle]
    assert all(math.isfinite(v) for v in lengths)
    assert d.l1 > 0 and d.l2 > d.l1
    total = d.l1 + d.l2
    # l2 - l1 = d/2π up to round-off of the subtraction
    assert abs((d.l2 - d.l1) - spacing / (2 * math.pi)) <= 8e-16 * total
    # zero horizontal velocity at the bottom of the designed trajectory
    omega = 1.0
    vx, _ = soil_velocity(d.l1, d.l2, math.pi, omega, spacing / (2 * math.pi) * omega)
    assert abs(vx) <= 8e-16 * total * omega
    # the hole achieved equals k·D; round-off is amplified by 1/sin ψ near ψ = π, and the
    # round-off of the bars themselves moves it by 2(d/2π - (l2 - l1)) sin ψ (kept <= 1e-9)
    kappa = 1.0 + 4.0 / (math.pi * max(math.sin(d.psi), 1e-300))
    bars = 4 * 2.2e-16 * total * math.sin(d.psi)
    assert abs(d.hole_width - k * depth) <= max(1e-12, 50 * kappa * 2.2e-16) * k * depth + bars


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(depths, spacings, edge_fractions)
def test_exact_design_over_the_feasible_domain(depth, spacing, frac):
    k = frac * hole_ratio_limit(depth, spacing)
    try:
        d = design_five_bar(depth, spacing, k)
    except DesignError as exc:
        # only a hole ratio so small that the mechanism would be unbounded may be refused here
        assert 'hole_ratio' in str(exc)
        return
    _check_invariants(d, depth, spacing, k)


@settings(max_examples=200, deadline=None)
@given(depths, spacings, st.floats(1.0 + 1e-9, 1e3))
def test_beyond_the_edge_raises_the_documented_error(depth, spacing, over):
    k = over * hole_ratio_limit(depth, spacing)
    with pytest.raises(DesignError, match='hole_ratio'):
        design_five_bar(depth, spacing, k)


@settings(max_examples=150, deadline=None)
@given(depths, spacings, edge_fractions, st.floats(-5.0, 50.0))
def test_hole_geometry_is_finite_for_any_speed_ratio(depth, spacing, frac, inv_lambda):
    k = frac * hole_ratio_limit(depth, spacing)
    try:
        d = design_five_bar(depth, spacing, k)
    except DesignError:
        return
    advance = inv_lambda * (d.l2 - d.l1)
    hole = hole_geometry(d.l1, d.l2, depth, advance)
    assert all(math.isfinite(v) for v in (hole.width, hole.entry_x, hole.exit_x, hole.psi))
    assert hole.width >= hole.entry_exit * (1 - 1e-12) >= 0


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(depths, spacings, st.floats(1e-6, 1.0 - 1e-6)), min_size=1,
                max_size=64))
def test_batch_agrees_with_scalar_everywhere(rows):
    depth = np.array([r[0] for r in rows])
    spacing = np.array([r[1] for r in rows])
    k = np.array([r[2] for r in rows]) * hole_ratio_limit(depth, spacing)
    ones = []
    for i in range(len(rows)):
        try:
            ones.append(design_five_bar(float(depth[i]), float(spacing[i]), float(k[i])))
        except DesignError:
            # a row the scalar path refuses (hole too small for float bars) fails the batch
            with pytest.raises(DesignError, match='hole_ratio'):
                design_five_bar(depth, spacing, k)
            return
    batch = design_five_bar(depth, spacing, k)
    assert np.all(np.isfinite(batch.l1)) and np.all(np.isfinite(batch.hole_width))
    for i, one in enumerate(ones):
        assert batch.l1[i] == pytest.approx(one.l1, rel=1e-12, abs=1e-15)
        assert batch.hole_width[i] == pytest.approx(one.hole_width, rel=1e-12)


@pytest.mark.parametrize('k', [1e-12, 1e-30, 1e-200])
def test_vanishing_hole_ratio_gives_a_huge_but_finite_design_or_a_clear_error(k):
    try:
        d = design_five_bar(0.045, 0.2, k)
    except DesignError as exc:
        assert 'finite' in str(exc)
        return
    assert math.isfinite(d.l1) and d.hole_width == pytest.approx(k * 0.045, rel=1e-9)
