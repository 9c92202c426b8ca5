"""Automatic search for a three-arm design meeting the eight goals (replaces the paper's manual
"parameter-guided" search).

scipy's differential evolution (deterministic for a given seed) over the twelve control radii
and the installation parameters Φ0, β0, S, H1, γ0; the control angles stay at the scene's (the
paper's near-even 30° spread), since moving them adds twelve dimensions and the radii already
shape the curve. The score is the sum of each goal's violation over its scale (goals.BOUNDS),
measured against bounds tightened by a small margin so that the result passes with some slack;
a design the core refuses scores 1000. The search stops at score 0, at max_time, or when DE
converges.

The population is scored as one batch per generation (`vectorized=True`): spline, closure,
gear maps, cycle and goals for all designs at once (kinematics.three_arm.batch), the batch
split over `workers` processes. A batch is a pure function of the designs in it, so a seed
gives the same search whatever the number of workers. The chosen design is checked again by
the single-design model before it is returned.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
import math
import multiprocessing
import time
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planter_ros.host.processes import die_with_parent
from planter_ros.kinematics.arrays import FloatArray

from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.three_arm.batch import CurveBasis, MechanismBatch
from planter_ros.kinematics.three_arm.gear_train import Installation, ThreeArmMechanism
from planter_ros.kinematics.three_arm.goals import (GOAL_NAMES, Goal, evaluate_goals,
                                                    goal_bounds, goal_settings, goal_values,
                                                    violation)

if TYPE_CHECKING:
    from multiprocessing.pool import Pool

# a flat scene parameter dict (planter_ros.scene.load_scene): values as the scene file gives them
SceneParams = Mapping[str, Any]
# (scores (S,), goals passing (S,)) of a batch of S designs
Scores = tuple[FloatArray, NDArray[np.int_]]

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
# DE settings: a population of 6 × 17 dimensions (the Sobol start rounds it up to 128), a
# differential weight dithered in 0.3–0.9 and crossover 0.95. With the deferred updating of a
# batched generation these reached all eight goals from the paper's scene in 2 200–7 600
# designs over seeds 1–8, where scipy's usual (0.5, 1.0) and 12 × 17 needed 15 000–38 000.
POPSIZE = 6
MUTATION = (0.3, 0.9)
RECOMBINATION = 0.95
REFUSED = 1000.0
GOAL_SAMPLES = 360


def parameters_from_vector(vector: ArrayLike, base: SceneParams) -> dict[str, Any]:
    """Scene dict with the optimised values written in (control angles from `base`)."""
    n = len(base['control_angles'])
    values = np.asarray(vector, dtype=float)
    params = dict(base)
    params['control_radii'] = [float(v) for v in values[:n]]
    for name, value in zip(INSTALL_BOUNDS, values[n:]):
        params[name] = float(value)
    return params


def score(vector: ArrayLike, base: SceneParams,
          margin: float = MARGIN) -> tuple[float, list[Goal] | None]:
    """One design, by the single-design model: sum of goal violations (0 = all eight pass with
    the margin) and the goals (None if the core refuses the design)."""
    params = parameters_from_vector(vector, base)
    try:
        mech = ThreeArmMechanism.from_parameters(params)
        goals = evaluate_goals(mech, params, samples=GOAL_SAMPLES)
    except DesignError:
        return REFUSED, None
    return float(sum(g.violation(margin) for g in goals)), goals


class BatchScorer:
    """Scores of many designs at once: `(vectors (S, N)) -> (scores (S,), goals passing (S,))`.

    Built once per search from the base scene (control angles, interpolant, goal settings).
    """

    def __init__(self, base: SceneParams, margin: float = MARGIN,
                 samples: int = GOAL_SAMPLES) -> None:
        self.n = len(base['control_angles'])
        self.basis = CurveBasis(np.asarray(base['control_angles'], dtype=float),
                                base.get('interpolant', 'periodic_cubic'))
        self.cfg = goal_settings(base)
        self.bounds = goal_bounds(self.cfg)
        self.margin = margin
        self.samples = samples

    def __call__(self, vectors: ArrayLike) -> Scores:
        vectors = np.atleast_2d(np.asarray(vectors, dtype=float))
        n = self.n
        with np.errstate(all='ignore'):
            mech = MechanismBatch(self.basis, vectors[:, :n],
                                  Installation(*vectors[:, n:n + 5].T))
            values = goal_values(mech, self.cfg, self.samples)
            total = np.zeros(len(vectors))
            passing = np.zeros(len(vectors), dtype=int)
            ok = mech.valid.copy()
            for name in GOAL_NAMES:
                lower, upper, _ = self.bounds[name]
                value = values[name]
                ok &= np.isfinite(value)
                total += violation(name, value, lower, upper, self.margin)
                inside = np.ones(len(vectors), dtype=bool)
                if lower is not None:
                    inside &= value >= lower
                if upper is not None:
                    inside &= value <= upper
                passing += inside
        return np.where(ok, total, REFUSED), np.where(ok, passing, 0)


_WORKER: dict[str, BatchScorer] = {}       # a pool worker's scorer


def _worker_init(base: SceneParams, margin: float, samples: int) -> None:
    parent = multiprocessing.parent_process()
    if parent is not None and parent.pid is not None:     # (a pool worker has one)
        die_with_parent(parent.pid)          # no orphan when the search dies
    _WORKER['scorer'] = BatchScorer(base, margin, samples)


def _worker_score(vectors: FloatArray) -> Scores:
    return _WORKER['scorer'](vectors)


class PopulationScorer:
    """BatchScorer over `workers` processes (forked once, each building its own basis): the
    batch is split in order and joined in order, so the scores do not depend on `workers`.
    Use as a context manager, or call close()."""

    def __init__(self, base: SceneParams, workers: object = 1, margin: float = MARGIN,
                 samples: int = GOAL_SAMPLES) -> None:
        if not (isinstance(workers, int) and workers >= 1):
            raise ValueError(f'workers = {workers} is out of range: allowed an integer >= 1')
        self.local = BatchScorer(base, margin, samples)     # refuses a bad scene up front
        self.workers = workers
        self._pool: Pool | None = None
        if workers > 1:
            self._pool = multiprocessing.get_context('fork').Pool(
                workers, initializer=_worker_init, initargs=(base, margin, samples))

    def __call__(self, vectors: ArrayLike) -> Scores:
        vectors = np.atleast_2d(np.asarray(vectors, dtype=float))
        if self._pool is None:
            return self.local(vectors)
        parts = self._pool.map(_worker_score, np.array_split(vectors, self.workers))
        return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]))

    def close(self) -> None:
        if self._pool is not None:
            self._pool.close()
            self._pool.join()
            self._pool = None

    def __enter__(self) -> PopulationScorer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True)
class SearchProgress:
    """Where the search stands after a generation. The "so far" figures never get worse: the
    lowest score of any design scored, and the most goals any design met (not necessarily the
    same design: the score weighs how far each goal is missed); the generation's own best
    design is reported beside them."""

    elapsed: float                   # s since the search started
    max_time: float                  # s, the time limit
    generation: int
    best_score: float                # lowest so far (0: all eight goals met with the margin)
    most_goals: int                  # most goals met by one design so far, of 8
    generation_score: float          # this generation's best design
    generation_goals: int

    def line(self) -> str:
        """One progress line of fixed width (no newline): time, the bests so far, this
        generation's best."""
        n = len(GOAL_NAMES)
        return (f'gen {self.generation:4d} {self.elapsed:6.1f}/{self.max_time:g} s  best so far: '
                f'score {self.best_score:8.4f}, most goals {self.most_goals}/{n}  this gen: '
                f'{self.generation_score:8.4f}, {self.generation_goals}/{n}')


