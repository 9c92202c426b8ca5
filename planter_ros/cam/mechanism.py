"""The geared five-bar as the cam sees it, and the laws the sun bar may follow in the soil.

The tip in the soil frame (paper 1, formula 8, with the travelled distance s in place of v·t;
x along the row, y up from the lowest point of the tip's path, θ = 0 at the top):

    x = (l2 − l1) sin θ + s,        y = (l1 + l2)(1 + cos θ),

in the soil where y ≤ D, i.e. θ = π + φ with |φ| ≤ ψ, cos ψ = 1 − D/(l1 + l2). The tip stands
still in the soil when dx/ds = a cos θ · θ′ + 1 = 0 (a = l2 − l1): θ′ = −1/(a cos θ).

A cam is a function of distance, θ(s). Over the in-soil arc every law here is written the
other way round, as the distance travelled since the planting instant (the bottom, φ = 0):

    s(φ) = zero_slip · a sin φ + advance · φ,

* constant speed at spacing d:   zero_slip = 0, advance = d/2π;
* the design-speed rule:         zero_slip = 0, advance = a (the sun bar turns at the
  mechanism's own zero-speed ratio θ′ = 1/a: the hole it was designed for);
* exact zero slip:               zero_slip = 1, advance = 0 (a sin θ + s constant: x stands
  still, a point hole);
* a blend β of a law with constant speed: both coefficients blended.

In the soil the tip then moves by x − x_plant = advance · φ − (1 − zero_slip) · a sin φ: the
five-bar's own closed-form hole (`five_bar.hole_geometry`) of a mechanism with l2 − l1 =
(1 − zero_slip)·a at that advance, which gives the tip sweep without sampling. The tilt is the
monitor's model (`kinematics.planting`) fed the mean advance of the exit climb,
Δs/ψ: the stem is dragged by the slip Δs − a·ψ relative to the synchronous path.

Pure numpy: no ROS.
"""

from dataclasses import dataclass
import math
from typing import Protocol

from planter_ros.kinematics.arrays import Floats
from planter_ros.kinematics.five_bar import (
    TWO_PI, bars_depth_angle, hole_geometry, soil_trajectory)
from planter_ros.kinematics.planting import FiveBarPlanting

from .errors import CamInputError

__all__ = ['CamMechanism', 'SoilLaw', 'RULES', 'rule_law', 'constant_law']

# the cam rules a user chooses between (constant speed is the reference, not a rule)
RULES = ('design_speed', 'zero_slip')

# the in-soil law's slowest point must still move forward this much (m/rad) relative to a
_MIN_SLOPE = 1e-6


class BarsAndDepth(Protocol):
    """A five-bar design as `CamMechanism.from_design` reads it (lengths in m; one design:
    an array holds one value)."""

    @property
    def l1(self) -> Floats: ...

    @property
    def l2(self) -> Floats: ...

    @property
    def depth(self) -> Floats: ...


def _finite_positive(name: str, value: object, unit: str) -> float:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise CamInputError(name, value, f'finite and > 0 {unit}')
    return float(value)


@dataclass(frozen=True)
class CamMechanism:
    """The five-bar's bars and the planting depth (m); `nozzle_width` is the nozzle's width along
    the row (m), added to the tip's sweep for the hole the soil sees."""

    l1: float
    l2: float
    depth: float
    nozzle_width: float = 0.0

    def __post_init__(self) -> None:
        for name in ('l1', 'l2', 'depth'):
            object.__setattr__(self, name, _finite_positive(name, getattr(self, name), 'm'))
        w: object = self.nozzle_width          # checked: the caller's value, of any type
        if not (isinstance(w, (int, float)) and math.isfinite(w) and w >= 0):
            raise CamInputError('nozzle_width', w, 'finite and >= 0 m')
        object.__setattr__(self, 'nozzle_width', float(w))
        if not self.l2 > self.l1:
            raise CamInputError('l2', self.l2, f'> l1 = {self.l1:.6g} m', 'the nozzle must loop')
        if not self.depth < 2.0 * (self.l1 + self.l2):
            raise CamInputError('depth', self.depth, f'< 2(l1 + l2) = '
                                f'{2 * (self.l1 + self.l2):.6g} m')

    @classmethod
    def from_design(cls, design: BarsAndDepth, nozzle_width: float = 0.0) -> 'CamMechanism':
        """From the five-bar core's design (`five_bar.FiveBarDesign`, scalar) or any object
        with l1, l2 and depth in m."""
        return cls(float(design.l1), float(design.l2), float(design.depth), nozzle_width)

    @property
    def a(self) -> float:
        """l2 − l1 (m): the tip's speed in the frame at the bottom is a·θ′ backwards."""
        return self.l2 - self.l1

    @property
    def total(self) -> float:
        return self.l1 + self.l2

    @property
    def psi(self) -> float:
        """Half the sun-bar angle spent in the soil (rad): entry at π − ψ, exit at π + ψ."""
        return bars_depth_angle(self.l1, self.l2, self.depth)

    @property
    def design_spacing(self) -> float:
        """The spacing this mechanism plants at zero speed turning at constant speed, 2π·a."""
        return TWO_PI * self.a

    @property
    def design_hole(self) -> float:
        """The tip sweep at its own zero-speed ratio (m): the hole it was designed for."""
        return float(hole_geometry(self.l1, self.l2, self.depth, self.a).width)

    def tip(self, theta: Floats, s: Floats) -> tuple[Floats, Floats]:
        """Tip in the soil frame (m) at sun-bar angle θ and travelled distance s (arrays)."""
        x, y = soil_trajectory(self.l1, self.l2, theta, 0.0)
        return x + s, y


