"""The typed design: what the design node publishes on `design` and every consumer reads.

One frozen dataclass per mechanism, sharing `Design`'s fields. SI units (REP 103): lengths in
m, angles in rad, speeds in m/s and rad/s; the mechanism frame has x forward (the direction of
travel) and y up. A design read from an older recording may lack the fields that came later
(`nozzle_width`, `crop`, the nominal speeds, a three-arm goal's `basis`): those are None, and
a consumer that needs one says so (prediction: the nozzle width).

Built from a scene in `design.build`, turned into and read from the topic's JSON in
`design.message`. Light: no numpy, no mechanism model imported.
"""

from dataclasses import dataclass, field
from typing import ClassVar

__all__ = ['Design', 'FiveBar', 'GoalResult', 'ThreeArm', 'TipPath']


@dataclass(frozen=True, kw_only=True)
class Design:
    """What every mechanism's design says."""

    mechanism: ClassVar[str] = ''
    plant_spacing: float                 # d, distance between plants along the row (m)
    planting_depth: float                # D, depth of the nozzle tip below the soil (m)
    plants_per_revolution: int           # n, plants set per revolution of the driven shaft
    nozzle_width: float | None = None    # the nozzle's width along the row (m); the hole the
    #                                      soil sees is the tip's sweep plus this
    crop: str | None = None              # crop name, for people and recordings
    nominal_ground_speed: float | None = None      # v the scene plans for (m/s)
    top_ground_speed: float | None = None          # the highest v it plants at (m/s)
    nominal_mechanism_speed: float | None = None   # 2πv/(n·d) at that speed (rad/s)
    planting_phase: float | None = None  # shaft angle of the planting instant (rad); None:
    #                                      the mechanism's own (five-bar π, three-arm lowest tip)


@dataclass(frozen=True, kw_only=True)
class FiveBar(Design):
    """A geared five-bar (paper 1): one plant per revolution of the sun bar. The tip moves on
    x = (l2 − l1) sin θ, y = (l1 + l2) cos θ about the sun bar's pivot (θ = 0 at the top)."""

    mechanism: ClassVar[str] = 'five_bar'
    l1: float                            # sun bar AB (m)
    l2: float                            # planet bar BC (m)
    l3: float | None = None              # passive dyad C–D (m)
    l4: float | None = None              # passive dyad D–E (m)
    l5: float | None = None              # frame A–E (m)
    hole_ratio: float | None = None      # k = t/D asked for
    requested_hole: float | None = None  # t = k·D asked for (m)
    hole_width: float | None = None      # hole (entry–exit distance) achieved at λ = 1 (m)
    psi: float | None = None             # half crank angle below the soil surface (rad)
    method: str | None = None            # reverse design: exact, or paper (cube-root)
    dyad_ratios: tuple[float, ...] | None = None   # l3, l4, l5 over (l1 + l2)
    assemblable: bool | None = None      # the passive dyad closes over the whole cycle
    min_transmission_angle: float | None = None    # min over the cycle of min(μ, π − μ) (rad)


@dataclass(frozen=True)
class TipPath:
    """One nozzle tip over one revolution of the driven shaft, in the mechanism frame."""

    angle: tuple[float, ...]             # shaft angle (rad), increasing over one turn
    x: tuple[float, ...]                 # tip x, forward (m)
    y: tuple[float, ...]                 # tip y, up (m)


@dataclass(frozen=True)
class GoalResult:
    """One of the three-arm's eight goals as the design reports it."""

    name: str
    value: float                         # in `unit`
    lower: float | None                  # bound, in `unit` (None: none)
    upper: float | None
    unit: str                            # m or rad
    passed: bool
    basis: str | None = None             # 'paper' or 'assumption'
    assumed: dict = field(default_factory=dict)    # values it rests on the paper lacks (SI)
    derived: dict = field(default_factory=dict)    # figures computed alongside (SI)


@dataclass(frozen=True, kw_only=True)
class ThreeArm(Design):
    """A three-arm non-circular planetary gear mechanism (paper 2): three plants per carrier
    revolution; arms II and III follow arm I's tip path 2π/3 and 4π/3 later."""

    mechanism: ClassVar[str] = 'three_arm'
    tip_path: TipPath                    # arm I's tip over one carrier turn
    picking_phase: float | None = None   # carrier angle of arm I at picking (rad)
    centre_distance: float | None = None         # gear centre distance a (m)
    closure_residual: float | None = None        # |mean ratio − 1| of the gear closure
    closure_method: str | None = None
    interpolant: str | None = None               # pitch-curve reading of the control points
    pitch_radius_range: tuple[float, float] | None = None   # min, max pitch radius (m)
    goals: tuple[GoalResult, ...] = ()
    goals_passed: int | None = None
    all_goals_passed: bool | None = None
    paper_goals_passed: int | None = None
    paper_goals: int | None = None
    assumption_goals_passed: int | None = None
    assumption_goals: int | None = None
    phases_from: dict | None = None      # picking/planting phase: 'scene' or 'tip extremes'
    zero_slip_spacing: float | None = None       # spacing with no slip at planting (m)
    carrier_speed: float | None = None           # carrier speed at the nominal speed (rad/s)