class SearchInfo(TypedDict):
    """How a search went (SI)."""

    score: float                        # the best design's (0: all goals met with the margin)
    generations: int
    evaluations: int                    # designs scored
    seconds: float
    stopped: str                        # 'all goals met', 'generation limit', 'time limit', ...
    seed: int
    workers: int
    designs_per_second: float | None
    seconds_to_all_goals: float | None  # to the first design meeting all goals (None: none did)
    designs_to_all_goals: int | None


@dataclass
class _SearchState:
    """What the search has found so far (updated by the objective and the callback)."""

    best: float = math.inf              # the lowest score of any design scored
    passing: int = 0                    # that design's goals met
    x: FloatArray | None = None         # that design (None before the first is scored)
    evaluations: int = 0
    generation: int = 0
    stop: str = ''                      # why the search stopped ('' while it runs, converged)
    to_all_goals: tuple[float, int] | None = None    # (s, evaluations) to a design meeting all
    most_goals: int = 0                 # the most goals any design met
    latest: tuple[float, int] = (math.inf, 0)        # this generation's best (score, goals)


@dataclass(frozen=True)
class SearchOptions:
    """How a search runs: the random seed, when it stops (seconds, or generations: None for
    no limit), the population per dimension and the processes sharing each generation.

    Stopping on `max_generations` (not on time) makes a run reproducible to the bit; `workers`
    processes share each generation's batch without changing the result."""

    seed: int = 1
    max_time: float = 60.0
    popsize: int = POPSIZE
    max_generations: int | None = None
    workers: int = 1


