"""What the shell hands the command process at start: every setting as plain data (JSON), and
back into the typed configuration classes."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any

from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.control.machine_law import TurnConfig
from planter_ros.control.phase_lock import PhaseLockConfig
from planter_ros.drive.config import DriveConfig
from planter_ros.drive.setup import DriveSetup
from planter_ros.rows import Row
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
from planter_ros.sensing.row_speed import YawRateLimits

__all__ = ['LAW_CLASSES', 'CommandSettings', 'law_to_data', 'law_from_data']

# the law's configuration classes, in the order Machine(…, *values) takes them
LAW_CLASSES = (PhaseLockConfig, GroundSpeedLimits, YawRateLimits, TurnConfig)


def law_to_data(values: tuple) -> list[dict[str, Any]]:
    return [asdict(value) for value in values]


def law_from_data(data: list[dict[str, Any]]) -> tuple:
    return tuple(cls(**values) for cls, values in zip(LAW_CLASSES, data))


@dataclass(frozen=True)
class CommandSettings:
    """The command engine's settings: drive, loop, rows, law (the values of LAW_CLASSES);
    `data()` / `from_data()` for the command process. `setups`: row name -> what the machine
    file says of its drive (checked, applied at enable; its phase offset places the joint
    angle), none without a machine file. `hold`: build and check, but enable no drive until
    an operator's `enable` (a restart after a crash: doc/command.md)."""

    drive: DriveConfig
    loop: SyncLoopConfig
    rows: list[Row]
    law: tuple[Any, ...]
    log_level: str = 'info'
    setups: dict[str, DriveSetup] = field(default_factory=dict)
    hold: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, 'rows', list(self.rows))
        object.__setattr__(self, 'law', tuple(self.law))
        object.__setattr__(self, 'setups', dict(self.setups or {}))
        object.__setattr__(self, 'hold', bool(self.hold))

    def data(self) -> dict[str, Any]:
        return {'drive': asdict(self.drive), 'loop': asdict(self.loop),
                'rows': [row.as_dict() for row in self.rows], 'law': law_to_data(self.law),
                'log_level': self.log_level,
                'setups': {name: setup.data() for name, setup in self.setups.items()},
                'hold': self.hold}

    @classmethod
    def from_data(cls, data: dict[str, Any]) -> 'CommandSettings':
        rows = [Row(int(r['index']), str(r['name']), float(r['lateral_offset']),
                    None if r['drive_node_id'] is None else int(r['drive_node_id']),
                    bool(r['enabled'])) for r in data['rows']]
        return cls(DriveConfig(**data['drive']), SyncLoopConfig(**data['loop']), rows,
                   law_from_data(data['law']), data.get('log_level', 'info'),
                   {name: DriveSetup.from_data(setup)
                    for name, setup in data.get('setups', {}).items()},
                   bool(data.get('hold', False)))

    def held(self, hold: bool = True) -> 'CommandSettings':
        """The same settings, held (or not)."""
        return replace(self, hold=hold)
