"""The command engine's control step: per running row its drive's status, the row loop's
command, and the frame that carries it (a velocity in profile velocity; in CSP the SYNC first,
then the position target for the next one); the master heartbeat when due. A ground-speed
sample in profile velocity sends every row's frames at once.

Owns the SYNC instants and the timing figures (between SYNCs, sample to frame); the recovery
it hands each step to is `watch.RowWatch`.
"""
from __future__ import annotations

from collections import deque
import logging
import time
from typing import TYPE_CHECKING

from planter_ros import interfaces
from planter_ros.control import sync_status
from planter_ros.control.loop_timing import PeriodStats
from planter_ros.control.row_loop import RowStep, cam_csp_target, csp_setpoint
from planter_ros.control.sync_status import Halt
from planter_ros.drive.errors import DriveError

from .lifecycle import Lifecycle
from .state import EngineState, RowUnit
from .watch import RowWatch

if TYPE_CHECKING:
    from planter_ros.drive.cia402 import DriveStatus

__all__ = ['ControlStep']


class ControlStep:
    """One step of every running row (see the module doc)."""

    def __init__(self, state: EngineState, lifecycle: Lifecycle, watch: RowWatch) -> None:
        self.state = state
        self.log = state.log
        self.lifecycle = lifecycle
        self.watch = watch
        self._syncs: deque[float] = deque(maxlen=4)     # when the last SYNCs were sent
        self.sync_intervals = PeriodStats()              # between SYNCs sent
        # profile velocity: from a sample's receive time (the shell's, same clock) to the last
        # row's frame sent for it (10 µs bins up to 0.1 s)
        self.sample_latency = PeriodStats(1e-5, 0.1)

    def sample(self, v: float, yaw_rate: float, now: float) -> None:
        """A ground-speed sample (m/s, rad/s) received at `now`: in profile velocity the rows'
        frames go at once; in CSP the targets go with the next SYNC."""
        with self.state.lock:
            self.state.machine.sample(v, yaw_rate, now)
            if not self.state.csp and any(unit.running for unit in self.state.units):
                self.step(now)
                self.sample_latency.add(time.monotonic() - now)

    def step(self, now: float) -> None:
        """One command per running row and the master heartbeat when due. With rows in CSP:
        first the SYNC (the drives apply the targets sent last period), then each row's
        target for the next SYNC: its last target advanced by the row loop's speed over one
        SYNC period (phase-locked through the law; a halted row restarts from where its
        drive is)."""
        state = self.state
        with state.lock:
            if not any(unit.running for unit in state.units):
                return
            self.lifecycle.take_over_sync()     # the loop's first step takes the SYNC over
            canbus = state.drives.canbus
            if state.sync_loop and (state.csp or now - canbus.last_sync
                                    >= 0.9 * state.loop.control_period):
                try:
                    sent = time.monotonic()
                    canbus.send_sync()
                    self._syncs.append(sent)        # the instant SYNC-triggered TPDOs measure
                    self.sync_intervals.event(sent)
                except DriveError as exc:
                    self._send_failed(now, exc, None)
            for unit in state.units:
                if unit.running:
                    status = unit.bus_drive.status()
                    if unit.csp:
                        status = sync_status.at_sync(status, self._syncs)
                    unit.status = unit.joint_status(status)
                    self.watch.watch(unit, now)
            step = state.row_loop.step([unit.status if unit.running else None
                                        for unit in state.units],
                                       [unit.running for unit in state.units], now)
            trouble = self.watch.bus_trouble(now)
            for unit, row in zip(state.units, step.rows):
                if not row.running:
                    continue
                if row.changed:
                    self._report_halt(unit, row.halt, unit.status)
                unit.halt = row.halt
                self.watch.track(unit, row, now, trouble)
                if unit.recovery.reconfiguring:
                    unit.command = 0.0
                    continue                    # its enable steps send their own frames
                if unit.recovery.resumed:       # frames again after a pause on purpose
                    unit.recovery.resumed = False
                    unit.period.restart()
                try:
                    if unit.csp:
                        self._send_target(unit, row, now)
                    else:
                        unit.bus_drive.send_velocity(row.command)
                except DriveError as exc:
                    self._send_failed(now, exc, unit)
                unit.period.event(time.monotonic())      # when the frame went
                unit.command = row.command
            if step.heartbeat:      # after the commands (they are what is waited for)
                try:
                    state.drives.send_heartbeat()
                except DriveError as exc:
                    self._send_failed(now, exc, None)

    def _send_target(self, unit: RowUnit, row: RowStep, now: float) -> None:
        """The row's position for the next SYNC: advanced by its speed over the time since the
        last target (a late step is made up: the angle stays on the distance travelled)."""
        period = self.state.drive_config.sync_period
        before = (unit.target, unit.target_time, unit.behind)
        try:
            self._next_target(unit, row, now, period)
        except DriveError:
            # not sent (a send error, bus-off): the drive still has the last target; the time
            # since is owed and made up over the next SYNCs, never in one jump
            unit.target, unit.target_time, unit.behind = before
            raise

    def _next_target(self, unit: RowUnit, row: RowStep, now: float, period: float) -> None:
        ahead = 0.0
        if row.halt is not None or unit.target is None:
            # (re)start from where the drive is, once its position is fresh (after a restart
            # the last one known may be from before it: the shaft coasted on since)
            status = unit.measured
            fresh = now - status.stamp <= 3.0 * period
            unit.target = status.position if row.halt is None and fresh else None
            unit.behind = 0.0
        else:
            # time owed since the last target; at most two periods' worth per SYNC, so a late
            # step is made up over the next SYNCs at up to twice the speed, never in one jump
            owed = max(now - unit.target_time, 0.0) + unit.behind
            step = min(owed, 2.0 * period)
            unit.behind = min(owed - step, 0.5)
            unit.target += row.command * step
            on_cam = None if self.state.stopping else cam_csp_target(
                unit.law, unit.target, now + period, step)
            if on_cam is not None:          # a cam row's target is its angle at the next SYNC
                unit.target, ahead = on_cam, period
        unit.target_time = now
        if unit.target is None:
            unit.bus_drive.send_hold()
        else:
            unit.bus_drive.send_position(csp_setpoint(unit.target, row.command, period, ahead)
                                         - unit.angle_shift)

    def _report_halt(self, unit: RowUnit, halt: Halt | None, status: DriveStatus | None) -> None:
        row = '' if self.state.implicit else f'row {unit.label}: '
        if halt is not None and halt.kind != sync_status.NOT_ENABLED:
            unit.faults += 1
            unit.last_fault = halt.text
        if halt is None:
            self.log(logging.INFO, f'{row}drive back in operation: resuming')
        elif halt.kind == sync_status.FAULTED:
            service = interfaces.RESET_FAULT.for_row(unit.row.name)
            state = status.state if status is not None else 'unknown'
            self.log(logging.ERROR, f'{row}{halt.text} (state {state}): commanding 0; '
                                    f'call the {service} service once the cause is cleared')
        else:
            self.log(logging.WARNING, f'{row}{halt.text}: commanding 0')

    def _send_failed(self, now: float, exc: Exception, unit: RowUnit | None) -> None:
        last = self.state.last_bus_error if unit is None else unit.last_send_error
        first = last is None or now - last[0] > sync_status.SEND_ERROR_HOLD
        if unit is None:
            self.state.bus_send_errors += 1
            self.state.last_bus_error = (now, str(exc))
        else:
            unit.send_errors += 1
            unit.last_send_error = (now, str(exc))
        if first:
            self.log(logging.ERROR, f'CAN send failed: {exc}')
