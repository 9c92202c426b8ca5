"""What moves the five-bar's hole: analytic sensitivities (against central finite differences)
and the Monte Carlo hole-width range of built machines, as a designer reads them."""
import json
import math

from hypothesis import assume, given, settings, strategies as st
import numpy as np
import pytest

from planter_ros.kinematics.five_bar import (design_five_bar, hole_geometry, hole_sensitivity,
                                             hole_tolerance)

from cli_helpers import run_planter

TOMATO = (0.045, 0.2, 0.05)
QUANTITIES = ('l1', 'l2', 'depth', 'speed_ratio')


def width(l1, l2, depth, advance):
    return hole_geometry(l1, l2, depth, advance).width


def central_differences(l1, l2, depth, advance, rel=1e-5):
    """∂W/∂x by central differences, with the same fixed quantities as hole_sensitivity."""
    lam = (l2 - l1) / advance
    funcs = {'l1': (lambda v: width(v, l2, depth, advance), l1),
             'l2': (lambda v: width(l1, v, depth, advance), l2),
             'depth': (lambda v: width(l1, l2, v, advance), depth),
             'speed_ratio': (lambda v: width(l1, l2, depth, (l2 - l1) / v), lam)}
    out = {}
    for name, (f, x) in funcs.items():
        h = rel * abs(x)
        out[name] = (f(x + h) - f(x - h)) / (2 * h)
    return out


def branch_gap(l1, l2, depth, advance):
    """Relative distance between the exit and turning-point half-widths (0 at a kink)."""
    hole = hole_geometry(l1, l2, depth, advance)
    return abs(hole.width - 2 * abs(hole.exit_x)) / hole.width


@pytest.mark.parametrize('lam', [0.5, 0.9, 1.0, 1.02, 1.07, 1.1, 1.5, 3.0])
def test_tomato_sensitivities_agree_with_central_differences(lam):
    d = design_five_bar(*TOMATO)
    advance = (d.l2 - d.l1) / lam
    s = hole_sensitivity(d.l1, d.l2, d.depth, advance)
    fd = central_differences(d.l1, d.l2, d.depth, advance)
    for name in QUANTITIES:
        assert getattr(s, name) == pytest.approx(fd[name], rel=1e-6), name


def test_both_branches_of_the_hole_are_exercised():
    """λ 1.07 and 1.1 sit where the backward loop, not the exit, sets the width."""
    d = design_five_bar(*TOMATO)
    a = d.l2 - d.l1
    loop = [lam for lam in (1.0, 1.07, 1.1, 1.5)
            if hole_geometry(d.l1, d.l2, d.depth, a / lam).width
            > 2 * abs(hole_geometry(d.l1, d.l2, d.depth, a / lam).exit_x) * (1 + 1e-9)]
    assert loop == [1.07, 1.1]


@settings(max_examples=60, deadline=None, derandomize=True)
@given(depth=st.floats(0.02, 0.1), spacing=st.floats(0.15, 0.6), k_frac=st.floats(0.02, 0.5),
       lam=st.floats(0.3, 4.0))
def test_sensitivities_agree_with_central_differences_over_the_domain(depth, spacing, k_frac,
                                                                      lam):
    from planter_ros.kinematics.five_bar import hole_ratio_limit
    d = design_five_bar(depth, spacing, k_frac * hole_ratio_limit(depth, spacing))
    advance = (d.l2 - d.l1) / lam
    assume(branch_gap(d.l1, d.l2, d.depth, advance) > 1e-3)     # no derivative at a kink
    s = hole_sensitivity(d.l1, d.l2, d.depth, advance)
    fd = central_differences(d.l1, d.l2, d.depth, advance)
    for name in QUANTITIES:
        assert getattr(s, name) == pytest.approx(fd[name], rel=1e-6, abs=1e-9 * d.l2), name


def test_batch_sensitivities_equal_the_scalar_ones():
    d = design_five_bar(np.array([0.045, 0.06]), np.array([0.2, 0.3]), 0.05)
    s = hole_sensitivity(d.l1, d.l2, d.depth, d.advance)
    for i in range(2):
        one = hole_sensitivity(float(d.l1[i]), float(d.l2[i]), float(d.depth[i]),
                               float(d.advance[i]))
        for name in QUANTITIES:
            assert getattr(s, name)[i] == pytest.approx(getattr(one, name), rel=1e-14)


