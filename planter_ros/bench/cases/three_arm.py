"""Three-arm rows: gear-train closure (our Gauss rule vs the paper's 1° sum and the uniform
trapezoid rule) against an mpmath reference, the build of a gear train, and one full cycle of
all three arms after the build."""

from __future__ import annotations

from collections.abc import Iterator
import math
from typing import Any

import mpmath
import numpy as np

from planter_ros.kinematics.arrays import FloatArray
from planter_ros.kinematics.three_arm import PitchCurve, ThreeArmMechanism, solve_centre_distance
from planter_ros.optimize.three_arm import (INSTALL_BOUNDS, RADIUS_BOUNDS, PopulationScorer,
                                            SearchOptions, optimize, score)
from planter_ros.scene import default_scene_path, load_scene

from ..registry import BenchContext, Row, Target, bench_case
from ..timing import from_samples

CLOSURE_TARGET = 1e-9          # quality target: gear-closure integral <= 1e-9 relative
CYCLE_TARGET = 1e-3            # ... and a full three-arm cycle <= 1 ms
CLOSURE_ERROR_OF = ('|a − a_ref| / a_ref, centre distance vs mpmath (30 digits) on the same '
                    'pitch curve; the closure residual |mean ratio − 1| is in the note')


def _paper_scene() -> dict[str, Any]:
    return load_scene(default_scene_path('rice_three_arm.yaml'), 'design_node')


def _mpmath_mean_ratio(curve: PitchCurve, a: float, radii: dict[float, Any] | None = None
                       ) -> Any:      # an mpmath mpf
    """(1/2π)∮ρ/(a−ρ)dθ by mpmath quadrature, piece by piece between the spline knots.
    `radii`: ρ at the nodes seen so far (θ → mpf), shared by the calls on one curve: the
    root-finding calls this again and again at the same nodes, and ρ (a float spline value)
    does not depend on a; the same values, each evaluated once."""
    ends = [float(e) for e in curve.pieces]
    exact = mpmath.mpf(a)
    seen: dict[float, Any] = {} if radii is None else radii

    def rho(t: Any) -> Any:
        key = float(t)
        r = seen.get(key)
        if r is None:
            r = seen[key] = mpmath.mpf(float(curve(key)))
        return r
    total = mpmath.fsum(
        mpmath.quad(lambda t: (lambda r: r / (exact - r))(rho(t)),
                    [ends[i], ends[i + 1]]) for i in range(len(ends) - 1))
    return total / (2 * mpmath.pi)


@bench_case('gear-train closure')
def three_arm_closure(ctx: BenchContext) -> Iterator[Row]:
    params = _paper_scene()
    curve = PitchCurve(params['control_radii'], params['control_angles'],
                       params.get('interpolant', 'periodic_cubic'))
    ctx.progress('  mpmath reference centre distance ...')
    radii: dict[float, Any] = {}         # ρ at the quadrature nodes, for every call below
    with mpmath.workdps(30):
        # the secant method from two starts 1e-9 apart at the float result (one start: its
        # second point 1/4 away, two more 30-digit quadratures of the curve to come back)
        start = solve_centre_distance(curve).a
        a_ref = mpmath.findroot(lambda a: _mpmath_mean_ratio(curve, a, radii) - 1,
                                (start, start * (1 + 1e-9)))
        methods: list[tuple[str, dict[str, int]]] = [('gauss', {}), ('paper', {})]
        methods += [('trapezoid', {'samples': n}) for n in ctx.n((90, 360, 1024, 4096), (360,))]
        for method, kw in methods:
            t = ctx.measure(lambda: solve_centre_distance(curve, method, **kw))
            closure = solve_centre_distance(curve, method, **kw)
            err = float(abs(closure.a - a_ref) / a_ref)
            residual = float(abs(_mpmath_mean_ratio(curve, closure.a, radii) - 1))
            label = {'gauss': 'Gauss–Legendre per spline piece (ours)',
                     'paper': "paper's 1° sum (eq. 2)"}.get(
                         method, f"trapezoid n={kw.get('samples')}")
            yield Row('gear-train closure (centre distance)', label, 1, 'closure', t,
                      error=err, error_of=CLOSURE_ERROR_OF,
                      targets=[Target('err ≤ 1e-9', err <= CLOSURE_TARGET)] if method == 'gauss'
                      else [],
                      note=f'residual {residual:.1e}, {closure.evaluations} evaluations',
                      series='closure, trapezoid' if method == 'trapezoid' else
                      f'closure, {method}')


