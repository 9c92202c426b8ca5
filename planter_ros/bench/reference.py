"""High-precision references (mpmath) for the five-bar core, computed from the same float inputs.

Every function works at DIGITS significant digits *after* cancellation: where a formula
subtracts nearly equal numbers (ψ - sin ψ for small ψ, advance·φ - a sin φ near λ = 1) the
working precision is raised by the digits the subtraction loses, so the reference keeps at least
DIGITS correct digits. Inputs are taken as the exact binary floats they are.
"""

from dataclasses import dataclass
import math
from typing import SupportsFloat

import mpmath
from mpmath import mp, mpf

DIGITS = 40

# (x, y) of mpmath numbers (mpmath ships no type information: mpf is Any to the checker)
Pair = tuple[mpf, mpf]


def _extra_digits(small: float) -> int:
    """Digits lost by ψ - sin ψ ≈ ψ³/6 against ψ (≈ log10(6/ψ²)), for ψ ≈ small."""
    small = abs(float(small))
    if small == 0.0 or small >= 1.0:
        return 5
    return int(2 * -math.log10(small)) + 10


def solve_psi_reference(c: float) -> mpf:
    """ψ in (0, π] with ψ - sin ψ = c, by Newton in mpmath (c an exact float, 0 < c <= π)."""
    guess = min((6.0 * float(c)) ** (1.0 / 3.0), math.pi)
    with mp.workdps(DIGITS + _extra_digits(guess)):
        exact = mpf(c)
        # below the root (ψ³/6 > ψ - sin ψ)
        psi = min(mpf(6) * exact, mpf(mp.pi) ** 3) ** (mpf(1) / 3)
        tol = mpf(10) ** (-(DIGITS + 5))
        for _ in range(400):
            step = (psi - mpmath.sin(psi) - exact) / (1 - mpmath.cos(psi))
            psi -= step
            if abs(step) <= tol * psi:
                break
        else:
            raise ArithmeticError(f'reference Newton did not converge for c = {exact}')
        return +psi


def design_reference(depth: float, spacing: float, hole_ratio: float) -> Pair:
    """(l1, l2) of the exact design, as mpf: ψ - sin ψ = πkD/d, l1 + l2 = D/(1 - cos ψ)."""
    with mp.workdps(DIGITS + 20):
        c = mp.pi * mpf(hole_ratio) * mpf(depth) / mpf(spacing)
    psi = solve_psi_reference(c)
    with mp.workdps(DIGITS + _extra_digits(float(psi))):
        total = mpf(depth) / (2 * mpmath.sin(psi / 2) ** 2)
        half_gap = mpf(spacing) / (4 * mp.pi)
        return +(total / 2 - half_gap), +(total / 2 + half_gap)


def depth_angle_reference(depth: float, l1: float, l2: float) -> mpf:
    """ψ with 1 - cos ψ = D/(l1+l2), i.e. sin(ψ/2)² = D/(2L); π when D >= 2L (the soil line at
    or above the top of the path, the core's convention). l1 + l2 is summed exactly."""
    with mp.workdps(DIGITS + 10):
        ratio = mpf(depth) / (2 * (mpf(l1) + mpf(l2)))
        return +mp.pi if ratio >= 1 else 2 * mpmath.asin(mpmath.sqrt(ratio))


def hole_reference(l1: float, l2: float, depth: float, advance: float) -> Pair:
    """(entry-exit distance, swept extent) of the hole at depth D for advance = v/ω1 (mpf, m).

    Below the surface the path relative to its bottom is h(φ) = advance·φ - a sin φ on
    [-ψ, ψ], a = l2 - l1; the extent is 2·max|h| over φ = ψ and the stationary point
    cos φ* = advance/a (if it lies inside), found here with mpmath.findroot on h'(φ) = 0.
    """
    psi = depth_angle_reference(depth, l1, l2)
    with mp.workdps(DIGITS + _extra_digits(float(psi)) + 20):
        a = mpf(l2) - mpf(l1)
        adv = mpf(advance)

        def h(phi: mpf) -> mpf:
            return adv * phi - a * mpmath.sin(phi)
        end = abs(h(psi))
        half = end
        if a != 0 and abs(adv) <= abs(a):
            guess = mpmath.acos(adv / a)
            if guess < psi and guess > 0:
                phi = mpmath.findroot(lambda p: adv - a * mpmath.cos(p), guess)
                half = max(half, abs(h(phi)))
        return +(2 * end), +(2 * half)