@dataclass(frozen=True)
class SoilLaw:
    """The sun bar's law over the in-soil arc: s(φ) = zero_slip·a·sin φ + advance·φ (m),
    φ = θ − π in [−ψ, ψ], s from the planting instant. `name` says which law it is."""

    zero_slip: float
    advance: float
    name: str = ''

    def check(self, mech: CamMechanism) -> 'SoilLaw':
        """Refuse a law that does not move forward over the whole in-soil arc (exact zero slip
        with the soil surface at or above the sun-bar axis, ψ ≥ π/2)."""
        slowest = self.zero_slip * mech.a * math.cos(mech.psi) + self.advance
        if not slowest > _MIN_SLOPE * mech.a:
            raise CamInputError('depth', mech.depth, f'< l1 + l2 = {mech.total:.6g} m for '
                                f'{self.name or "this law"}', 'zero slip needs the tip to move '
                                'backwards in the frame over the whole in-soil arc')
        return self

    def distance(self, mech: CamMechanism, phi: float) -> float:
        """s(φ) (m): distance travelled from the planting instant to sun-bar angle π + φ."""
        return self.zero_slip * mech.a * math.sin(phi) + self.advance * phi

    def derivatives(self, mech: CamMechanism, phi: float) -> tuple[float, float, float]:
        """(s′, s″, s‴)(φ) in m/rad, m/rad², m/rad³."""
        za = self.zero_slip * mech.a
        return (za * math.cos(phi) + self.advance, -za * math.sin(phi), -za * math.cos(phi))

    def half_length(self, mech: CamMechanism) -> float:
        """Distance from the planting instant to the soil exit (= from the entry to it), m."""
        return self.distance(mech, mech.psi)

    def angle_derivatives(self, mech: CamMechanism, phi: float) -> tuple[float, float, float]:
        """(θ′, θ″, θ‴) at φ: the derivatives of the inverse function θ(s)."""
        s1, s2, s3 = self.derivatives(mech, phi)
        d1 = 1.0 / s1
        d2 = -s2 * d1 ** 3
        d3 = (3.0 * s2 * s2 - s1 * s3) * d1 ** 5
        return d1, d2, d3

    def edge_state(self, mech: CamMechanism, side: float) -> tuple[float, float, float]:
        """(θ, θ′, θ″) at the soil exit (side = +1) or entry (side = −1), θ of the plant at π."""
        phi = side * mech.psi
        d1, d2, _ = self.angle_derivatives(mech, phi)
        return math.pi + phi, d1, d2

    def tip_sweep(self, mech: CamMechanism) -> float:
        """The tip's swept extent along the row in the soil (m), closed form (module doc)."""
        a_eff = (1.0 - self.zero_slip) * mech.a
        if a_eff == 0.0 and self.advance == 0.0:
            return 0.0
        half = 0.5 * a_eff
        return float(hole_geometry(0.5 * mech.total - half, 0.5 * mech.total + half,
                                   mech.depth, self.advance).width)

    def hole_width(self, mech: CamMechanism) -> float:
        return self.tip_sweep(mech) + mech.nozzle_width

    def climb_advance(self, mech: CamMechanism, psi: float | None = None) -> float:
        """Mean advance over the climb from the planting instant to the soil exit, Δs/ψ
        (m/rad): what the tilt model's v/ω means when ω is not constant."""
        psi = mech.psi if psi is None else psi
        return self.distance(mech, psi) / psi

    def tilt(self, mech: CamMechanism) -> float:
        """The seedling's tilt from vertical (rad, + = top leaning forward) by the monitor's
        tilt model (`kinematics.planting`), fed this law's exit climb."""
        model = FiveBarPlanting(mech.l1, mech.l2, mech.depth, mech.design_spacing,
                                nozzle_width=mech.nozzle_width)
        return float(model.tilt(self.climb_advance(mech, model.exit_angle)))

    def blend(self, other: 'SoilLaw', beta: float) -> 'SoilLaw':
        """β·self + (1 − β)·other (both coefficients): β = 1 is this law, 0 the other."""
        return SoilLaw(beta * self.zero_slip + (1.0 - beta) * other.zero_slip,
                       beta * self.advance + (1.0 - beta) * other.advance,
                       f'{self.name} blended {beta:.4g} with {other.name}')

    def same_as(self, other: 'SoilLaw') -> bool:
        return self.zero_slip == other.zero_slip and self.advance == other.advance


def constant_law(spacing: float) -> SoilLaw:
    """Constant sun-bar speed at spacing d: one revolution per d."""
    return SoilLaw(0.0, spacing / TWO_PI, 'constant speed')


def rule_law(mech: CamMechanism, rule: str) -> SoilLaw:
    """The in-soil law of a cam rule: 'design_speed' or 'zero_slip'."""
    if rule == 'design_speed':
        return SoilLaw(0.0, mech.a, 'design-speed rule')
    if rule == 'zero_slip':
        return SoilLaw(1.0, 0.0, 'exact zero slip').check(mech)
    raise CamInputError('rule', rule, ' or '.join(RULES))