@bench_case('three-arm build and cycle')
def three_arm_cycle(ctx: BenchContext) -> Iterator[Row]:
    params = _paper_scene()
    t = ctx.measure(lambda: ThreeArmMechanism.from_parameters(params))
    yield Row('three-arm gear train', 'build (spline, closure, gear maps)', 1, 'build', t,
              note="the paper's parameter set (config/rice_three_arm.yaml)")
    mech = ThreeArmMechanism.from_parameters(params)
    for samples in ctx.n((360, 3600), (360,)):
        t = ctx.measure(lambda: mech.cycle(samples))
        # invariant error: each arm returns to its start pose after one carrier revolution,
        # and the vectorised cycle agrees with the per-arm tip() path
        theta, tips, _ = mech.cycle(samples)
        start = np.array([mech.tip(0.0, arm) for arm in range(3)])
        end = np.array([mech.tip(2 * math.pi, arm) for arm in range(3)])
        per_arm = np.array([mech.tip(theta, arm) for arm in range(3)])
        err = max(float(np.max(np.abs(end - start))),
                  float(np.max(np.abs(per_arm - tips)))) / float(mech.arm_length)
        yield Row('three-arm cycle (3 arms)', f'{samples} angles per arm', 1, 'cycle', t,
                  error=err, error_of='max |tip(2π) − tip(0)| and |cycle − per-arm tip| over '
                  'the arm length S',
                  targets=[Target('≤ 1 ms', t.median <= CYCLE_TARGET)] if samples == 360 else [],
                  note='' if samples == 360 else "10× finer than the paper's 1° grid")


OPTIMISER_TARGET = 15.0        # quality target: all eight goals in <= 15 s of search
OPTIMISER_SEED = 1


def _search_box(rng: np.random.Generator, count: int) -> FloatArray:
    """`count` random designs from the optimiser's search box (radii, then Φ0, β0, S, H1, γ0)."""
    radii = rng.uniform(*RADIUS_BOUNDS, (count, 12))
    install = [rng.uniform(lo, hi, count) for lo, hi in INSTALL_BOUNDS.values()]
    return np.column_stack([radii, *install])


@bench_case('three-arm optimiser')
def three_arm_optimiser(ctx: BenchContext) -> Iterator[Row]:
    params = _paper_scene()
    rng = np.random.default_rng(ctx.seed + 3)
    population = ctx.n(256, 32)
    vectors = _search_box(rng, population)
    singles = ctx.n(64, 4)
    what = 'three-arm optimiser (designs scored)'
    t = ctx.measure(lambda: [score(v, params) for v in vectors[:singles]],
                    repeats=ctx.n(5, 1))
    reference = np.array([score(v, params)[0] for v in vectors[:singles]])
    yield Row(what, 'single-design model, one design per call (the search before batching)',
              singles, 'design', t, note='random designs of the search box')
    error_of = ('max |batch score − single-design score| over the designs checked, in score '
                'units (goal violation / goal scale)')
    for workers in (1, 2):
        with PopulationScorer(params, workers) as scorer:
            t = ctx.measure(lambda: scorer(vectors), repeats=ctx.n(7, 1))
            err = float(np.max(np.abs(scorer(vectors)[0][:singles] - reference)))
        yield Row(what, f'batch: spline, closure, gear maps, cycle, goals at once, '
                  f'{workers} process{"es" if workers > 1 else ""}', population, 'design', t,
                  error=err, error_of=error_of,
                  note='the optimiser scores one such batch per generation')
    for workers in (1, 2):
        if ctx.quick:       # a whole search is too long for the smoke run: two generations
            _, goals, info = optimize(params, SearchOptions(
                seed=OPTIMISER_SEED, max_generations=2, max_time=60, workers=workers))
            targets = []
        else:
            ctx.progress(f'  planter optimize three-arm --seed {OPTIMISER_SEED} --workers '
                         f'{workers} ...')
            _, goals, info = optimize(params, SearchOptions(
                seed=OPTIMISER_SEED, max_time=120, workers=workers))
            met = goals is not None and sum(g.passed for g in goals) == len(goals) and \
                info['seconds'] <= OPTIMISER_TARGET
            # the target is the command's default, both cores
            targets = [Target('≤ 15 s', met)] if workers == 2 else []
        passed = sum(g.passed for g in goals) if goals else 0
        yield Row('three-arm optimiser (search)',
                  f"--seed {OPTIMISER_SEED} --workers {workers}", 1, 'search',
                  from_samples([info['seconds']]), targets=targets,
                  note=f"{passed}/8 goals, stopped: {info['stopped']}; {info['generations']} "
                       f"generations, {info['evaluations']} designs, "
                       f"{info['designs_per_second']:.0f} designs/s",
                  extra={'goals_passed': passed, 'generations': info['generations'],
                         'designs': info['evaluations'], 'stopped': info['stopped']})
