"""Five-bar rows: reverse design (exact vs paper, scalar and batched), hole width (closed form vs
root-finding vs dense sampling) and trajectory throughput, each against an mpmath reference."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
import math
from typing import Any

from mpmath import mp, mpf
import numpy as np
from scipy.optimize import brentq

from planter_ros.kinematics.arrays import FloatArray, Floats
from planter_ros.kinematics.five_bar import (
    GearedChain, chain_kinematics, design_five_bar, hole_geometry, hole_ratio_limit,
    hole_sensitivity, hole_tolerance, soil_trajectory)

from ..reference import (DIGITS, Chain, chain_reference, design_reference, hole_reference,
                         rel_error, soil_point_reference)
from ..registry import BenchContext, Row, Target, bench_case
from ..timing import Timing

DESIGN_TIME_TARGET = 20e-6     # quality target: a five-bar design <= 20 µs scalar
DESIGN_RATE_TARGET = 1e6       # ... and >= 1e6 designs/s batched
ACCURACY_TARGET = 1e-9         # exact design and hole width <= 1e-9 relative
TOMATO = (0.045, 0.2, 0.05)    # the paper's tomato scene: D, d, k
HOLE_ERROR_OF = ('max |hole of the computed bars − k·D| / k·D over the checked designs; '
                 'hole of the bars and k·D in mpmath')
WIDTH_ERROR_OF = 'max relative error of the swept hole width vs mpmath (same design, same λ)'


def design_domain(rng: np.random.Generator, n: int
                  ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """n random agronomic scenes: D 20-100 mm, d 0.15-0.6 m, k up to half its feasible limit."""
    depth = rng.uniform(0.02, 0.10, n)
    spacing = rng.uniform(0.15, 0.6, n)
    k = rng.uniform(0.01, 0.5, n) * np.asarray(hole_ratio_limit(depth, spacing))
    return depth, spacing, k


@dataclass(frozen=True)
class DesignCheck:
    """Computed bars against the mpmath references: the largest relative hole error, the
    largest bar-length error (of l1 + l2), over `checked` designs."""

    hole_error: float
    length_error: float
    checked: int


def _design_errors(l1: Sequence[float] | FloatArray, l2: Sequence[float] | FloatArray,
                   depth: FloatArray, spacing: FloatArray,
                   k: FloatArray, refs: Sequence[tuple[Any, Any]]) -> DesignCheck:
    """The errors of computed bars against the mpmath references `refs`."""
    hole_err = 0.0
    len_err = 0.0
    for i, (r1, r2) in enumerate(refs):
        achieved, _ = hole_reference(l1[i], l2[i], depth[i], spacing[i] / (2 * math.pi))
        with mp.workdps(DIGITS + 10):
            asked = mpf(k[i]) * mpf(depth[i])
            hole_err = max(hole_err, float(abs(achieved - asked) / asked))
            len_err = max(len_err, float(max(abs(mpf(l1[i]) - r1), abs(mpf(l2[i]) - r2))
                                         / (r1 + r2)))
    return DesignCheck(hole_err, len_err, len(refs))


@bench_case('five-bar reverse design')
def five_bar_design(ctx: BenchContext) -> Iterator[Row]:
    rng = np.random.default_rng(ctx.seed)
    sizes = ctx.n((1, 1000, 1_000_000), (1, 10, 100))
    n_ref = ctx.n(1000, 10)
    depth, spacing, k = design_domain(rng, max(sizes[-1], n_ref))
    ctx.progress(f'  mpmath reference designs ({n_ref}) ...')
    refs = [design_reference(depth[i], spacing[i], k[i]) for i in range(n_ref)]

    for method in ('exact', 'paper'):
        # scalar: plain floats, one call per design, cycling through n_ref different scenes
        args = [(float(depth[i]), float(spacing[i]), float(k[i])) for i in range(n_ref)]
        t = ctx.measure(lambda: [design_five_bar(a, b, c, method) for a, b, c in args]).per(n_ref)
        designs = [design_five_bar(a, b, c, method) for a, b, c in args]
        l1 = [float(d.l1) for d in designs]          # scalar designs: floats
        l2 = [float(d.l2) for d in designs]
        yield _design_row(method, 'scalar', 1, t, _design_errors(l1, l2, depth, spacing, k, refs))
        for n in sizes:
            ctx.progress(f'  {method} batch of {n} ...')
            D, d, kk = depth[:n].copy(), spacing[:n].copy(), k[:n].copy()
            t = ctx.measure(lambda: design_five_bar(D, d, kk, method),
                            repeats=5 if n >= 100_000 else None)
            out = design_five_bar(D, d, kk, method)
            m = min(n, n_ref)
            check = _design_errors(np.asarray(out.l1)[:m], np.asarray(out.l2)[:m], depth,
                                   spacing, k, refs[:m])
            yield _design_row(method, 'batched', n, t, check)


def _design_row(method: str, how: str, n: int, t: Timing, check: DesignCheck) -> Row:
    targets: list[Target] = []
    if how == 'scalar':
        targets.append(Target('≤ 20 µs', t.median <= DESIGN_TIME_TARGET))
    elif n >= 1_000_000:
        targets.append(Target('≥ 1e6/s', n / t.median >= DESIGN_RATE_TARGET))
    if method == 'exact':
        targets.append(Target('err ≤ 1e-9', check.hole_error <= ACCURACY_TARGET))
    name = {'exact': 'exact (ψ − sin ψ solved)', 'paper': 'paper (ψ³/6 ≈ ψ − sin ψ)'}[method]
    return Row('five-bar reverse design', f'{name}, {how}', n, 'design', t,
               error=check.hole_error, error_of=HOLE_ERROR_OF, targets=targets,
               note=f'checked {check.checked} designs; bar lengths vs mpmath exact design: '
                    f'{check.length_error:.1e} of l1+l2',
               series=f'design, {method}' if how == 'scalar' else '',
               extra={'length_error': check.length_error, 'checked': check.checked})


# --- hole width -----------------------------------------------------------------------------

def hole_by_sampling(l1: float, l2: float, depth: float, advance: float, samples: int) -> float:
    """The naive way: sample one sun-bar turn, keep the points below the soil surface, take the
    extent along the row. Error shrinks like 1/samples (the surface crossing is missed by up to
    one step)."""
    theta = np.linspace(0.0, 2.0 * math.pi, samples)
    x, y = (np.asarray(v) for v in soil_trajectory(l1, l2, theta, advance))
    below = x[y <= depth]
    return float(below.max() - below.min()) if below.size > 1 else 0.0


def hole_by_root_finding(l1: float, l2: float, depth: float, advance: float) -> float:
    """The generic way: scipy brentq for the surface crossings y(θ) = D and the turning points
    dx/dθ = 0 between them, then the extent of x over those angles."""
    total, a = l1 + l2, l2 - l1
    def y(th: float) -> float:
        return total * (1.0 + math.cos(th)) - depth

    def x(th: float) -> float:
        return a * math.sin(th) + advance * th

    def dx(th: float) -> float:
        return a * math.cos(th) + advance
    t_in = brentq(y, 0.0, math.pi)
    t_out = brentq(y, math.pi, 2.0 * math.pi)
    angles = [t_in, t_out]
    for lo, hi in ((t_in, math.pi), (math.pi, t_out)):
        if dx(lo) * dx(hi) < 0.0:
            angles.append(brentq(dx, lo, hi))
    xs = [x(th) for th in angles]
    return max(xs) - min(xs)


def _speed_ratios(a: float) -> list[float]:
    """Advances v/ω1 covering dragging, in sync, slight and strong overspeed, and reversing."""
    return [a / lam for lam in (0.5, 0.9, 1.0, 1.05, 1.2, 2.0, 10.0)] + [-0.5 * a]


@bench_case('hole width')
def hole_width(ctx: BenchContext) -> Iterator[Row]:
    design = design_five_bar(*TOMATO)
    l1, l2, depth = float(design.l1), float(design.l2), float(design.depth)   # one design
    advances = _speed_ratios(l2 - l1)
    refs = [hole_reference(l1, l2, depth, adv)[1] for adv in advances]
    count = len(advances)

    def max_err(widths: Sequence[Floats]) -> float:
        return max(rel_error(w, r) for w, r in zip(widths, refs))

    t = ctx.measure(lambda: [hole_geometry(l1, l2, depth, adv) for adv in advances]).per(count)
    err = max_err([hole_geometry(l1, l2, depth, adv).width for adv in advances])
    yield Row('hole width', 'closed form (hole_geometry), scalar', 1, 'hole', t, error=err,
              error_of=WIDTH_ERROR_OF, series='hole width, closed form',
              targets=[Target('err ≤ 1e-9', err <= ACCURACY_TARGET)],
              note=f'tomato design, {count} speed ratios λ from -2 to 10')

    rng = np.random.default_rng(ctx.seed + 1)
    n_ref = ctx.n(500, 10)
    for n in ctx.n((1000, 1_000_000), (10,)):
        ctx.progress(f'  closed form, batch of {n} ...')
        D, d, k = design_domain(rng, n)
        batch = design_five_bar(D, d, k)
        adv = (batch.l2 - batch.l1) / rng.uniform(0.5, 2.0, n)
        t = ctx.measure(lambda: hole_geometry(batch.l1, batch.l2, D, adv),
                        repeats=5 if n >= 100_000 else None)
        widths = np.asarray(hole_geometry(batch.l1, batch.l2, D, adv).width)
        m = min(n, n_ref)
        bars = np.asarray(batch.l1), np.asarray(batch.l2)
        err = max(rel_error(widths[i], hole_reference(bars[0][i], bars[1][i], D[i],
                                                      adv[i])[1]) for i in range(m))
        yield Row('hole width', 'closed form (hole_geometry), batched', n, 'hole', t,
                  error=err, error_of=WIDTH_ERROR_OF,
                  targets=[Target('err ≤ 1e-9', err <= ACCURACY_TARGET)],
                  note=f'random designs, λ 0.5-2; checked {m}')

    t = ctx.measure(lambda: [hole_by_root_finding(l1, l2, depth, adv)
                             for adv in advances]).per(count)
    err = max_err([hole_by_root_finding(l1, l2, depth, adv) for adv in advances])
    yield Row('hole width', 'root-finding (scipy brentq)', 1, 'hole', t, error=err,
              error_of=WIDTH_ERROR_OF, series='hole width, root-finding',
              note='crossings and turning points by brentq, default tolerances')

    for samples in ctx.n((100, 1000, 10_000, 100_000, 1_000_000), (100, 1000)):
        ctx.progress(f'  dense sampling, {samples} samples ...')
        t = ctx.measure(lambda: [hole_by_sampling(l1, l2, depth, adv, samples)
                                 for adv in advances],
                        repeats=5 if samples >= 100_000 else None).per(count)
        err = max_err([hole_by_sampling(l1, l2, depth, adv, samples) for adv in advances])
        yield Row('hole width', f'dense sampling, {samples:,} samples/turn', 1, 'hole', t,
                  error=err, error_of=WIDTH_ERROR_OF, series='hole width, dense sampling',
                  extra={'samples': samples})


# --- tolerances -----------------------------------------------------------------------------

@bench_case('hole-width tolerance')
def hole_width_tolerance(ctx: BenchContext) -> Iterator[Row]:
    design = design_five_bar(*TOMATO)
    s = hole_sensitivity(design.l1, design.l2, design.depth, design.advance)
    samples = ctx.n(100_000, 10_000)
    t = ctx.measure(lambda: hole_tolerance(design, 1e-4, 0.01, samples))
    # with tolerances small enough for W to be linear, a uniform ±M on each bar gives
    # std = M·|∇W|/√3: the Monte Carlo's sampling error plus its agreement with the
    # analytic sensitivities
    m = 1e-6
    small = hole_tolerance(design, m, 0.0, samples)
    linear = m * math.hypot(s.l1, s.l2) / math.sqrt(3.0)
    err = abs(small['std'] - linear) / linear
    yield Row('hole-width tolerance (Monte Carlo)', 'vectorised hole_geometry, bars ±0.1 mm, '
              'speed ±1 %', samples, 'sample', t, error=err,
              error_of='|std − M·|∇W|/√3| / (M·|∇W|/√3) at bars ±1 µm (linear regime): '
                       'sampling error against the analytic sensitivities',
              targets=[Target('≥ 1e5 samples < 1 s', samples >= 100_000 and t.median < 1.0)]
              if not ctx.quick else [],
              note=f'tomato design (hole {design.hole_width * 1e3:.2f} mm)')


# --- trajectory -----------------------------------------------------------------------------

@bench_case('trajectory evaluation')
def trajectory(ctx: BenchContext) -> Iterator[Row]:
    design = design_five_bar(*TOMATO)
    l1, l2, adv = float(design.l1), float(design.l2), float(design.advance)   # one design
    total = l1 + l2
    rng = np.random.default_rng(ctx.seed + 2)
    n_ref = ctx.n(200, 10)
    error_of = 'max position error / (l1+l2) vs mpmath'
    for n in ctx.n((1000, 1_000_000), (100,)):
        theta = np.sort(rng.uniform(0.0, 6.0 * math.pi, n))
        t = ctx.measure(lambda: soil_trajectory(l1, l2, theta, adv),
                        repeats=5 if n >= 100_000 else None)
        x, y = (np.asarray(v) for v in soil_trajectory(l1, l2, theta, adv))
        idx = rng.choice(n, min(n, n_ref), replace=False)
        err = 0.0
        for i in idx:
            rx, ry = soil_point_reference(l1, l2, theta[i], adv)
            err = max(err, float(abs(x[i] - rx) / total), float(abs(y[i] - ry) / total))
        yield Row('trajectory evaluation', 'soil_trajectory (x, y)', n, 'point', t, error=err,
                  error_of=error_of, note=f'tomato design, θ over 3 turns; checked {len(idx)}')

    omega = 2.0 * math.pi
    n = ctx.n(1_000_000, 100)
    alpha = np.sort(rng.uniform(0.0, 6.0 * math.pi, n))
    t = ctx.measure(lambda: chain_kinematics(alpha, omega, GearedChain(l1, l2)),
                    repeats=5 if n > 1000 else None)
    pos, vel, acc = chain_kinematics(alpha, omega, GearedChain(l1, l2))
    err = 0.0
    for i in rng.choice(n, min(n, n_ref), replace=False):
        rp, rv, ra = chain_reference(alpha[i], omega, Chain(l1, l2))
        for got, ref, scale in ((pos, rp, total), (vel, rv, total * omega),
                                (acc, ra, total * omega ** 2)):
            err = max(err, float(abs(np.asarray(got[0])[i] - ref[0]) / scale),
                      float(abs(np.asarray(got[1])[i] - ref[1]) / scale))
    yield Row('trajectory evaluation', 'chain_kinematics (pos, vel, acc)', n, 'point', t,
              error=err, error_of='max error / (l1+l2)·ω^j (j = 0, 1, 2) vs mpmath',
              note='paper formula 3, ω1 = 2π rad/s')
