"""What tests and the demo read of a simulated drive, in SI (motor shaft rad and rad/s) unless
named counts: read-only views of the drive's parts (the drive's lock taken where two values
must agree)."""
from __future__ import annotations

import math
import threading
from typing import TYPE_CHECKING

from .mechanism import wrap_angle

if TYPE_CHECKING:
    from .clock import Gaps
    from .device import SimulatedDevice
    from .faults import InjectedFaults
    from .mechanism import Mechanism
    from .motor import Motor
    from .node import StrictNode
    from .pdo import PdoTiming
    from .spec import SimSpec
    from .watchdog import Watchdog

__all__ = ['DriveViews']

TWO_PI = 2.0 * math.pi


class DriveViews:
    """Read-only views of a SimulatedDrive's parts (mixed into it; the parts it reads, which
    SimulatedDrive makes, are declared here)."""

    spec: SimSpec
    node: StrictNode
    device: SimulatedDevice
    mechanism: Mechanism
    faults: InjectedFaults
    watchdog: Watchdog
    pdo: PdoTiming
    sync_gaps: Gaps
    sync_count: int
    sync_late: int
    sync_missing: int
    following_error_faults: int
    _lock: threading.RLock
    _heartbeat_period: float

    @property
    def state(self) -> str:
        return self.device.control.state

    @property
    def statusword(self) -> int:
        with self._lock:
            return self.device.statusword()

    @property
    def controlword(self) -> int:
        return self.device.control.controlword

    @property
    def nmt_state(self) -> str:
        return self.node.nmt.state

    @property
    def mode_display(self) -> int:
        return self.device.control.mode

    @property
    def supported_modes(self) -> tuple[int, ...]:
        return self.device.supported_modes

    @property
    def motor(self) -> Motor:
        return self.device.motor

    @property
    def motor_velocity(self) -> float:
        """Motor shaft speed, rad/s."""
        return self.device.motor.shaft_velocity

    @property
    def motor_position(self) -> float:
        """Motor shaft angle, rad."""
        return self.device.motor.shaft_position

    @property
    def target_velocity(self) -> float:
        """Target velocity 60FFh as last received, motor rad/s."""
        return self.device.target * TWO_PI / self.spec.counts_per_motor_rev

    @property
    def target_counts(self) -> int:
        """Target velocity 60FFh as last received, counts/s."""
        return self.device.target

    @property
    def target_at_enable(self) -> int | None:
        """60FFh (counts/s) at the moment the drive last entered OPERATION ENABLED."""
        return self.device.target_at_enable

    @property
    def quick_stopped(self) -> bool:
        """A quick stop happened since the drive was last in OPERATION ENABLED."""
        return self.device.control.quick_stopped

    @property
    def error_code(self) -> int:
        return self.device.control.error_code

    @property
    def heartbeat_period(self) -> float:
        return self._heartbeat_period

    @property
    def interpolation_period(self) -> float:
        """s, the CSP interpolation period the drive uses (60C2h, or 1006h)."""
        return self.device.csp.period

    @property
    def following_error(self) -> float:
        """CSP: set point − actual position, motor rad."""
        return self.device.csp.error * TWO_PI / self.spec.counts_per_motor_rev

    @property
    def last_following_fault(self) -> str:
        return self.device.csp.last_fault

    @property
    def targets_missing(self) -> int:
        return self.device.csp.targets_missing

    @property
    def watchdog_trips(self) -> list[tuple[str, int]]:
        """Communication watchdog trips, newest last: (reason, EMCY code)."""
        return self.watchdog.trips

    @property
    def rpdo_count(self) -> int:
        return self.pdo.rpdo_count

    @property
    def tpdo_count(self) -> int:
        return self.pdo.tpdo_count

    @property
    def power_cycles(self) -> int:
        return self.faults.power_cycles

    @property
    def sdo_requests(self) -> int:
        return self.faults.sdo_requests

    @property
    def sdo_slow(self) -> int:
        return self.faults.sdo_slow

    @property
    def bottom_times(self) -> list[float]:
        """monotonic s at which the mechanism passed its bottom forwards (record_bottom)."""
        return self.mechanism.bottom_times

    def sync_summary(self) -> dict[str, object]:
        """SYNC timing as this drive saw it (its own clock)."""
        return {'syncs': self.sync_count, 'late': self.sync_late, 'missing': self.sync_missing,
                'period': self.node.value(0x1006, 0, 0) / 1e6, 'gaps': self.sync_gaps.summary(),
                'targets_missing': self.targets_missing,
                'following_error_faults': self.following_error_faults}

    @property
    def mechanism_angle(self) -> float:
        """rad, the mechanism's true angle from its bottom (0 = tip lowest), forward +."""
        with self._lock:
            return self.mechanism.angle(self.device.motor.position)

    def mechanism_angle_at(self, position: float) -> float:
        """The true mechanism angle from the bottom, wrapped to [-pi, pi), where the drive
        reports `position` (mechanism rad as the master counts them: 6064h increments over
        counts_per_motor_rev * gear_ratio, after polarity and homing)."""
        with self._lock:
            device = self.device
            user = position * self.spec.counts_per_motor_rev * self.spec.gear_ratio / TWO_PI
            counts = device.sign(0x80) * (user - device.homing.shift)
            return wrap_angle(self.mechanism.angle(counts))

    @property
    def home_switch(self) -> bool:
        """The bottom proximity switch is active."""
        with self._lock:
            return self.mechanism.switch_active(self.device.motor.position)
