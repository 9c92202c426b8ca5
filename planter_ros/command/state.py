"""What the command engine holds, as plain state: per row the row, its law, its drive and what
it last did (`RowUnit`); for the whole engine its configuration, rows, drives, lock and the
run's flags (`EngineState`); a row's measured motion as the shell publishes it (`Feedback`).

The engine's parts (command.lifecycle, command.design_change, command.control_step,
command.watch, command.status) each own their own state and share this one, under
`EngineState.lock`; reports are built from it. Nothing here imports the engine or its parts,
so they import it without a cycle; no CAN calls, no threads started, no rclpy.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
import threading
from typing import TYPE_CHECKING

from planter_ros.control import sync_status
from planter_ros.control.loop_timing import PeriodStats
from planter_ros.control.machine_law import Machine
from planter_ros.control.phase_lock import PhaseLock
from planter_ros.control.row_loop import RowLoop
from planter_ros.control.sync_status import Halt
from planter_ros.drive.bus_load import BusLoad
from planter_ros.drive.errors import DriveError
from planter_ros.drive.states import CYCLIC_SYNC_POSITION
from planter_ros.rows import IMPLICIT, Row

from .recovery import RowRecovery
from .settings import CommandSettings

if TYPE_CHECKING:
    from planter_ros.drive.cia402 import Cia402Drive, DriveStatus
    from planter_ros.drive.drive_set import DriveSet

__all__ = ['EngineState', 'Feedback', 'Log', 'RowUnit']

Log = Callable[[int, str], None]        # (logging level, one line)


class RowUnit:
    """One row as the engine runs it: the row, its law, its drive and what it last did."""

    def __init__(self, row: Row, law: PhaseLock, drive: Cia402Drive | None,
                 hardware_id: str) -> None:
        self.row = row
        # the joint's angle minus the drive's (rad): with a machine file's phase offset the
        # joint angle is the design's (the tip lowest at its bottom angle), else the drive's
        setup = drive.setup if drive is not None else None
        self.phase_offset = setup.phase_offset if setup is not None else None
        self.angle_shift = -self.phase_offset if self.phase_offset is not None else 0.0
        self.law = law
        self.drive = drive                  # None: disabled in the scene, never on the bus
        self.hardware_id = hardware_id
        self.running = False                # enabled at start-up and not shut down
        self.left_out = ''                  # why the drive was left out at start-up
        self.status: DriveStatus | None = None
        self.halt: Halt | None = sync_status.NEVER_ENABLED
        self.command = 0.0
        self.send_errors = 0
        self.last_send_error: tuple[float, str] | None = None
        self.joint: str | None = None       # joint name, once the design is known
        self.period = PeriodStats()         # gaps between its command frames
        self.faults = 0                     # drive faults (and lost heartbeats) seen
        self.last_fault = ''
        self.target: float | None = None    # CSP: position target of the next SYNC (rad)
        self.target_time = 0.0              # when it was computed (monotonic s)
        self.behind = 0.0                   # s of motion still to be made up (late steps)
        self.recovery = RowRecovery()       # halts, the plants they cost, restarts, EMCYs

    @property
    def csp(self) -> bool:
        return self.drive is not None and self.drive.mode == CYCLIC_SYNC_POSITION

    @property
    def label(self) -> str:
        return self.row.label

    @property
    def bus_drive(self) -> Cia402Drive:
        """The drive of a row on the bus (DriveError for a row disabled in the scene: it never
        runs, so nothing running asks)."""
        if self.drive is None:
            raise DriveError(f'row {self.label} is disabled in the scene: it has no drive')
        return self.drive

    @property
    def measured(self) -> DriveStatus:
        """The drive's last status (a running row has one from its first step on)."""
        if self.status is None:
            raise DriveError(f'row {self.label}: no status from its drive yet')
        return self.status

    def joint_status(self, status: DriveStatus) -> DriveStatus:
        """The drive's status with the row's joint angle (see `angle_shift`)."""
        if self.angle_shift == 0.0 and self.phase_offset is None:
            return status
        return replace(status, position=status.position + self.angle_shift,
                       commanded_position=status.commanded_position + self.angle_shift)


@dataclass(frozen=True)
class Feedback:
    """A running row's measured motion for joint_states."""

    joint: str
    position: float
    velocity: float
    stamp: float


class EngineState:
    """What the engine's parts share: the configuration, the rows (`units`), the laws, the
    drives and the run's flags. Every read and write holds `lock`."""

    def __init__(self, settings: CommandSettings, machine: Machine, drives: DriveSet,
                 bus_load: BusLoad, log: Log) -> None:
        drive_config, rows = settings.drive, settings.rows
        self.drive_config = drive_config
        self.loop = settings.loop
        self.log = log
        self.rows = rows
        self.implicit = len(rows) == 1 and rows[0].name == IMPLICIT
        self.machine = machine
        self.row_loop = RowLoop(machine, drive_config.heartbeat_period,
                                drive_config.drive_heartbeat_timeout)
        self.drives = drives
        self.bus_load = bus_load
        self.bus_id = f'{drive_config.can_interface}:{drive_config.can_channel}'
        self.units = [RowUnit(row, machine.laws[row.index], drives.drives.get(row.name),
                              f'{self.bus_id} node {row.drive_node_id}')
                      for row in rows]
        self.hardware_id = self.units[0].hardware_id
        self.lock = threading.RLock()
        self.shut_down = False
        self.stopping = False               # ramping to zero before a shutdown
        self.csp = False                    # some row runs CSP: SYNC every step, targets
        self.sync_loop = False              # the loop sends SYNC (CSP, or feedback on SYNC)
        self.bus_send_errors = 0            # SYNC and heartbeat (a row's are its own)
        self.last_bus_error: tuple[float, str] | None = None

    @property
    def law(self) -> PhaseLock:
        """The first row's law."""
        return self.units[0].law

    @property
    def send_errors(self) -> int:
        return self.bus_send_errors + sum(unit.send_errors for unit in self.units)

    @property
    def running(self) -> int:
        """Rows whose drives run."""
        return sum(unit.running for unit in self.units)

    @property
    def period(self) -> float:
        """The loop's period: the SYNC period when a row runs CSP, else the control period."""
        return self.drive_config.sync_period if self.csp else self.loop.control_period

    def unit(self, name: str) -> RowUnit:
        return next(unit for unit in self.units if unit.row.name == name)

    def row_text(self, unit: RowUnit, text: str) -> str:
        return text if self.implicit else f'row {unit.label}: {text}'

    def idle_reason(self, unit: RowUnit) -> str:
        if unit.drive is None:
            return 'disabled in the scene: never enabled on the bus'
        if unit.left_out:
            return f'left out at start-up: {unit.left_out}'
        return 'shut down' if self.shut_down else 'not enabled yet'

    def mode_text(self) -> str:
        """The CiA 402 mode the enabled drives run, in words."""
        return (f'cyclic synchronous position, SYNC every '
                f'{1e3 * self.drive_config.sync_period:g} ms' if self.csp
                else 'profile velocity')
