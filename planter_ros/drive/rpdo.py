"""The master's command frames to one drive: its RPDOs as the start-up plan mapped them (one,
or the controlword and the target in two where the drive's RPDO takes one entry), packed
straight from the layout (16-bit controlword, 32-bit target) rather than through canopen's
per-entry encoding, which cost several times the send in the loop's hot path.

The target is a velocity (counts/s, profile velocity) or a position (counts, CSP: the drive
takes it at the next SYNC). Every frame's controlword comes from the supervisor (a faulted
drive is held: velocity 0, or in CSP the position where it is). NON-BLOCKING: one frame per
RPDO at most, never an SDO."""
from __future__ import annotations

import math
import struct
import threading
import time
from typing import TYPE_CHECKING

from . import objects as od
from .errors import DriveError, NotConnectedError, bus_error
from .states import CYCLIC_SYNC_POSITION

if TYPE_CHECKING:
    import canopen

    from .config import DriveConfig
    from .feedback import Feedback
    from .plan import PdoPlan
    from .supervision import Supervisor

__all__ = ['Commander', 'wrap_i32']

_INT32 = (-2**31, 2**31 - 1)


def wrap_i32(value: int) -> int:
    return (value + 2**31) % 2**32 - 2**31


class Commander:
    """The RPDO frames of one drive (module doc)."""

    def __init__(self, config: DriveConfig, feedback: Feedback, supervisor: Supervisor) -> None:
        self.config = config
        self.feedback = feedback
        self.supervisor = supervisor
        self.mode = 0                              # 3 profile velocity, 8 CSP (at enable)
        self._network: canopen.Network | None = None
        self._frames: tuple[tuple[int, struct.Struct, tuple[int, ...]], ...] = ()
        self._tx_lock = threading.Lock()
        self.target_counts: int | None = None      # CSP: the last target position sent (raw)
        self.commanded = 0.0                       # mechanism rad/s in the last frame
        self.commanded_position = math.nan         # CSP: mechanism rad in the last frame

    @property
    def ready(self) -> bool:
        return bool(self._frames)

    def configure(self, network: canopen.Network, mode: int,
                  rpdos: tuple[PdoPlan, ...]) -> None:
        """The frames of the plan's RPDOs (each entry: 0 the controlword, 1 the target)."""
        frames = []
        for pdo in rpdos:
            slots = tuple(0 if obj is od.CONTROLWORD else 1 for obj in pdo.entries)
            layout = struct.Struct('<' + ''.join(obj.fmt for obj in pdo.entries))
            frames.append((pdo.cob_id(self.config.drive_node_id), layout, slots))
        # the target before the controlword (an asynchronous RPDO acts at once)
        frames.sort(key=lambda frame: 0 in frame[2])
        with self._tx_lock:
            self._network, self.mode, self._frames = network, mode, tuple(frames)

    def close(self) -> None:
        with self._tx_lock:
            self._network, self._frames = None, ()

    def counts_per_s(self, speed: float) -> int:
        counts = round(speed / self.feedback.rad_per_count)
        if not _INT32[0] <= counts <= _INT32[1]:
            limit = _INT32[1] * self.feedback.rad_per_count
            raise DriveError(f'speed {speed!r} rad/s is out of range (allowed: |speed| <= '
                             f'{limit:.6g} rad/s)')
        return counts

    def hold_counts(self, enabled: bool) -> int:
        """The target that holds the drive: velocity 0, or in CSP the last target sent (the
        position where it was told to be; the actual one at enable)."""
        if self.mode != CYCLIC_SYNC_POSITION:
            return 0
        fb = self.feedback
        with fb.lock:
            if not enabled and fb.fresh_position(3 * self.config.sync_period):
                # enabling, with fresh feedback: where the shaft is now (after a restart it
                # may still coast; the target written when configuring is behind it)
                return wrap_i32(fb.position_counts)
            if self.target_counts is not None:
                return self.target_counts
            return wrap_i32(fb.position_counts)

    def transmit(self, controlword: int, counts: int | None = None) -> None:
        """The RPDO frames: controlword + target velocity (counts/s) or target position
        (counts, CSP); None = the holding target. BusError on a send failure."""
        if counts is None:
            counts = self.hold_counts(self.supervisor.enabled)
        values = (controlword, counts)
        with self._tx_lock:
            network = self._network
            if network is None or not self._frames:
                raise NotConnectedError(f'drive node {self.config.drive_node_id}: not '
                                        'connected (call connect_and_enable first)')
            try:
                for cob_id, layout, slots in self._frames:
                    network.send_message(cob_id, layout.pack(*(values[i] for i in slots)))
            except Exception as exc:        # (the text is made only on a failure: hot path)
                cfg = self.config
                raise bus_error(exc, f'drive node {cfg.drive_node_id}: CAN send of RPDO '
                                f'(controlword 0x{controlword:04X}, target {counts}) failed on '
                                f'{cfg.can_interface}:{cfg.can_channel}',
                                cfg.drive_node_id) from None
            self.supervisor.last_controlword = controlword

    def send_velocity(self, speed: float) -> None:
        """Profile velocity: controlword + 60FFh for `speed` (mechanism rad/s)."""
        if self.mode == CYCLIC_SYNC_POSITION:
            raise DriveError(f'drive node {self.config.drive_node_id}: runs cyclic synchronous '
                             'position: send_position(), not send_velocity()')
        if not math.isfinite(speed):
            raise DriveError(f'speed {speed!r} rad/s is not finite (allowed: a finite number)')
        counts = self.counts_per_s(speed)
        with self.feedback.lock:
            controlword, commanding = self.supervisor.controlword(time.monotonic())
            counts = counts if commanding else 0
            self.commanded = counts * self.feedback.rad_per_count
        self.transmit(controlword, counts)

    def send_position(self, angle: float) -> None:
        """CSP: controlword + 607Ah for mechanism angle `angle` (rad, unwrapped), taken by the
        drive at the next SYNC; a held drive is held where it is."""
        if self.mode != CYCLIC_SYNC_POSITION:
            raise DriveError(f'drive node {self.config.drive_node_id}: runs profile velocity: '
                             'send_velocity(), not send_position()')
        if not math.isfinite(angle):
            raise DriveError(f'angle {angle!r} rad is not finite (allowed: a finite number)')
        fb = self.feedback
        with fb.lock:
            controlword, commanding = self.supervisor.controlword(time.monotonic())
            if commanding:
                counts = wrap_i32(round(angle / fb.rad_per_count))
                self.commanded_position = angle
            else:                                  # hold where the drive is
                counts = wrap_i32(fb.position_counts)
                self.commanded_position = fb.position
            self.commanded = 0.0
            self.target_counts = counts
        self.transmit(controlword, counts)

    def send_hold(self) -> None:
        """Keep the drive fed without moving it: velocity 0, or in CSP the last target."""
        if self.mode == CYCLIC_SYNC_POSITION:
            with self.feedback.lock:
                controlword, _ = self.supervisor.controlword(time.monotonic())
            self.transmit(controlword, None)
        else:
            self.send_velocity(0.0)