def test_the_tomato_figures_a_designer_needs():
    """0.1 mm on l2 moves the 2.25 mm hole about 5 %, 1 mm of depth 3.4 %, 0.01 of λ 17 %."""
    d = design_five_bar(*TOMATO)
    s = hole_sensitivity(d.l1, d.l2, d.depth, d.advance)
    hole = d.hole_width
    assert s.width == pytest.approx(hole, rel=1e-12)
    assert s.l2 * 1e-4 / hole == pytest.approx(-0.051, abs=0.001)
    assert s.l1 * 1e-4 / hole == pytest.approx(0.050, abs=0.001)
    assert s.depth * 1e-3 / hole == pytest.approx(0.034, abs=0.001)
    assert s.speed_ratio * 0.01 / hole == pytest.approx(-0.170, abs=0.001)


def test_monte_carlo_matches_linear_propagation_for_small_tolerances():
    """Uniform ±M on each bar: std ≈ M·sqrt((∂W/∂l1)² + (∂W/∂l2)²)/√3 while W is linear."""
    d = design_five_bar(*TOMATO)
    s = hole_sensitivity(d.l1, d.l2, d.depth, d.advance)
    m = 1e-6
    t = hole_tolerance(d, m, 0.0)
    assert t['samples'] >= 100_000
    assert t['std'] == pytest.approx(m * math.hypot(s.l1, s.l2) / math.sqrt(3), rel=0.01)
    f = 1e-5        # speed only: λ = 1/(1 + e), ∂W/∂e ≈ −∂W/∂λ
    t = hole_tolerance(d, 0.0, f)
    assert t['std'] == pytest.approx(f * abs(s.speed_ratio) / math.sqrt(3), rel=0.01)


def test_monte_carlo_range_percentiles_and_determinism():
    d = design_five_bar(*TOMATO)
    t = hole_tolerance(d, 1e-4, 0.01)
    assert t == hole_tolerance(d, 1e-4, 0.01)                     # seeded
    p = t['percentiles']
    values = [t['min']] + [p[k] for k in ('0.1', '1', '5', '50', '95', '99', '99.9')] + \
        [t['max']]
    assert values == sorted(values)
    assert t['min'] < t['nominal'] < t['max']
    # the extremes are those of the corners of the tolerance box (W is monotone there)
    corners = [width(d.l1 + a * 1e-4, d.l2 + b * 1e-4, d.depth, d.advance * (1 + c * 0.01))
               for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]
    assert min(corners) <= t['min'] < min(corners) * 1.02
    assert max(corners) * 0.98 < t['max'] <= max(corners)
    hist = t['histogram']
    assert sum(hist['counts']) == t['samples'] and len(hist['edges']) == len(hist['counts']) + 1
    json.dumps(t)
    exact = hole_tolerance(d, 0.0, 0.0)
    assert exact['min'] == exact['max'] == pytest.approx(d.hole_width, rel=1e-12)


def test_cli_json_reports_sensitivity_and_tolerance():
    out = run_planter('design', 'five-bar', '--depth', '0.045', '--spacing', '0.2', '--json',
                      '--tolerance', '0.0001', '--speed-error', '0.01')
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    assert set(r['sensitivity']) == set(QUANTITIES)
    assert r['sensitivity']['l2'] == pytest.approx(-1.1425, rel=1e-4)        # m per m
    t = r['tolerance']
    assert t['bar_tolerance'] == 0.0001 and t['speed_error'] == 0.01
    assert t['min'] < r['hole_width'] < t['max'] and t['samples'] >= 100_000
    plain = json.loads(run_planter('design', 'five-bar', '--depth', '0.045', '--spacing', '0.2',
                                   '--json').stdout)
    assert 'tolerance' not in plain and 'sensitivity' in plain


def test_cli_table_shows_sensitivities_and_the_range():
    out = run_planter('design', 'five-bar', '--depth', '0.045', '--spacing', '0.2',
                      '--speed-error', '0.01')
    assert out.returncode == 0, out.stderr
    assert 'hole width sensitivity' in out.stdout and '(-17.0 %)' in out.stdout
    assert 'min … max' in out.stdout and 'speed ±1 %' in out.stdout


@pytest.mark.parametrize('args, needle', [
    (['--tolerance', '-0.001'], '--tolerance'),
    (['--tolerance', 'nan'], '--tolerance'),
    (['--tolerance', '0.05'], 'a tenth of l1'),
    (['--speed-error', '-0.01'], '--speed-error'),
    (['--speed-error', 'inf'], '--speed-error'),
    (['--speed-error', '2'], '0..0.2'),
    (['--speed-error', '0.45'], '0..0.2'),          # 45 %: a broken sensor, not an error
    (['--tolerance', 'x'], '--tolerance'),
])
def test_bad_tolerances_are_one_line_exit_2(args, needle):
    out = run_planter('design', 'five-bar', '--depth', '0.045', '--spacing', '0.2', *args)
    assert out.returncode == 2 and out.stdout == ''
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and 'Traceback' not in out.stderr
