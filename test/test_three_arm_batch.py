"""A batch of three-arm designs (the optimiser's population) gives what each design gives alone,
and the optimiser scores, stops and reports the way a user reads it."""
import math

import numpy as np
import pytest

from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.three_arm import Installation, ThreeArmMechanism
from planter_ros.kinematics.three_arm.batch import CurveBasis, MechanismBatch
from planter_ros.kinematics.three_arm.goals import GOAL_NAMES, goal_settings, goal_values
from planter_ros.optimize.three_arm import (INSTALL_BOUNDS, RADIUS_BOUNDS, BatchScorer,
                                            SearchOptions, optimize, parameters_from_vector,
                                            score)


NAMES = tuple(INSTALL_BOUNDS)


def random_designs(params, count, seed):
    """The paper's design first, then designs from the optimiser's search box."""
    rng = np.random.default_rng(seed)
    n = len(params['control_angles'])
    radii = rng.uniform(*RADIUS_BOUNDS, (count, n))
    install = np.column_stack([rng.uniform(lo, hi, count) for lo, hi in INSTALL_BOUNDS.values()])
    radii[0] = params['control_radii']
    install[0] = [params[k] for k in NAMES]
    return radii, install


@pytest.mark.parametrize('interpolant', ['periodic_cubic', 'bspline_polar', 'trigonometric'])
def test_batch_goals_equal_single_design_goals(params, interpolant):
    radii, install = random_designs(params, 24, seed=7)
    cfg = goal_settings(params)
    batch = MechanismBatch(CurveBasis(params['control_angles'], interpolant), radii,
                           Installation(*install.T))
    assert batch.valid.all()
    got = goal_values(batch, cfg, samples=360)
    compared = 0
    for i in range(len(radii)):
        p = dict(params, interpolant=interpolant, control_radii=list(radii[i]),
                 **dict(zip(NAMES, install[i])))
        try:
            mech = ThreeArmMechanism.from_parameters(p)
        except DesignError:
            continue          # the single-design closure may refuse a spiky curve; the batch not
        want = goal_values(mech, cfg, samples=360)
        assert batch.a[i, 0] == pytest.approx(mech.a, rel=1e-11)
        for name in GOAL_NAMES + ('zero_slip_spacing',):
            # ρ's extremes (gearbox) are sampled in a batch, found by roots alone: ≤ 1 µm apart
            tol = 1e-6 if name == 'gearbox_clearance' else 1e-9
            assert got[name][i] == pytest.approx(float(want[name]), abs=tol), (i, name)
        compared += 1
    assert compared >= 18


def test_batch_marks_designs_the_core_refuses_and_stays_finite(params):
    radii, install = random_designs(params, 4, seed=3)
    radii[1, 3] = -0.01             # a negative control radius
    install[2, 3] = 0.5             # pusher offset H1 beyond the arm length S
    radii[3] = [0.065, 0.065, 0.001, 0.001] * 3    # dips to ρ < 0 between the points
    batch = MechanismBatch(CurveBasis(params['control_angles']), radii, Installation(*install.T))
    assert batch.valid.tolist() == [True, False, False, False]
    values = goal_values(batch, goal_settings(params), samples=180)
    assert all(np.all(np.isfinite(values[name])) for name in GOAL_NAMES)
    scores, passing = BatchScorer(params, samples=180)(np.column_stack([radii, install]))
    assert scores[0] < 1000 and np.all(scores[1:] == 1000) and np.all(passing[1:] == 0)


def test_a_batch_needs_a_curve_linear_in_the_radii(params):
    with pytest.raises(DesignError, match='bspline_cartesian') as info:
        CurveBasis(params['control_angles'], 'bspline_cartesian')
    assert 'periodic_cubic' in str(info.value) and '\n' not in str(info.value)


