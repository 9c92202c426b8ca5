"""Geared five-bar planting mechanism (paper 1): exact reverse design and forward kinematics.

Conventions (REP 103 style, SI units): the mechanism plane has x along the row (the direction of
travel, forward) and y vertical (up). Angles in rad. The sun bar AB (l1) turns about A at ω1; the
planet bar BC (l2) is fixed to the planet gear, gear ratio ω2/ω1 = -2, so the nozzle tip C moves
on the ellipse x = (l2-l1) sin θ, y = (l1+l2) cos θ about A (θ = ω1 t, θ = 0 at the top).

In the soil frame the bottom of the trajectory is y = 0 and the soil surface is y = D:
    x = (l2-l1) sin θ + v t,   y = (l1+l2)(1 + cos θ).
With `advance` = v/ω1 (metres travelled per radian of the sun bar) the speed ratio is
λ = (l2-l1)/advance; λ = 1 is zero-speed planting, v = d ω1 / 2π for one plant per revolution.

Reverse design: the hole (entry-exit distance) at depth D is exactly t = (d/π)(ψ - sin ψ) with
ψ = arccos(1 - D/(l1+l2)); the paper replaces ψ - sin ψ by ψ³/6 (method 'paper'), which
designs holes 1-7 % smaller than asked. Method 'exact' solves ψ - sin ψ = π k D / d to round-off.

Passive dyad: C-D (l3) and D-E (l4) with the frame pivot E on the horizontal through A at
distance l5 (the paper's right triangle A-C-E at the top position). Behind or ahead of A gives
mirror-image cycles (x is odd in θ), so the closure checks are the same for both.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math
from typing import Any, TypedDict, overload

import numpy as np
from numpy.typing import NDArray

from .arrays import Bools, FloatArray, Floats
from .errors import DesignError, require_positive_finite


TWO_PI = 2.0 * math.pi
PAPER_DYAD_RATIOS = (1.4, 1.5, 1.3)
METHODS = ('exact', 'paper')

# Horner denominators of ψ - sin ψ = ψ³/6 (1 - z/20 (1 - z/42 (1 - ...))), z = ψ²;
# ten terms make the series exact to < 1e-19 relative for ψ < 1.
_SERIES_DENOMS = (420.0, 342.0, 272.0, 210.0, 156.0, 110.0, 72.0, 42.0, 20.0)
_SERIES_LIMIT = 1.0


def _series_psi_minus_sin(psi: Floats) -> Floats:
    z = psi * psi
    acc: Floats = 1.0
    for den in _SERIES_DENOMS:
        acc = 1.0 - z / den * acc
    return psi * z / 6.0 * acc


@overload
def psi_minus_sin(psi: float) -> float: ...
@overload
def psi_minus_sin(psi: FloatArray) -> FloatArray: ...
@overload
def psi_minus_sin(psi: Floats) -> Floats: ...
def psi_minus_sin(psi: Floats) -> Floats:
    """ψ - sin ψ to full relative precision (series below 1 rad, where the difference cancels)."""
    if isinstance(psi, float):
        return _series_psi_minus_sin(psi) if abs(psi) < _SERIES_LIMIT else psi - math.sin(psi)
    psi = np.asarray(psi, dtype=np.float64)
    small = np.abs(psi) < _SERIES_LIMIT
    return np.where(small, _series_psi_minus_sin(np.where(small, psi, 0.0)), psi - np.sin(psi))


@overload
def solve_psi(c: float) -> float: ...
@overload
def solve_psi(c: FloatArray) -> FloatArray: ...
def solve_psi(c: Floats) -> Floats:
    """Solve ψ - sin ψ = c for ψ in (0, π]; c in (0, π] (scalar or array).

    Three Halley steps from the series inverse s + s³/60 (s = cbrt(6c)) reach round-off over the
    whole domain (checked against mpmath in the tests and `planter bench`); the residual uses
    the cancellation-free series, so tiny ψ keeps full relative precision. A fixed step count
    keeps the batch path free of data-dependent loops.
    """
    if isinstance(c, float):
        return _solve_psi_scalar(c)
    return _solve_psi_batch(np.asarray(c, dtype=np.float64))


def _solve_psi_scalar(c: float) -> float:
    psi = min(_initial_psi(c), math.pi)
    for _ in range(3):
        g = psi_minus_sin(psi) - c
        s = math.sin(0.5 * psi)
        g1 = 2.0 * s * s                       # 1 - cos ψ
        den = 2.0 * g1 * g1 - g * math.sin(psi)
        if den > 0.0:
            psi = min(psi - 2.0 * g * g1 / den, math.pi)
    return psi


def _solve_psi_batch(c: FloatArray) -> FloatArray:
    psi = np.minimum(_initial_psi(c), math.pi)
    for _ in range(3):
        g = psi_minus_sin(psi) - c
        s = np.sin(0.5 * psi)
        g1 = 2.0 * s * s                       # 1 - cos ψ
        den = 2.0 * g1 * g1 - g * np.sin(psi)
        psi = np.minimum(psi - np.where(den > 0, 2.0 * g * g1 / np.where(den > 0, den, 1.0),
                                        0.0), math.pi)
    return psi


@overload
def _initial_psi(c: float) -> float: ...
@overload
def _initial_psi(c: FloatArray) -> FloatArray: ...
def _initial_psi(c: Floats) -> Floats:
    # Inverse of ψ³/6 (1 - ψ²/20): s + s³/60 with s = cbrt(6c); lies below the root for c < 1.
    s: Floats = np.cbrt(6.0 * c) if isinstance(c, np.ndarray) else (6.0 * c) ** (1.0 / 3.0)
    return s + s ** 3 / 60.0


@overload
def depth_angle(depth: float, total_length: float) -> float: ...
@overload
def depth_angle(depth: Floats, total_length: Floats) -> Floats: ...
def depth_angle(depth: Floats, total_length: Floats) -> Floats:
    """ψ with cos ψ = 1 - D/(l1+l2): half the crank angle spent below the soil surface.

    Written as 2·atan2(√D, √(2L - D)) so it keeps full precision for shallow holes (where
    arccos(1 - x) loses half the digits) and needs D <= 2L (soil line inside the trajectory).
    """
    if isinstance(depth, float) and isinstance(total_length, float):
        return 2.0 * math.atan2(math.sqrt(depth), math.sqrt(max(2.0 * total_length - depth, 0.0)))
    depth = np.asarray(depth, dtype=float)
    total_length = np.asarray(total_length, dtype=float)
    return 2.0 * np.arctan2(np.sqrt(depth), np.sqrt(np.maximum(2.0 * total_length - depth, 0.0)))


@overload
def bars_depth_angle(l1: float, l2: float, depth: float) -> float: ...
@overload
def bars_depth_angle(l1: Floats, l2: Floats, depth: Floats) -> Floats: ...
def bars_depth_angle(l1: Floats, l2: Floats, depth: Floats) -> Floats:
    """depth_angle for the bars l1, l2 themselves, not their rounded sum.

    Near ψ = π (the soil line near the top of the path) ψ ≈ π - 2√((2L - D)/D) is infinitely
    sensitive to 2L - D, so the rounding of l1 + l2 is carried along (Knuth's TwoSum) and
    2L - D is formed from the exact sum.
    """
    total = l1 + l2
    b = total - l1
    lost = (l1 - (total - b)) + (l2 - b)          # l1 + l2 = total + lost exactly
    gap = (2.0 * total - depth) + 2.0 * lost       # 2L - D
    if isinstance(gap, float) and not isinstance(depth, np.ndarray):
        return 2.0 * math.atan2(math.sqrt(depth), math.sqrt(max(gap, 0.0)))
    return 2.0 * np.arctan2(np.sqrt(depth), np.sqrt(np.maximum(gap, 0.0)))


def hole_ratio_limit(depth: Floats, spacing: Floats) -> Floats:
    """Largest feasible k = t/D for (D, d): k·D < d and l1 > 0 (scalar or array)."""
    depth = np.asarray(depth, dtype=float)
    spacing = np.asarray(spacing, dtype=float)
    k_geom = spacing / depth
    # l1 = 0 where 1 - cos ψ = 2πD/d; no such ψ < π when 2πD/d >= 2.
    x = TWO_PI * depth / spacing
    psi_l1 = 2.0 * np.arcsin(np.sqrt(np.minimum(x, 2.0) / 2.0))
    k_l1 = np.where(x < 2.0, spacing * psi_minus_sin(psi_l1) / (math.pi * depth), np.inf)
    out = np.minimum(k_geom, k_l1)
    return float(out) if out.ndim == 0 else out


@dataclass(frozen=True)
class FiveBarDesign:
    """A five-bar design; every length in m, angles in rad (fields are arrays for a batch)."""

    depth: Floats
    spacing: Floats
    hole_ratio: Floats
    method: str
    l1: Floats
    l2: Floats
    l3: Floats
    l4: Floats
    l5: Floats
    psi: Floats                      # half crank angle below the soil surface
    hole_width: Floats               # hole (entry-exit distance) this design achieves at λ = 1
    assemblable: Bools               # dyad closes over the whole cycle, no branch flip
    min_transmission_angle: Floats   # min over the cycle of min(μ, π - μ), 0 if not assemblable
    dyad_ratios: tuple[float, float, float] = PAPER_DYAD_RATIOS

    @property
    def requested_hole(self) -> Floats:
        return self.hole_ratio * self.depth

    @property
    def advance(self) -> Floats:
        """Designed travel per radian of sun bar, d/2π (m/rad)."""
        return self.spacing / TWO_PI

    def sun_bar_speed(self, ground_speed: Floats) -> Floats:
        """ω1 = 2π v / d (rad/s) that keeps zero-speed planting at ground speed v (m/s)."""
        return sun_bar_speed(ground_speed, self.spacing)

    def as_dict(self) -> dict[str, object]:
        """Plain SI dict (JSON-ready for scalars)."""
        out: dict[str, object] = {k: _plain(getattr(self, k)) for k in (
            'l1', 'l2', 'l3', 'l4', 'l5', 'hole_width', 'assemblable', 'min_transmission_angle',
            'depth', 'spacing', 'hole_ratio', 'psi')}
        out['method'] = self.method
        out['requested_hole'] = _plain(self.requested_hole)
        out['dyad_ratios'] = list(self.dyad_ratios)
        return out


def _plain(v: Floats | Bools) -> float | bool | list[Any]:
    if isinstance(v, np.ndarray):
        values: list[Any] = v.tolist()
        return values
    if isinstance(v, (np.bool_, bool)):
        return bool(v)
    return float(v)


def sun_bar_speed(ground_speed: Floats, spacing: Floats,
                  plants_per_revolution: int = 1) -> Floats:
    """ω = 2π v / (n d) (rad/s): the paper's v = d ω1 / 2π for n plants per revolution."""
    return TWO_PI * np.asarray(ground_speed) / (plants_per_revolution * np.asarray(spacing)) \
        if isinstance(ground_speed, np.ndarray) or isinstance(spacing, np.ndarray) \
        else TWO_PI * ground_speed / (plants_per_revolution * spacing)


def design_five_bar(depth: Floats, spacing: Floats, hole_ratio: Floats = 0.05,
                    method: str = 'exact',
                    dyad_ratios: Sequence[float] = PAPER_DYAD_RATIOS
                    ) -> FiveBarDesign:
    """Reverse design from planting depth D (m), plant spacing d (m) and hole ratio k = t/D.

    Scalars give a scalar design in a few microseconds; arrays (broadcast together) give a batch.
    Raises DesignError (one line, naming the limit) for non-finite, non-positive or infeasible
    input: the exact design exists iff k·D < d and l1 > 0 (see hole_ratio_limit).
    """
    if method not in METHODS:
        raise DesignError('method', method, ' or '.join(METHODS))
    require_positive_finite('depth', depth, 'm')
    require_positive_finite('spacing', spacing, 'm')
    require_positive_finite('hole_ratio', hole_ratio)
    if len(dyad_ratios) != 3:
        raise DesignError('dyad_ratios', dyad_ratios, 'three ratios (l3, l4, l5)/(l1+l2)')
    for name, r in zip(('l3_ratio', 'l4_ratio', 'l5_ratio'), dyad_ratios):
        require_positive_finite(name, r)
    if not all(isinstance(v, (int, float)) for v in (depth, spacing, hole_ratio)):
        depth, spacing, hole_ratio = np.broadcast_arrays(
            *(np.asarray(v, dtype=float) for v in (depth, spacing, hole_ratio)))
        return _design_batch(depth, spacing, hole_ratio, method,
                             (dyad_ratios[0], dyad_ratios[1], dyad_ratios[2]))
    return _design_scalar(float(depth), float(spacing), float(hole_ratio), method,
                          (float(dyad_ratios[0]), float(dyad_ratios[1]), float(dyad_ratios[2])))


def _infeasible(depth: float, spacing: float, hole_ratio: float, why: str) -> DesignError:
    k_max = hole_ratio_limit(depth, spacing)
    return DesignError('hole_ratio', hole_ratio, f'0 < k < {k_max:.6g} for D = {depth:.6g} m, '
                       f'd = {spacing:.6g} m', why)


def _design_scalar(depth: float, spacing: float, k: float, method: str,
                   ratios: tuple[float, float, float]) -> FiveBarDesign:
    c = math.pi * k * depth / spacing
    if method == 'exact':
        if not c < math.pi:
            raise _infeasible(depth, spacing, k, 'needs k·D < d')
        psi = solve_psi(c)
    else:
        psi = (6.0 * c) ** (1.0 / 3.0)          # the paper: ψ³/6 = π k D / d
        if not psi < math.pi:
            raise _infeasible(depth, spacing, k, "the paper's formula needs k·D/d < π²/6")
    s = math.sin(0.5 * psi)
    total = depth / (2.0 * s * s) if s > 0.0 else math.inf   # l1 + l2 = D / (1 - cos ψ)
    if not math.isfinite(total):
        raise DesignError('hole_ratio', k, '> 0 such that l1 + l2 stays finite',
                          'the hole is too small for a mechanism of finite size')
    half_gap = spacing / (2.0 * TWO_PI)        # (l2 - l1)/2 = d/4π
    l1 = 0.5 * total - half_gap
    if not l1 > 0.0:
        raise _infeasible(depth, spacing, k, 'needs l1 > 0')
    l2 = 0.5 * total + half_gap
    l3, l4, l5 = (r * total for r in ratios)
    psi_a = bars_depth_angle(l1, l2, depth)
    ideal, slip = _achieved_hole(l1, l2, spacing, psi_a)
    if not (abs(slip) <= ROUND_OFF_LIMIT * ideal and ideal >= _TINY):
        raise _unrepresentable(depth, spacing, k, l1 + l2, slip, ideal)
    ok, mu = dyad_closure(l1, l2, l3, l4, l5)
    return FiveBarDesign(depth, spacing, k, method, l1, l2, l3, l4, l5, psi_a, ideal + slip, ok,
                         mu, ratios)


# A design is delivered as float bar lengths; refuse it when their round-off alone moves the
# hole by more than this (the accuracy target), instead of reporting a hole they miss.
ROUND_OFF_LIMIT = 1e-9
_TINY = 2.2250738585072014e-308     # smallest normal float: below it the hole has no precision


@overload
def _achieved_hole(l1: float, l2: float, spacing: float, psi: float) -> tuple[float, float]: ...
@overload
def _achieved_hole(l1: FloatArray, l2: FloatArray, spacing: FloatArray,
                   psi: Floats) -> tuple[FloatArray, FloatArray]: ...
def _achieved_hole(l1: Floats, l2: Floats, spacing: Floats,
                   psi: Floats) -> tuple[Floats, Floats]:
    """(ideal, slip): the hole the float bars achieve at advance d/2π is ideal + slip.

    Entry-exit distance 2h(ψ), h = adv·ψ - a sin ψ = adv(ψ - sin ψ) + (adv - a) sin ψ with
    a = l2 - l1; `slip` is the second term, nonzero only by the round-off of the bars.
    """
    adv = spacing / TWO_PI
    sin_psi = math.sin(psi) if isinstance(psi, float) else np.sin(psi)
    return 2.0 * adv * psi_minus_sin(psi), 2.0 * (adv - (l2 - l1)) * sin_psi


def min_hole_ratio(depth: float, spacing: float) -> float:
    """About the smallest k whose design's bars, as floats, still achieve k·D to 1e-9.

    Leading order: the bars round off by ε(l1+l2), moving the hole by 6ε(l1+l2)/(aψ²) relative
    with l1+l2 ≈ 2D/ψ², a = d/2π; solved for ψ and mapped to k by ψ³/6 = πkD/d.
    """
    eps = 2.220446049250313e-16
    psi: float = (12.0 * eps * depth * TWO_PI / (spacing * ROUND_OFF_LIMIT)) ** 0.25
    return psi ** 3 / 6.0 * spacing / (math.pi * depth)


def _unrepresentable(depth: float, spacing: float, k: float, total: float, slip: float,
                     ideal: float) -> DesignError:
    moved = f'{abs(slip) / ideal:.1e} of it' if ideal >= _TINY else 'all of it'
    return DesignError('hole_ratio', k, f'k ≳ {min_hole_ratio(depth, spacing):.3g} for '
                       f'D = {depth:.6g} m, d = {spacing:.6g} m',
                       f'the hole is too small for bars of {total:.3g} m: at finite precision '
                       f'their round-off alone would move the hole by {moved}')


def _design_batch(depth: NDArray[np.float64], spacing: NDArray[np.float64],
                  k: NDArray[np.float64], method: str,
                  ratios: tuple[float, float, float]) -> FiveBarDesign:
    c = math.pi * k * depth / spacing
    if method == 'exact':
        bad = ~(c < math.pi)
        if bad.any():
            i = np.flatnonzero(bad.ravel())[0]
            raise _batch_error(depth, spacing, k, i, bad.sum(), 'needs k·D < d')
        psi = solve_psi(c)
    else:
        psi = np.cbrt(6.0 * c)
        bad = ~(psi < math.pi)
        if bad.any():
            i = np.flatnonzero(bad.ravel())[0]
            raise _batch_error(depth, spacing, k, i, bad.sum(),
                               "the paper's formula needs k·D/d < π²/6")
    s = np.sin(0.5 * psi)
    with np.errstate(divide='ignore', over='ignore'):
        total = depth / (2.0 * s * s)
    bad = ~np.isfinite(total)
    if bad.any():
        i = np.flatnonzero(bad.ravel())[0]
        raise DesignError('hole_ratio', float(k.flat[i]), '> 0 such that l1 + l2 stays finite',
                          f'at batch index {i}: the hole is too small for a finite mechanism')
    half_gap = spacing / (2.0 * TWO_PI)
    l1 = 0.5 * total - half_gap
    bad = ~(l1 > 0.0)
    if bad.any():
        i = np.flatnonzero(bad.ravel())[0]
        raise _batch_error(depth, spacing, k, i, bad.sum(), 'needs l1 > 0')
    l2 = 0.5 * total + half_gap
    l3, l4, l5 = (r * total for r in ratios)
    psi_a = bars_depth_angle(l1, l2, depth)
    ideal, slip = _achieved_hole(l1, l2, spacing, psi_a)
    bad = ~((np.abs(slip) <= ROUND_OFF_LIMIT * ideal) & (ideal >= _TINY))
    if bad.any():
        i = np.flatnonzero(bad.ravel())[0]
        err = _unrepresentable(float(depth.flat[i]), float(spacing.flat[i]), float(k.flat[i]),
                               float(l1.flat[i] + l2.flat[i]), float(slip.flat[i]),
                               float(ideal.flat[i]))
        err.args = (f'{err.args[0]} at batch index {i} ({bad.sum()} refused)',)
        raise err
    ok, mu = dyad_closure(l1, l2, l3, l4, l5)
    return FiveBarDesign(depth, spacing, k, method, l1, l2, l3, l4, l5, psi_a, ideal + slip, ok,
                         mu, ratios)


def _batch_error(depth: NDArray[np.float64], spacing: NDArray[np.float64],
                 k: NDArray[np.float64], i: int | np.integer, count: int | np.integer,
                 why: str) -> DesignError:
    err = _infeasible(float(depth.flat[i]), float(spacing.flat[i]), float(k.flat[i]), why)
    err.args = (f'{err.args[0]} at batch index {i} ({count} infeasible)',)
    return err


# --- passive dyad -----------------------------------------------------------------------------

def _distance_range(l1: Floats, l2: Floats, l5: Floats) -> tuple[Floats, Floats]:
    """Min and max over the cycle of |CE| with E = (±l5, 0).

    |CE|² = (a s ∓ l5)² + L²(1 - s²) with s = sin θ is a quadratic in s on [-1, 1] (concave,
    as L > |a|), so the extremes are at s = ±1 or at its vertex s* = ∓a l5 / (L² - a²) —
    closed form, no sampling. Worked in units of L, so squares neither overflow nor underflow at
    any scale; L² - a² is written 4 l1 l2 (no cancellation when l1 is small).
    """
    total = l1 + l2
    a = (l2 - l1) / total
    e = l5 / total
    def r2(s: Floats) -> Floats:
        u = a * s - e
        return u * u + (1.0 - s) * (1.0 + s)
    ends_lo = r2(1.0)
    ends_hi = r2(-1.0)
    denom = 4.0 * (l1 / total) * (l2 / total)          # = 1 - a², > 0 for l1, l2 > 0
    if isinstance(denom, np.ndarray) or isinstance(a, np.ndarray):
        denoms = np.asarray(denom)
        vertices = np.where(denoms > 0, -a * e / np.where(denoms > 0, denoms, 1.0), 2.0)
        inside = np.abs(vertices) < 1.0
        rv = np.where(inside, r2(np.clip(vertices, -1.0, 1.0)), ends_lo)
        lo = np.minimum(np.minimum(ends_lo, ends_hi), np.where(inside, rv, np.inf))
        hi = np.maximum(np.maximum(ends_lo, ends_hi), np.where(inside, rv, -np.inf))
        return total * np.sqrt(lo), total * np.sqrt(hi)
    # scalars: a is not an array, so neither are l1, l2, l5 nor any value derived from them
    vals = [float(ends_lo), float(ends_hi)]
    if denom > 0:
        vertex = float(-a * e / denom)
        if abs(vertex) < 1.0:
            vals.append(float(r2(vertex)))
    return total * math.sqrt(max(min(vals), 0.0)), total * math.sqrt(max(vals))


def dyad_closure(l1: Floats, l2: Floats, l3: Floats, l4: Floats,
                 l5: Floats) -> tuple[Bools, Floats]:
    """(assemblable, min transmission angle) of the dyad C-D-E over a full sun-bar turn.

    Assemblable: |l3 - l4| < |CE| < l3 + l4 at every angle, so point D exists and its two
    branches never meet (no branch flip). The transmission angle μ at D grows with r = |CE|;
    the worst value of min(μ, π - μ) is at an extreme of r (see transmission_angle).
    """
    rmin, rmax = _distance_range(l1, l2, l5)
    if (isinstance(rmin, np.ndarray) or isinstance(rmax, np.ndarray)
            or isinstance(l3, np.ndarray) or isinstance(l4, np.ndarray)):
        ok = np.asarray(rmax < l3 + l4) & np.asarray(rmin > np.abs(l3 - l4))
        mu = np.minimum(transmission_angle(l3, l4, rmin),
                        transmission_angle(l3, l4, rmax, supplement=True))
        return ok, np.where(ok, mu, 0.0)
    if not (rmax < l3 + l4 and rmin > abs(l3 - l4)):
        return False, 0.0
    return True, min(transmission_angle(l3, l4, rmin),
                     transmission_angle(l3, l4, rmax, supplement=True))


@overload
def transmission_angle(l3: float, l4: float, r: float, supplement: bool = False) -> float: ...
@overload
def transmission_angle(l3: Floats, l4: Floats, r: Floats, supplement: bool = False) -> Floats: ...
def transmission_angle(l3: Floats, l4: Floats, r: Floats, supplement: bool = False) -> Floats:
    """Angle μ at D between D-C (l3) and D-E (l4) for |CE| = r, or π - μ with supplement.

    tan²(μ/2) = (r² - (l3-l4)²) / ((l3+l4)² - r²), each factor written as a product of sums
    and differences of the given lengths, so μ keeps full relative precision as the dyad
    approaches its stretched (μ → π) or folded (μ → 0) position, where arccos of the law of
    cosines loses half the digits and rounds to 0 or π. Requires |l3-l4| <= r <= l3+l4.
    """
    if isinstance(r, np.ndarray) or isinstance(l3, np.ndarray) or isinstance(l4, np.ndarray):
        diffs = np.abs(l3 - l4)
        totals = l3 + l4
        open_a = np.sqrt(np.maximum((r - diffs) / totals, 0.0)
                         * np.maximum((r + diffs) / totals, 0.0))
        shut_a = np.sqrt(np.maximum((totals - r) / totals, 0.0)
                         * np.maximum((totals + r) / totals, 0.0))
        angle: FloatArray = (np.arctan2(shut_a, open_a) if supplement
                             else np.arctan2(open_a, shut_a))
        return 2.0 * angle
    diff = abs(l3 - l4)
    total = l3 + l4                                  # also the scale of the factors
    open_ = math.sqrt(max((r - diff) / total, 0.0) * max((r + diff) / total, 0.0))
    shut = math.sqrt(max((total - r) / total, 0.0) * max((total + r) / total, 0.0))
    return 2.0 * (math.atan2(shut, open_) if supplement else math.atan2(open_, shut))


def dyad_positions(design: FiveBarDesign, theta: Floats,
                   branch: int = 1) -> tuple[Floats, Floats, Floats]:
    """Point D (x, y relative to A, m) and transmission angle μ (rad) at sun-bar angles θ.

    E = (-l5, 0) (behind A). branch = +1 or -1 picks one of the two assembly modes. Raises
    DesignError where the dyad cannot close.
    """
    theta = np.asarray(theta, dtype=float)
    cx, cy = static_trajectory(design.l1, design.l2, theta)
    ex, ey = -design.l5, 0.0
    dx, dy = ex - cx, ey - cy
    r = np.hypot(dx, dy)
    l3, l4 = design.l3, design.l4
    # beyond the closure limits by more than round-off: the dyad cannot close (within it, a
    # design dyad_closure calls assemblable touches its singular position and is drawn there)
    slack = 64.0 * float(np.finfo(float).eps)
    if np.any(r > (l3 + l4) * (1.0 + slack)) or np.any(r < np.abs(l3 - l4) * (1.0 - slack)):
        raise DesignError('dyad', f'l3={l3:.4g} m, l4={l4:.4g} m', '|l3-l4| < |CE| < l3+l4',
                          'the passive dyad cannot close at some angle')
    along = (l3 - l4) * ((l3 + l4) / r) / 2.0 + r / 2.0
    # height of D over C-E (Heron): products of sums and differences, exact near singular
    h = np.sqrt(np.maximum((l3 + l4 - r) / r, 0.0) * np.maximum((r + l3 - l4) / r, 0.0)
                * np.maximum((r - l3 + l4) / r, 0.0)
                * np.maximum((r + l3 + l4) / r, 0.0)) * r / 2.0
    ux, uy = dx / r, dy / r
    px, py = cx + along * ux, cy + along * uy
    # left normal of C->E is (-uy, ux); for E behind and below C that points up
    x = px - branch * h * uy
    y = py + branch * h * ux
    return x, y, transmission_angle(l3, l4, r)


# --- forward kinematics -----------------------------------------------------------------------

@dataclass(frozen=True)
class GearedChain:
    """The paper's 2R chain: bars l1, l2 (m), the second turning at α2 = gear_ratio·α1 + θ2
    relative to the first, the first at θ1 when α1 = 0 (rad). The defaults (ratio -2,
    θ1 = π/2, θ2 = 0) trace the static ellipse of static_trajectory."""

    l1: float
    l2: float
    gear_ratio: float = -2.0
    theta1: float = 0.5 * math.pi
    theta2: float = 0.0


def chain_kinematics(alpha: Floats, omega1: float,
                     chain: GearedChain) -> tuple[tuple[Floats, Floats], ...]:
    """The paper's formula (3) of a GearedChain (general case).

    alpha: sun-bar rotation ω1 t (rad, array). Returns (position, velocity, acceleration), each
    (x, y) in the frame of A, for constant ω1 (rad/s).
    """
    l1, l2, gear_ratio, theta1, theta2 = (chain.l1, chain.l2, chain.gear_ratio, chain.theta1,
                                          chain.theta2)
    alpha = np.asarray(alpha, dtype=float)
    a1 = alpha + theta1
    a12 = (1.0 + gear_ratio) * alpha + theta1 + theta2
    w12 = (1.0 + gear_ratio) * omega1
    pos = (l2 * np.cos(a12) + l1 * np.cos(a1), l2 * np.sin(a12) + l1 * np.sin(a1))
    vel = (-l2 * w12 * np.sin(a12) - l1 * omega1 * np.sin(a1),
           l2 * w12 * np.cos(a12) + l1 * omega1 * np.cos(a1))
    acc = (-l2 * w12 ** 2 * np.cos(a12) - l1 * omega1 ** 2 * np.cos(a1),
           -l2 * w12 ** 2 * np.sin(a12) - l1 * omega1 ** 2 * np.sin(a1))
    return pos, vel, acc


def static_trajectory(l1: Floats, l2: Floats, theta: Floats) -> tuple[Floats, Floats]:
    """Nozzle tip C relative to A (m): x = (l2-l1) sin θ, y = (l1+l2) cos θ."""
    return static_x(l1, l2, theta), (l1 + l2) * np.cos(theta)


def static_x(l1: Floats, l2: Floats, theta: Floats) -> Floats:
    """static_trajectory's x alone (m)."""
    return (l2 - l1) * np.sin(theta)


def soil_trajectory(l1: Floats, l2: Floats, theta: Floats,
                    advance: Floats) -> tuple[Floats, Floats]:
    """Tip in the soil frame (m): bottom of the path at y = 0, soil surface at y = D.

    advance = v/ω1 (m travelled per rad of sun bar; d/2π when in sync; any sign).
    """
    theta = np.asarray(theta, dtype=float)
    return (l2 - l1) * np.sin(theta) + advance * theta, (l1 + l2) * (1.0 + np.cos(theta))


def soil_velocity(l1: Floats, l2: Floats, theta: Floats, omega1: Floats,
                  ground_speed: Floats) -> tuple[Floats, Floats]:
    """Tip velocity in the soil frame (m/s) at constant ω1 (rad/s) and ground speed v (m/s)."""
    return ((l2 - l1) * omega1 * np.cos(theta) + ground_speed,
            -(l1 + l2) * omega1 * np.sin(theta))


def soil_acceleration(l1: Floats, l2: Floats, theta: Floats,
                      omega1: Floats) -> tuple[Floats, Floats]:
    """Tip acceleration (m/s²) at constant ω1 and v: the frame's ellipse acceleration."""
    return (-(l2 - l1) * omega1 ** 2 * np.sin(theta), -(l1 + l2) * omega1 ** 2 * np.cos(theta))


@dataclass(frozen=True)
class Hole:
    """Where the nozzle is below the soil surface, along the row, relative to the bottom point."""

    psi: Floats          # half crank angle below the surface (rad): entry at π-ψ, exit at π+ψ
    entry_x: Floats      # m
    exit_x: Floats       # m
    min_x: Floats        # m, rearmost point of the path below the surface
    max_x: Floats        # m, foremost point
    width: Floats        # m, swept extent max_x - min_x (what the soil sees)

    @property
    def entry_exit(self) -> Floats:
        return np.abs(self.exit_x - self.entry_x)


def hole_geometry(l1: Floats, l2: Floats, depth: Floats, advance: Floats) -> Hole:
    """Hole at depth D for any speed ratio λ = (l2-l1)/advance, in closed form (no sampling).

    Below the surface the path relative to its bottom is h(φ) = advance·φ - a sin φ, φ in
    [-ψ, ψ], a = l2 - l1. It is odd, so the extent is 2·max|h| over φ = ψ and the stationary
    point cos φ* = advance/a (exists when |advance| <= a: λ >= 1 loops backwards). λ < 1 drags
    the nozzle forwards: h is monotone and the extent is the entry-exit distance. Any l1, l2 > 0
    (l1 > l2 too) and any advance, including 0 and reversing.
    """
    if (isinstance(l1, np.ndarray) or isinstance(l2, np.ndarray)
            or isinstance(depth, np.ndarray) or isinstance(advance, np.ndarray)):
        return _hole_geometry_batch(l1, l2, depth, advance)
    return _hole_geometry_scalar(l1, l2, depth, advance)


# Below the surface the tip is h(φ) = adv·φ - a sin φ from the bottom point, written as
# adv (φ - sin φ) + (adv - a) sin φ to avoid cancellation when adv ≈ a and φ is small. l1 > l2
# runs the ellipse the other way: (a, advance) -> (-a, -advance) flips the sign of h only, so the
# turning points are those of (|a|, ±advance).

def _hole_geometry_batch(l1: Floats, l2: Floats, depth: Floats, advance: Floats) -> Hole:
    a = l2 - l1
    psi = bars_depth_angle(l1, l2, depth)

    def h(phi: Floats, adv: Floats, a: Floats) -> Floats:
        return adv * psi_minus_sin(phi) + (adv - a) * np.sin(phi)
    h_end = h(psi, advance, a)
    flip = np.where(a < 0, -1.0, 1.0)
    a_abs, adv = np.abs(a), flip * advance
    ratio_ok = np.abs(adv) <= a_abs
    a_safe = np.where(a_abs > 0, a_abs, 1.0)
    phi_star = 2.0 * np.arctan2(np.sqrt(np.maximum(a_safe - adv, 0.0)),
                                np.sqrt(np.maximum(a_safe + adv, 0.0)))
    inside = ratio_ok & (phi_star < psi) & (a_abs > 0)
    h_star = np.where(inside, np.abs(h(np.where(inside, phi_star, 0.0), adv, a_abs)), 0.0)
    half = np.maximum(np.abs(h_end), h_star)
    return Hole(psi, -h_end, h_end, -half, half, 2.0 * half)


def _hole_geometry_scalar(l1: float, l2: float, depth: float, advance: float) -> Hole:
    a = l2 - l1
    psi = bars_depth_angle(l1, l2, depth)

    def h(phi: float, adv: float, a: float) -> float:
        return adv * psi_minus_sin(phi) + (adv - a) * math.sin(phi)
    h_end = h(psi, advance, a)
    a_abs, adv = (-a, -advance) if a < 0 else (a, advance)
    half = abs(h_end)
    if a_abs > 0 and abs(adv) <= a_abs:
        phi_star = 2.0 * math.atan2(math.sqrt(max(a_abs - adv, 0.0)),
                                    math.sqrt(max(a_abs + adv, 0.0)))
        if phi_star < psi:
            half = max(half, abs(h(phi_star, adv, a_abs)))
    return Hole(psi, -h_end, h_end, -half, half, 2.0 * half)


# --- what the hole width is sensitive to ------------------------------------------------------

@dataclass(frozen=True)
class HoleSensitivity:
    """∂(hole width)/∂x at a design point (SI): m per m for l1, l2 and depth, m per unit of the
    speed ratio λ = (l2 − l1)/advance. Bars and depth move at fixed advance (the machine kept in
    sync with the plant spacing); λ moves at fixed bars and depth."""

    width: Floats
    l1: Floats
    l2: Floats
    depth: Floats
    speed_ratio: Floats

    def as_dict(self) -> dict[str, float | bool | list[Any]]:
        return {k: _plain(getattr(self, k)) for k in ('l1', 'l2', 'depth', 'speed_ratio')}


def hole_sensitivity(l1: Floats, l2: Floats, depth: Floats, advance: Floats) -> HoleSensitivity:
    """Analytic derivatives of hole_geometry(...).width with respect to l1, l2, depth and λ.

    The half-width is |h| at the exit φ = ψ, or at the turning point φ* where that is larger
    (h(φ) = advance·φ − a sin φ, a = l2 − l1). At the exit,
    dh = ψ d(advance) − sin ψ da + (advance − a cos ψ) dψ with 1 − cos ψ = D/(l1 + l2), so
    dψ/dD = 1/(L sin ψ) and dψ/dL = −D/(L² sin ψ); at the turning point h'(φ*) = 0, so only the
    explicit terms remain: dh = φ* d(advance) − sin φ* da. λ enters through
    advance = a/λ: d(advance)/dλ = −advance/λ. Where the two candidates are equal (the
    narrowest hole, λ ≈ 1.05 for the tomato design) the width has a kink and this is the
    derivative of the exit branch. Scalars or arrays.
    """
    arrays = any(isinstance(v, np.ndarray) for v in (l1, l2, depth, advance))
    l1, l2, depth, advance = (np.asarray(v, dtype=float) for v in (l1, l2, depth, advance))
    hole = hole_geometry(l1, l2, depth, advance)
    a = l2 - l1
    total = l1 + l2
    psi = np.asarray(hole.psi)
    sin_psi = np.sin(psi)
    h_end = np.asarray(hole.exit_x)
    half = 0.5 * np.asarray(hole.width)
    # the turning point of |a| and the advance as seen from it (l1 > l2 runs the other way)
    flip = np.where(a < 0, -1.0, 1.0)
    a_abs, adv = np.abs(a), flip * advance
    phi_star = 2.0 * np.arctan2(np.sqrt(np.maximum(a_abs - adv, 0.0)),
                                np.sqrt(np.maximum(a_abs + adv, 0.0)))
    h_star = advance * phi_star - a * np.sin(phi_star)
    star = half > np.abs(h_end)
    with np.errstate(divide='ignore', invalid='ignore'):
        dpsi_dtotal = -depth / (total * total * sin_psi)
        dpsi_ddepth = 1.0 / (total * sin_psi)
    slope_end = advance - a * np.cos(psi)         # ∂h/∂φ at the exit
    s_end, s_star = np.sign(h_end), np.sign(h_star)

    def width_change(d_adv: Floats, d_a: Floats, d_psi: Floats) -> Floats:
        end = s_end * (psi * d_adv - sin_psi * d_a + slope_end * d_psi)
        turn = s_star * (phi_star * d_adv - np.sin(phi_star) * d_a)
        return 2.0 * np.where(star, turn, end)

    with np.errstate(divide='ignore', invalid='ignore'):
        dadv_dlambda = -advance * advance / a          # advance = a/λ
    out = HoleSensitivity(
        width=2.0 * half,
        l1=width_change(0.0, -1.0, dpsi_dtotal),
        l2=width_change(0.0, 1.0, dpsi_dtotal),
        depth=width_change(0.0, 0.0, dpsi_ddepth),
        speed_ratio=width_change(dadv_dlambda, 0.0, 0.0))
    if arrays:
        return out
    return HoleSensitivity(**{k: float(getattr(out, k)) for k in
                              ('width', 'l1', 'l2', 'depth', 'speed_ratio')})


TOLERANCE_SAMPLES = 100_000
TOLERANCE_PERCENTILES = (0.1, 1.0, 5.0, 50.0, 95.0, 99.0, 99.9)
TOLERANCE_BINS = 20


class ToleranceHistogram(TypedDict):
    edges: list[float]       # m, TOLERANCE_BINS + 1 bin edges
    counts: list[int]


class HoleTolerance(TypedDict):
    """hole_tolerance's JSON-ready figures (SI)."""

    bar_tolerance: float
    speed_error: float
    samples: int
    distribution: str
    seed: int
    nominal: float
    min: float
    max: float
    mean: float
    std: float
    percentiles: dict[str, float]        # '0.1', '1', ... '99.9' -> m
    histogram: ToleranceHistogram


def hole_tolerance(design: FiveBarDesign, bar_tolerance: float, speed_error: float,
                   samples: int = TOLERANCE_SAMPLES, seed: int = 0) -> HoleTolerance:
    """Hole widths of `samples` built machines: l1 and l2 each uniform within ±bar_tolerance
    (m) of the design, the ground speed uniform within ±speed_error (a fraction) of the
    synchronised speed, so advance = (d/2π)(1 + e); depth as designed. One vectorised
    hole_geometry call; a seeded generator, so the same inputs give the same figures.

    Returns a JSON-ready dict (SI): the inputs, the nominal width, min/max/mean/std,
    percentiles and a histogram of the widths.
    """
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.0, 1.0, (3, samples))
    l1 = design.l1 + bar_tolerance * u[0]
    l2 = design.l2 + bar_tolerance * u[1]
    advance = design.advance * (1.0 + speed_error * u[2])
    width = np.asarray(hole_geometry(l1, l2, design.depth, advance).width)
    counts, edges = np.histogram(width, bins=TOLERANCE_BINS)
    nominal = float(design.hole_width)
    return {
        'bar_tolerance': float(bar_tolerance),
        'speed_error': float(speed_error),
        'samples': int(samples),
        'distribution': 'uniform: l1, l2 within ±bar_tolerance, ground speed within '
                        '±speed_error of the synchronised speed, independent',
        'seed': int(seed),
        'nominal': nominal,
        'min': float(width.min()),
        'max': float(width.max()),
        'mean': float(width.mean()),
        'std': float(width.std()),
        'percentiles': {f'{p:g}': float(v) for p, v in
                        zip(TOLERANCE_PERCENTILES, np.percentile(width, TOLERANCE_PERCENTILES))},
        'histogram': {'edges': edges.tolist(), 'counts': counts.tolist()},
    }
