"""What the command engine holds per row, as plain state: the row, its law, its drive and what
it last did (`RowUnit`), and a row's measured motion as the shell publishes it (`Feedback`).

The engine's parts (life cycle, the control step, recovery, diagnostics) read and write these
under the engine's lock; reports are built from them. No CAN, no threads, no rclpy here.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from planter_ros.control import sync_status
from planter_ros.control.loop_timing import PeriodStats
from planter_ros.control.phase_lock import PhaseLock
from planter_ros.control.sync_status import Halt
from planter_ros.drive.states import CYCLIC_SYNC_POSITION
from planter_ros.rows import Row

from .recovery import RowRecovery

if TYPE_CHECKING:
    from planter_ros.drive.cia402 import Cia402Drive, DriveStatus

__all__ = ['Feedback', 'RowUnit']


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


@dataclass(frozen=True)
class Feedback:
    """A running row's measured motion for joint_states."""

    joint: str
    position: float
    velocity: float
    stamp: float