def test_batch_scores_equal_single_design_scores(params):
    radii, install = random_designs(params, 12, seed=11)
    vectors = np.column_stack([radii, install])
    scores, passing = BatchScorer(params)(vectors)
    for i, v in enumerate(vectors):
        value, goals = score(v, params)
        if goals is None:
            continue
        # ≤ 1 µm on the gearbox clearance (sampled ρ extremes) over its 10 mm scale
        assert scores[i] == pytest.approx(value, abs=1e-4)
        assert passing[i] == sum(g.passed for g in goals)


def test_tip_velocity_is_the_derivative_of_the_tip(params):
    mech = ThreeArmMechanism.from_parameters(params)
    theta = np.linspace(0.1, 6.2, 37)
    h = 1e-6
    for arm in range(3):
        dx, dy = mech.tip_velocity(theta, arm)
        (x1, y1), (x0, y0) = mech.tip(theta + h, arm), mech.tip(theta - h, arm)
        assert np.allclose(dx, (x1 - x0) / (2 * h), atol=1e-7)
        assert np.allclose(dy, (y1 - y0) / (2 * h), atol=1e-7)


def test_optimiser_is_deterministic_and_the_same_on_two_workers(params):
    one = optimize(params, SearchOptions(seed=5, max_time=1e9, max_generations=3, popsize=4))
    again = optimize(params, SearchOptions(seed=5, max_time=1e9, max_generations=3, popsize=4))
    two = optimize(params, SearchOptions(seed=5, max_time=1e9, max_generations=3, popsize=4,
                                          workers=2))
    assert one[0] == again[0] == two[0]
    # scipy rounds a Sobol population up to a power of two: 4·17 -> 128, four batches
    assert one[2]['evaluations'] == two[2]['evaluations'] == 128 * 4
    assert one[2]['stopped'] == 'generation limit'


def test_progress_reports_the_best_design_so_far(params):
    seen = []
    options = SearchOptions(seed=2, max_time=1e9, max_generations=6, popsize=4)
    params_out, goals, info = optimize(params, options, progress=seen.append)
    assert [s.generation for s in seen] == list(range(1, 7))
    bests = [s.best_score for s in seen]
    assert bests == sorted(bests, reverse=True)            # never worse than before
    value, checked = score([*params_out['control_radii'], *(params_out[k] for k in NAMES)],
                           params)
    assert value == pytest.approx(bests[-1], abs=1e-4)
    assert bests[-1] == info['score']
    assert seen[-1].most_goals >= sum(g.passed for g in checked) == sum(g.passed for g in goals)


def test_the_progress_line_never_shows_a_best_getting_worse(params):
    """The bests "so far" never get worse from one line to the next (the most goals met
    included: the lowest score's design may meet fewer); the generation's own best may, and is
    shown apart."""
    seen = []
    optimize(params, SearchOptions(seed=1, max_time=1e9, max_generations=12),
             progress=seen.append)
    best = [s.best_score for s in seen]
    most = [s.most_goals for s in seen]
    assert best == sorted(best, reverse=True) and most == sorted(most)
    assert all(s.generation_score >= s.best_score and s.generation_goals <= s.most_goals
               for s in seen)
    # a run where the generation's own best does get worse, so the test can tell
    assert any(b.generation_score > a.generation_score for a, b in zip(seen, seen[1:]))
    lines = [s.line() for s in seen]
    assert len({len(line) for line in lines}) == 1          # a carriage return overwrites it
    assert f'most goals {most[-1]}/8' in lines[-1] and 'this gen' in lines[-1]


def test_parameters_from_vector_keeps_the_control_angles(params):
    v = np.r_[np.full(12, 0.03), [0.1, 0.2, 0.15, 0.05, -0.3]]
    p = parameters_from_vector(v, params)
    assert p['control_angles'] == params['control_angles']
    assert p['control_radii'] == [0.03] * 12 and p['planet_carrier_angle'] == -0.3
    assert math.isclose(p['arm_length'], 0.15)
