"""Automatic search for a three-arm design meeting the eight goals (replaces the paper's manual
"parameter-guided" search).

scipy's differential evolution (deterministic for a given seed, one worker: the machine is
shared) over the twelve control radii and the installation parameters Φ0, β0, S, H1, γ0; the
control angles stay at the scene's (the paper's near-even 30° spread), since moving them adds
twelve dimensions and the radii already shape the curve. The score is the sum of each goal's
violation over its scale (goals.BOUNDS), measured against bounds tightened by a small margin
so that the result passes with some slack; a design the core refuses (DesignError) scores
1000. The search stops at score 0, at max_time, or when DE converges.
"""

import math
import time

from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.three_arm.gear_train import ThreeArmMechanism
from planter_ros.kinematics.three_arm.goals import evaluate_goals

DEG = math.pi / 180.0
RADIUS_BOUNDS = (0.015, 0.065)
INSTALL_BOUNDS = {                       # name: (low, high), SI
    'carrier_initial_angle': (-math.pi, math.pi),
    'arm_initial_angle': (-math.pi, math.pi),
    'arm_length': (0.10, 0.20),
    'pusher_offset': (0.02, 0.09),
    'planet_carrier_angle': (-100.0 * DEG, 100.0 * DEG),
}
MARGIN = 0.1            # fraction of each goal's scale kept inside its bounds
REFUSED = 1000.0
GOAL_SAMPLES = 360


def parameters_from_vector(vector, base):
    """Scene dict with the optimised values written in (control angles from `base`)."""
    n = len(base['control_angles'])
    params = dict(base)
    params['control_radii'] = [float(v) for v in vector[:n]]
    for name, value in zip(INSTALL_BOUNDS, vector[n:]):
        params[name] = float(value)
    return params


def score(vector, base, margin=MARGIN):
    """Sum of goal violations (0 = all eight pass with the margin); also the goals."""
    params = parameters_from_vector(vector, base)
    try:
        mech = ThreeArmMechanism.from_parameters(params)
        goals = evaluate_goals(mech, params, samples=GOAL_SAMPLES)
    except DesignError:
        return REFUSED, None
    return float(sum(g.violation(margin) for g in goals)), goals


def optimize(base, seed=1, max_time=60.0, popsize=12, progress=None, max_generations=None):
    """Run differential evolution from the scene `base`; returns (params, goals, info).

    Stopping on `max_generations` (not on time) makes a run reproducible to the bit.
    """
    from scipy.optimize import differential_evolution
    n = len(base['control_angles'])
    bounds = [RADIUS_BOUNDS] * n + list(INSTALL_BOUNDS.values())
    start = time.monotonic()
    state = {'best': math.inf, 'evaluations': 0, 'generation': 0, 'stop': ''}

    def objective(vector):
        state['evaluations'] += 1
        return score(vector, base)[0]

    def callback(intermediate_result):
        state['generation'] += 1
        state['best'] = float(intermediate_result.fun)
        elapsed = time.monotonic() - start
        if progress is not None:
            _, goals = score(intermediate_result.x, base, margin=0.0)
            passing = sum(g.passed for g in goals) if goals else 0
            progress(elapsed, state['generation'], state['best'], passing, max_time)
        if state['best'] <= 0.0:
            state['stop'] = 'all goals met'
            return True
        if max_generations is not None and state['generation'] >= max_generations:
            state['stop'] = 'generation limit'
            return True
        if elapsed >= max_time:
            state['stop'] = 'time limit'
            return True
        return False

    result = differential_evolution(objective, bounds, seed=seed, popsize=popsize, tol=0.0,
                                    maxiter=100000, polish=False, init='sobol',
                                    mutation=(0.5, 1.0), recombination=0.9,
                                    callback=callback, workers=1, updating='immediate')
    params = parameters_from_vector(result.x, base)
    value, goals = score(result.x, base, margin=0.0)
    info = {'score': state['best'], 'generations': state['generation'],
            'evaluations': state['evaluations'], 'seconds': time.monotonic() - start,
            'stopped': state['stop'] or 'converged', 'seed': seed}
    return params, goals, info