def soil_point_reference(l1: float, l2: float, theta: float, advance: float) -> Pair:
    """Soil-frame tip position (x, y) as mpf: x = (l2-l1) sin θ + advance·θ, y = L(1+cos θ)."""
    with mp.workdps(DIGITS + 10):
        th = mpf(theta)
        return ((mpf(l2) - mpf(l1)) * mpmath.sin(th) + mpf(advance) * th,
                (mpf(l1) + mpf(l2)) * (1 + mpmath.cos(th)))


@dataclass(frozen=True)
class Chain:
    """The paper's 2R chain (formula 3): bars l1, l2 (m), α2 = gear_ratio·α1 + θ2, the bars'
    phases θ1, θ2 (rad)."""

    l1: float
    l2: float
    gear_ratio: float = -2.0
    theta1: float = 0.5 * math.pi
    theta2: float = 0.0


def chain_reference(alpha: float, omega1: float, chain: Chain) -> tuple[Pair, Pair, Pair]:
    """Position, velocity, acceleration of the paper's 2R chain (formula 3), as mpf tuples."""
    with mp.workdps(DIGITS + 10):
        al, w1, b1, b2 = mpf(alpha), mpf(omega1), mpf(chain.l1), mpf(chain.l2)
        a1 = al + mpf(chain.theta1)
        a12 = (1 + mpf(chain.gear_ratio)) * al + mpf(chain.theta1) + mpf(chain.theta2)
        w12 = (1 + mpf(chain.gear_ratio)) * w1
        pos = (b2 * mpmath.cos(a12) + b1 * mpmath.cos(a1),
               b2 * mpmath.sin(a12) + b1 * mpmath.sin(a1))
        vel = (-b2 * w12 * mpmath.sin(a12) - b1 * w1 * mpmath.sin(a1),
               b2 * w12 * mpmath.cos(a12) + b1 * w1 * mpmath.cos(a1))
        acc = (-b2 * w12 ** 2 * mpmath.cos(a12) - b1 * w1 ** 2 * mpmath.cos(a1),
               -b2 * w12 ** 2 * mpmath.sin(a12) - b1 * w1 ** 2 * mpmath.sin(a1))
        return pos, vel, acc


def rel_error(value: SupportsFloat, reference: mpf) -> float:
    """|value - reference| / |reference| as a float (value a float, reference an mpf)."""
    with mp.workdps(DIGITS + 10):
        ref = mpf(reference)
        diff = abs(mpf(value) - ref)
        return float(diff / abs(ref)) if ref != 0 else float(diff)


def dyad_reference(l1: float, l2: float, l3: float, l4: float,
                   l5: float) -> tuple[mpf, mpf, mpf | None]:
    """(min |CE|, max |CE|, min transmission angle or None if the dyad cannot close), as mpf.

    C = ((l2-l1) sin θ, (l1+l2) cos θ), E = (±l5, 0): |CE|² = (a s ∓ l5)² + L²(1 - s²) with
    s = sin θ, a quadratic in s whose extremes are at s = ±1 or its vertex; the transmission
    angle at D follows from the law of cosines at those extremes.
    """
    with mp.workdps(DIGITS + 30):
        b1, b2, b3, b4, b5 = (mpf(v) for v in (l1, l2, l3, l4, l5))
        a, big = b2 - b1, b1 + b2

        def r2(s: mpf) -> mpf:
            return (a * s - b5) ** 2 + big ** 2 * (1 - s ** 2)
        values = [r2(mpf(1)), r2(mpf(-1))]
        vertex = a * b5 / (a ** 2 - big ** 2)
        if abs(vertex) < 1:
            values.append(r2(vertex))
        rmin, rmax = mpmath.sqrt(min(values)), mpmath.sqrt(max(values))
        if not (rmax < b3 + b4 and rmin > abs(b3 - b4)):
            return +rmin, +rmax, None

        def mu(r: mpf) -> mpf:
            return mpmath.acos((b3 ** 2 + b4 ** 2 - r ** 2) / (2 * b3 * b4))
        return +rmin, +rmax, +min(mu(rmin), mp.pi - mu(rmax))
