"""The design inputs: what a mechanism is designed from (the crop's planting depth and spacing,
the mechanism and its parameters), as a scene file (`config/*.yaml`), the command line or the
demo gives them, declared once for the design node, the command line, the demo and the core:
default, unit, range and meaning of every value.

Range checks live here; feasibility (does a mechanism with these values exist and run?) is the
models' job (`design.build.design_for_scene`). Light module: no numpy, no models imported.
"""

from dataclasses import dataclass
import math

from planter_ros.config import check, choice, setting

from .errors import DesignError
from .mechanisms import MECHANISMS, PITCH_CURVE_INTERPOLANTS


# the highest ground speed over the nominal one when a scene does not say (the demo's field
# run speeds up from its cruise at the nominal speed to this)
TOP_SPEED_FACTOR = 1.5


def top_ground_speed(nominal: float, top: float | None = None) -> float:
    """The highest ground speed a scene plants at (m/s): its `top_ground_speed`, or
    TOP_SPEED_FACTOR × its nominal ground speed when that is 0 or not given (at most the
    3 m/s a scene's speeds range to, at least the nominal speed)."""
    if top:
        return float(top)
    return max(float(nominal), min(TOP_SPEED_FACTOR * float(nominal), 3.0))


@dataclass(frozen=True, kw_only=True)
class DesignInputs:
    """Every design's inputs: the crop's agronomic needs and the mechanism (SI units)."""

    crop: str = setting('tomato', 'crop name, for people and recordings')
    mechanism: str = choice('five_bar', 'planting mechanism: five_bar (1 plant per revolution) '
                            'or three_arm (3 plants per revolution)', MECHANISMS)
    planting_depth: float = setting(0.045, 'planting depth D', unit='m', range=(0.001, 0.5))
    plant_spacing: float = setting(0.2, 'plant spacing d along the row', unit='m',
                                   range=(0.05, 2.0))
    hole_ratio: float = setting(0.05, 'five-bar: hole entry-exit distance over depth, '
                                'k = t/D; feasible while k·D < d and l1 > 0', range=(1e-4, 2.0))
    design_method: str = choice('exact', "five-bar reverse design: exact, or paper (the "
                                "paper's cube-root approximation)", ('exact', 'paper'))
    dyad_ratios: list[float] = setting([1.4, 1.5, 1.3], 'five-bar passive dyad l3, l4, l5 over '
                                '(l1 + l2)', range=(0.01, 100.0))
    nominal_ground_speed: float = setting(0.2, 'nominal ground speed v: the reported mechanism '
                                          'speed is 2πv/(n·d)', unit='m/s', range=(0.01, 3.0))
    top_ground_speed: float = setting(0.0, 'the highest ground speed the machine plants at: '
                                      'the cam is planned for it, the drive checked at it; 0: '
                                      f'{TOP_SPEED_FACTOR:g} × nominal_ground_speed (the field '
                                      "run's speed-up)", unit='m/s', range=(0.0, 3.0))
    nozzle_width: float = setting(kind=float, description="the nozzle's width along the row "
                                  '(a duckbill, a planting arm\'s clamp): the hole the soil sees '
                                  "is the tip's sweep plus this; no default, measure it",
                                  unit='m', range=(0.0, 0.5))
    design_spacing: float = setting(0.0, 'five-bar: the spacing the mechanism is built for '
                                    '(its l1, l2); 0: plant_spacing. With speed_profile: cam the '
                                    'sync node plants plant_spacing with this mechanism '
                                    '(doc/cam.md)', unit='m', range=(0.0, 2.0))
    spacing_schedule: list[float] = setting([], '`planter demo` and `planter simulate` only: [t1, '
                                     'd1, t2, d2, ...], plant_spacing becomes d_i at t_i s of '
                                     'the field run (a spacing changed at run time); the nodes '
                                     'ignore it',
                                     range=(0.0, 1e5))

    def __post_init__(self) -> None:
        check(self, DesignError.from_message)
        if self.top_ground_speed and self.top_ground_speed < self.nominal_ground_speed:
            raise DesignError('top_ground_speed', self.top_ground_speed,
                              f'0 or >= nominal_ground_speed = {self.nominal_ground_speed:g} '
                              'm/s')


@dataclass(frozen=True)
class ThreeArmInputs:
    """A three-arm mechanism's inputs (the paper's parameters, SI). The seven model values have
    no default: a scene that lacks one is refused, naming it."""

    control_radii: list[float] = setting(kind=list, description='pitch-curve control radii '
                                         'r_i', unit='m', range=(1e-4, 1.0))
    control_angles: list[float] = setting(kind=list, description='pitch-curve control angles '
                                          "θ_i, in the carrier's sense of rotation", unit='rad',
                                          range=(-2 * math.pi, 4 * math.pi))
    carrier_initial_angle: float = setting(kind=float, description='carrier initial angle Φ0',
                                           unit='rad', range=(-2 * math.pi, 2 * math.pi))
    arm_initial_angle: float = setting(kind=float, description='planting arm initial angle β0',
                                       unit='rad', range=(-2 * math.pi, 2 * math.pi))
    arm_length: float = setting(kind=float, description='planting arm length S', unit='m',
                                range=(0.01, 1.0))
    pusher_offset: float = setting(kind=float, description='pusher offset H1 from the arm line',
                                   unit='m', range=(0.0, 0.5))
    planet_carrier_angle: float = setting(kind=float, description='planet-carrier angle γ0',
                                          unit='rad', range=(-2 * math.pi, 2 * math.pi))
    interpolant: str = choice('periodic_cubic', 'pitch-curve reading of the control points: '
                              'interpolating (periodic_cubic, trigonometric) or approximating '
                              'B-spline with the points as control polygon (bspline_polar, '
                              'bspline_cartesian)', PITCH_CURVE_INTERPOLANTS)
    picking_phase: float = setting(-1.0, 'carrier angle of arm I at picking, for the picking '
                                   'and angle-difference goals; negative: at the highest tip '
                                   'point', unit='rad', range=(-1.0, 2 * math.pi))
    planting_phase: float = setting(-1.0, 'carrier angle of arm I at planting, for the pushing, '
                                    'angle-difference, seedling-push and gearbox goals; '
                                    'negative: at the lowest tip point', unit='rad',
                                    range=(-1.0, 2 * math.pi))
    seedling_height: float = setting(0.15, 'planted seedling above ground, for the no-push goal',
                                     unit='m', range=(0.01, 1.0))
    arm_width: float = setting(0.02, 'planting arm shell width, for the non-interference goal',
                               unit='m', range=(0.001, 0.2))

    def __post_init__(self) -> None:
        check(self, DesignError.from_message)


def input_classes(mechanism: str) -> tuple[type, ...]:
    """The classes of the design inputs of `mechanism` (a scene of it is made of them)."""
    return (DesignInputs, ThreeArmInputs) if mechanism == 'three_arm' else (DesignInputs,)
