"""The sync law of a whole machine: several planting units (rows) on one ground-speed sensor.

Each row keeps its own `PhaseLock` (the per-row law, unchanged), fed with the row's own speed
v_i = v − ω_z·y_i (turn compensation: on a curve the outer rows travel faster than the inner
ones) from the machine's one motion filter (`planter_ros.sensing.row_speed`): feed-forward
2πv_i/(n·d), the phase locked to the row's own travelled distance s_i = ∫v_i dt. A row whose
v_i ≤ 0 (or every row, when the machine itself is not moving forward) holds (never turns
backwards) and keeps its grid. With `turn_compensation` off every row
runs on the machine's v, so the difference can be shown. Rows are switched off and on one by one
(section control, `PhaseLock.switch`). Time is passed in explicitly; pure, no ROS.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from planter_ros.config import check, setting
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
from planter_ros.sensing.row_speed import MotionFilter, YawRateLimits, row_speed

from .phase_lock import PhaseLock, PhaseLockConfig, PlantingAngles


@dataclass(frozen=True)
class TurnConfig:
    """Turn compensation (a sync node parameter, changeable at run time)."""

    turn_compensation: bool = setting(True, "true: each row runs on its own speed v − ω_z·y "
                                      '(y its lateral offset, ω_z the yaw rate); false: every '
                                      "row on the machine's v (rows off their grids on a curve)")

    def __post_init__(self) -> None:
        check(self)


class Machine:
    """One motion filter, one PhaseLock per row at lateral offset `offsets[i]` (m, + left)."""

    def __init__(self, offsets: Iterable[float], config: PhaseLockConfig | None = None,
                 limits: GroundSpeedLimits | None = None,
                 yaw_limits: YawRateLimits | None = None, turn: TurnConfig | None = None) -> None:
        config = config or PhaseLockConfig()
        self.offsets = [float(y) for y in offsets]
        self.filter = MotionFilter(limits or GroundSpeedLimits(), yaw_limits or YawRateLimits())
        self.turn = turn or TurnConfig()
        self.laws = [PhaseLock(config, speed_filter=self.filter.speed) for _ in self.offsets]
        # the machine's reference point (y = 0): travelled distance and staleness for people
        self.reference = PhaseLock(config, speed_filter=self.filter.speed)
        self.yaw_rate_value = 0.0           # yaw rate of the last sample used (rad/s)

    def configure(self, config: PhaseLockConfig, limits: GroundSpeedLimits,
                  yaw_limits: YawRateLimits, turn: TurnConfig) -> None:
        """New gains and limits (a parameter update at run time)."""
        self.filter.configure(limits, yaw_limits)
        self.turn = turn
        for law in self.laws + [self.reference]:
            law.config = config

    def set_design(self, spacing: float, plants_per_revolution: int, now: float,
                   planting: PlantingAngles | None = None, cams: Sequence[Any] | None = None,
                   since: float | None = None) -> None:
        """A design for every row: each row running on its grid takes it at its own next
        planting instant (PhaseLock.set_design). `cams`: each row's cam profile (None:
        constant speed), or None for constant speed on every row. A cam change over the
        drive's limits on any row raises CamLimitError before any row changes."""
        cams = cams if cams is not None else [None] * len(self.laws)
        # every row's change checked first (CamLimitError: no row changes)
        for law, cam in zip(self.laws, cams):
            law.check_cam(cam, plants_per_revolution, now, since)
        for law, cam in zip(self.laws, cams):
            law.set_design(spacing, plants_per_revolution, now, planting, cam, since)

    def set_planting(self, planting: PlantingAngles | None) -> None:
        """Where the design's mechanism plants (PlantingAngles or None), found later than the
        design itself; used by the next section stops and design changes."""
        for law in self.laws:
            law.set_planting(planting)

    def sample(self, v: float, yaw_rate: float, now: float) -> bool:
        """Offer a ground-speed message's v (m/s) and ω_z (rad/s); True when the rows use it."""
        motion = self.filter.check(v, yaw_rate, now)
        if motion is None:
            return False
        v, w = motion
        self.yaw_rate_value = w
        used = w if self.turn.turn_compensation else 0.0
        self.reference.row_speed(v, now)
        for law, y in zip(self.laws, self.offsets):
            law.row_speed(row_speed(v, used, y), now)
        return True

    def row_speeds(self) -> list[float]:

        """The speed each row runs on now (m/s, ≥ 0)."""
        return [law.ground_speed_value for law in self.laws]