def optimize(base: SceneParams, options: SearchOptions = SearchOptions(),
             progress: Callable[[SearchProgress], object] | None = None
             ) -> tuple[dict[str, Any], list[Goal] | None, SearchInfo]:
    """Run differential evolution from the scene `base` as `options` say; returns (params,
    goals, info). `progress(SearchProgress)` is called after every generation."""
    # lazy: scipy.optimize costs 300 ms and only a search needs it; scoring designs (BatchScorer,
    # score, the bench's batch case) does not
    from scipy.optimize import differential_evolution
    seed, max_time, popsize = options.seed, options.max_time, options.popsize
    max_generations, workers = options.max_generations, options.workers
    n = len(base['control_angles'])
    bounds = [RADIUS_BOUNDS] * n + list(INSTALL_BOUNDS.values())
    state = _SearchState()
    population = PopulationScorer(base, workers)
    start = time.monotonic()

    def objective(x: ArrayLike) -> FloatArray:
        vectors = np.asarray(x, dtype=float).T        # DE hands over (N, S)
        scores, passing = population(vectors)
        state.evaluations += len(vectors)
        i = int(np.argmin(scores))
        state.latest = (float(scores[i]), int(passing[i]))
        state.most_goals = max(state.most_goals, int(np.max(passing)))
        if scores[i] < state.best:                  # the best design so far, and its goals
            state.best, state.passing, state.x = float(scores[i]), int(passing[i]), \
                vectors[i].copy()
        if state.to_all_goals is None and np.any(passing == len(GOAL_NAMES)):
            state.to_all_goals = (time.monotonic() - start, state.evaluations)
        return scores

    def callback(intermediate_result: object) -> bool:
        state.generation += 1
        elapsed = time.monotonic() - start
        if progress is not None:
            progress(SearchProgress(elapsed, max_time, state.generation, state.best,
                                    state.most_goals, *state.latest))
        if state.best <= 0.0:
            state.stop = 'all goals met'
            return True
        if max_generations is not None and state.generation >= max_generations:
            state.stop = 'generation limit'
            return True
        if elapsed >= max_time:
            state.stop = 'time limit'
            return True
        return False

    # scipy-stubs 1.17 type neither a vectorized=True objective (it returns the (S,) scores)
    # nor bounds as (low, high) pairs nor a callback returning True to stop: all three are
    # scipy's documented API (scipy.optimize.differential_evolution)
    with population:
        differential_evolution(
            objective, bounds,  # type: ignore[arg-type]  # see above: vectorized, (low, high)
            seed=seed, popsize=popsize, tol=0.0, maxiter=100000, polish=False, init='sobol',
            callback=callback,  # type: ignore[arg-type]  # see above: True stops the search
            mutation=MUTATION, recombination=RECOMBINATION, vectorized=True,
            updating='deferred')
    seconds = time.monotonic() - start
    if state.x is None:      # DE scores its first population before anything else
        raise RuntimeError('the search scored no design')
    params = parameters_from_vector(state.x, base)
    _, goals = score(state.x, base, margin=0.0)
    to_all = state.to_all_goals
    info: SearchInfo = {
        'score': state.best, 'generations': state.generation,
        'evaluations': state.evaluations, 'seconds': seconds,
        'stopped': state.stop or 'converged', 'seed': seed, 'workers': workers,
        'designs_per_second': state.evaluations / seconds if seconds > 0 else None,
        'seconds_to_all_goals': None if to_all is None else to_all[0],
        'designs_to_all_goals': None if to_all is None else to_all[1]}
    return params, goals, info
