"""Paper 2's own figures next to the model: Table 1 and the readings of its equations 4–14.

Table 1 of the paper gives, for its parameter set (§4.1, config/rice_three_arm.yaml), the
carrier angle at which each arm picks and plants: picking 20°, 140°, 260°, planting 191°, 311°,
71° for arms I, II, III. `paper_comparison` sets the model's picking point (highest tip point)
and planting point (lowest) of every arm beside them, with the picking and pushing angles the
model gives at the paper's angles.

The paper leaves its equations open to several readings; `readings()` are the ones tried, each a
change of the scene values that turns our model into that reading (`reading_parameters`, see
doc/design.md):

* γ0 sense: our model measures γ0 in the carrier's sense (clockwise); counter-clockwise, as
  eq 13 is printed (O3 = O2 + a·e(φ_H + γ0)), is γ0 → −γ0 in ours;
* β0 sense: likewise eq 14 as printed (φ3 + β0) is β0 → −β0;
* arm offset: our planet polar axis points from O3 towards its mesh point with the
  intermediate; the other end of that line turns the arm by π (β0 → β0 + π);
* planet reference: our arm angle follows the planet's absolute mesh angle w(θ); eq 8 with
  φ30 taken as the planet's mesh phase at θ = 0 measures it from there (β0 → β0 + w(0));
* pitch curve: the four interpolants of pitch_curve.
"""

from __future__ import annotations

from collections.abc import Mapping
import itertools
import math
from typing import TypedDict

import numpy as np

from .gear_train import ARMS, ThreeArmMechanism, _float
from .goals import _below_horizontal, _extremes, gear_module_limit
from .pitch_curve import INTERPOLANTS, TWO_PI

DEG = math.pi / 180.0
ARM_NAMES = ('I', 'II', 'III')
TABLE_1 = {'picking': tuple(v * DEG for v in (20.0, 140.0, 260.0)),
           'planting': tuple(v * DEG for v in (191.0, 311.0, 71.0))}
TABLE_1_SOURCE = ('paper 2, Table 1: carrier angle of each arm at picking and planting, for '
                  'its parameter set (§4.1)')


def _wrap(angle: float) -> float:
    """An angle difference in (−π, π]."""
    return -math.remainder(-float(angle), TWO_PI)


def arm_timing(mech: ThreeArmMechanism, arm: int, samples: int = 3600) -> tuple[float, float]:
    """(picking, planting) carrier angles of one arm: its highest and lowest tip points."""
    theta = np.linspace(0.0, TWO_PI, samples, endpoint=False)
    high, low = _extremes(theta, np.asarray(mech.tip(theta, arm)[1]))
    return float(np.mod(high, TWO_PI)), float(np.mod(low, TWO_PI))


def _attitude_below(mech: ThreeArmMechanism, theta: float, arm: int) -> float:
    return float(_below_horizontal(mech.pusher_attitude(theta, arm)))


class ArmComparison(TypedDict):
    """One arm's timing and attitudes beside Table 1's (rad)."""

    arm: str
    picking_phase: float
    paper_picking_phase: float
    picking_phase_difference: float
    planting_phase: float
    paper_planting_phase: float
    planting_phase_difference: float
    picking_angle: float
    picking_angle_at_paper_phase: float
    pushing_angle: float
    pushing_angle_at_paper_phase: float


class PaperComparison(TypedDict):
    source: str
    arms: list[ArmComparison]


def paper_comparison(mech: ThreeArmMechanism, samples: int = 3600) -> PaperComparison:
    """Per arm: the model's picking and planting carrier angles beside Table 1's, their
    differences, and the picking and pushing angles (goals 2 and 3) at both (rad)."""
    arms: list[ArmComparison] = []
    for k in range(ARMS):
        pick, plant = arm_timing(mech, k, samples)
        paper_pick, paper_plant = TABLE_1['picking'][k], TABLE_1['planting'][k]
        arms.append({
            'arm': ARM_NAMES[k],
            'picking_phase': pick,
            'paper_picking_phase': paper_pick,
            'picking_phase_difference': _wrap(pick - paper_pick),
            'planting_phase': plant,
            'paper_planting_phase': paper_plant,
            'planting_phase_difference': _wrap(plant - paper_plant),
            'picking_angle': _attitude_below(mech, pick, k),
            'picking_angle_at_paper_phase': _attitude_below(mech, paper_pick, k),
            'pushing_angle': _attitude_below(mech, plant, k),
            'pushing_angle_at_paper_phase': _attitude_below(mech, paper_plant, k),
        })
    return {'source': TABLE_1_SOURCE, 'arms': arms}


# the sign an angle of the scene takes in our (clockwise) convention under each reading
_SENSES = {'cw': 1.0, 'ccw': -1.0}


def readings() -> list[tuple[str, str, str, str, str]]:
    """Every reading tried: (γ0 sense, β0 sense, arm offset, planet reference, interpolant)."""
    return list(itertools.product(_SENSES, _SENSES, ('mesh point', 'opposite'),
                                  ('absolute', 'from θ = 0'), tuple(INTERPOLANTS)))


def reading_parameters(params: Mapping[str, object],
                       reading: tuple[str, str, str, str, str]) -> dict[str, object]:
    """The scene values that make our model follow `reading` (see the module doc)."""
    gamma_sense, beta_sense, offset, reference, interpolant = reading
    out = dict(params, interpolant=interpolant)
    out['planet_carrier_angle'] = _SENSES[gamma_sense] * _float(params, 'planet_carrier_angle')
    beta = _SENSES[beta_sense] * _float(params, 'arm_initial_angle')
    if offset == 'opposite':
        beta += math.pi
    if reference == 'from θ = 0':
        mech = ThreeArmMechanism.from_parameters(dict(out, arm_initial_angle=beta))
        beta += float(mech._w0[0])
    out['arm_initial_angle'] = beta
    return out


class ReadingRow(TypedDict):
    """Arm I's timing against Table 1 and the attitude goals (rad), and the gear module (m),
    under one reading."""

    reading: tuple[str, str, str, str, str]
    picking_phase: float
    picking_phase_difference: float
    planting_phase: float
    planting_phase_difference: float
    picking_angle: float
    pushing_angle: float
    picking_angle_at_paper_phase: float
    pushing_angle_at_paper_phase: float
    gear_module: float


def reading_table(params: Mapping[str, object], samples: int = 3600) -> list[ReadingRow]:
    """One row per reading: arm I's timing against Table 1 and the attitude goals (rad), and
    the gear module (m)."""
    rows: list[ReadingRow] = []
    for reading in readings():
        mech = ThreeArmMechanism.from_parameters(reading_parameters(params, reading))
        pick, plant = arm_timing(mech, 0, samples)
        rows.append({
            'reading': reading,
            'picking_phase': pick,
            'picking_phase_difference': _wrap(pick - TABLE_1['picking'][0]),
            'planting_phase': plant,
            'planting_phase_difference': _wrap(plant - TABLE_1['planting'][0]),
            'picking_angle': _attitude_below(mech, pick, 0),
            'pushing_angle': _attitude_below(mech, plant, 0),
            'picking_angle_at_paper_phase': _attitude_below(mech, TABLE_1['picking'][0], 0),
            'pushing_angle_at_paper_phase': _attitude_below(mech, TABLE_1['planting'][0], 0),
            'gear_module': float(gear_module_limit(mech)[0]),   # a float for one design
        })
    return rows
