"""What one drive tells the master, as the bus callbacks collect it: the statusword and error
code, the position (unwrapped across the 32-bit counter) and velocity from its TPDOs, whatever
PDOs the plan spread them over, and the EMCYs counted. `DriveStatus` is the snapshot the
control loop reads. The callbacks run on the Network's notifier thread and never block; readers
take `lock` (a Condition: waiting for the next TPDO)."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
import math
import threading
import time
from typing import TYPE_CHECKING

from . import objects as od

if TYPE_CHECKING:
    from canopen.emcy import EmcyConsumer, EmcyError
    from canopen.pdo.base import PdoMap

__all__ = ['DriveStatus', 'Feedback', 'EMCY_KEPT']

EMCY_KEPT = 100     # canopen's EMCY log and active list are trimmed to this many


@dataclass(frozen=True)
class DriveStatus:                             # snapshot, built without blocking
    state: str                                 # CiA 402 state name (drive.states) or 'UNKNOWN'
    statusword: int
    fault: bool                                # statusword bit 3 or an EMCY since the last reset
    error_code: int                            # 0x603F / last EMCY code, 0 if none
    position: float                            # mechanism angle (rad, unwrapped, from 0x6064)
    velocity: float                            # mechanism speed (rad/s, from 0x606C)
    heartbeat_age: float                       # s since the drive's last heartbeat (inf if never)
    stamp: float                               # time.monotonic() of the last feedback TPDO
    fault_reason: str = ''                     # why `fault` is set ('' when not), for diagnostics
    heartbeat_lost: bool = False               # heartbeat_age > drive_heartbeat_timeout
    resetting: bool = False                    # a requested fault reset is in progress
    enabled: bool = False                      # connected, OPERATION ENABLED, taking commands
    commanded_velocity: float = 0.0            # mechanism rad/s in the last RPDO sent
    mode: int = 0                              # 3 profile velocity, 8 CSP (0 before enable)
    commanded_position: float = math.nan       # CSP: mechanism rad in the last RPDO sent
    restarted: str = ''                        # why the drive must be configured again (it
                                               # booted, or its heartbeat says it is not
                                               # operational): '' when it need not


class Feedback:
    """The drive's own account of itself (module doc). `on_statusword(statusword)` is called
    under the lock with every new statusword (the fault latch watches it)."""

    def __init__(self, rad_per_count: float) -> None:
        self.lock = threading.Condition()
        self.rad_per_count = rad_per_count
        self.statusword = 0
        self.sw_received = False
        self.status_stamp = 0.0
        self.error_code = 0
        self._raw_position: int | None = None
        self.position_counts = 0
        self.velocity_counts = 0
        self.motion_stamp = 0.0
        #: EMCY frames received (every one, warnings and error resets too) and the last code
        self.emcy_count = 0
        self.last_emcy_code = 0
        self.on_statusword: Callable[[int], None] | None = None

    def on_tpdo(self, pdo_map: PdoMap) -> None:
        """A TPDO: whichever of our entries it carries (bus callback)."""
        now = time.monotonic()
        # every entry of ours is an integer (drive.objects); canopen types raw as any value
        values = {var.index: raw for var in pdo_map if isinstance(raw := var.raw, int)}
        with self.lock:
            if od.STATUSWORD.index in values:
                self.statusword = values[od.STATUSWORD.index]
                self.sw_received = True
                self.status_stamp = now
                if self.on_statusword is not None:
                    self.on_statusword(self.statusword)
            if od.ERROR_CODE.index in values:
                self.error_code = values[od.ERROR_CODE.index]
            if od.POSITION_ACTUAL.index in values:
                raw = values[od.POSITION_ACTUAL.index]
                if self._raw_position is None:
                    self.position_counts = raw
                else:                               # unwrap the 32-bit counter
                    self.position_counts += (raw - self._raw_position + 2**31) % 2**32 - 2**31
                self._raw_position = raw
                self.motion_stamp = now
            if od.VELOCITY_ACTUAL.index in values:
                self.velocity_counts = values[od.VELOCITY_ACTUAL.index]
                self.motion_stamp = now
            self.lock.notify_all()

    def count_emcy(self, entry: EmcyError, emcy: EmcyConsumer | None) -> None:
        """Count every EMCY; keep canopen's lists of them (`emcy`, the node's consumer)
        bounded: a drive in an EMCY storm sends hundreds a second."""
        self.emcy_count += 1
        self.last_emcy_code = entry.code
        if emcy is not None and len(emcy.log) > 2 * EMCY_KEPT:
            with emcy.emcy_received:
                del emcy.log[:-EMCY_KEPT]
                del emcy.active[:-EMCY_KEPT]

    def forget_statusword(self) -> None:
        with self.lock:
            self.sw_received = False

    @property
    def position(self) -> float:
        """Mechanism rad (unwrapped)."""
        return self.position_counts * self.rad_per_count

    @property
    def velocity(self) -> float:
        """Mechanism rad/s."""
        return self.velocity_counts * self.rad_per_count

    def fresh_position(self, within: float) -> bool:
        """A position arrived within `within` s (lock held or not: a read of two fields)."""
        return self._raw_position is not None and time.monotonic() - self.motion_stamp < within
