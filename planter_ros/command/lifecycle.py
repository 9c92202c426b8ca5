"""The command engine's life cycle: enable every row's drive at start-up (holding the bus's
start-up SYNC until the loop's own), the ramp to zero before a stop, and the shutdown; and the
CAN bus load a configuration makes (refused above the limit before anything is enabled).

Owns the start-up SYNC; sets the run's flags in `state.EngineState` (shut down, stopping, CSP,
SYNC from the loop) that the other parts read.
"""
from __future__ import annotations

from collections.abc import Sequence
from contextlib import AbstractContextManager
import logging
from typing import Any

from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.drive.bus_load import BusLoad, BusTiming, bus_load, check_bus_load
from planter_ros.drive.config import DriveConfig
from planter_ros.drive.errors import DriveError
from planter_ros.rows import Row

from .state import EngineState

__all__ = ['Lifecycle', 'checked_bus_load', 'machine_bus_load']


class Lifecycle:
    """Enable, stop ramp and shutdown of the engine's rows (see the module doc)."""

    def __init__(self, state: EngineState) -> None:
        self.state = state
        self.log = state.log
        # the bus's start-up SYNC, held until the loop's
        self._start_up_sync: AbstractContextManager[Any] | None = None

    def enable(self) -> None:
        """BLOCKING: configure and enable every row's drive at once (start-up only). A row whose
        drive does not answer is reported and left out; raises DriveError when no row runs."""
        # SYNC from before the drives' NMT start until the loop's first step sends its own
        # (drive.bus: a strict CiA 301 drive acts and reports on SYNC only)
        self._start_up_sync = self.state.drives.canbus.start_up_sync()
        self._start_up_sync.__enter__()
        try:
            failures = self.state.drives.enable(keep_alive=self.state.loop.control_period)
        except BaseException:
            self.release_start_up_sync()
            raise
        with_drive = [unit for unit in self.state.units if unit.drive is not None]
        if self.state.implicit and failures:
            raise next(iter(failures.values()))
        if with_drive and all(unit.row.name in failures for unit in with_drive):
            raise DriveError('no row\'s drive answered: '
                             + '; '.join(f'{u.label}: {failures[u.row.name]}'
                                         for u in with_drive))
        with self.state.lock:
            for unit in with_drive:
                if unit.row.name in failures:
                    unit.left_out = str(failures[unit.row.name])
                    self.log(logging.ERROR, f'row {unit.label} left out: {unit.left_out}')
                else:
                    unit.running = True
                    unit.halt = None
                    self.state.row_loop.enabled(unit.row.index)
            self.state.csp = any(unit.csp for unit in self.state.units if unit.running)
            # the loop produces SYNC while a running drive needs it (CSP, or feedback on SYNC)
            self.state.sync_loop = any(unit.bus_drive.plan is not None
                                       and unit.bus_drive.plan.needs_sync
                                       for unit in self.state.units if unit.running)
            self.state.bus_load = machine_bus_load(self.state.drive_config, self.state.loop,
                                                   len(with_drive), self.state.csp)
        running = [unit.label for unit in self.state.units if unit.running]
        mode = self.state.mode_text()
        if self.state.implicit:
            self.log(logging.INFO, f'drive {self.state.hardware_id} enabled ({mode})')
        else:
            self.log(logging.INFO, f'drives enabled ({mode}): rows '
                                   f'{", ".join(running)} on {self.state.bus_id}')
        self.log(logging.INFO, f'{len(with_drive)} row(s) on {self.state.bus_id}: CAN bus load '
                               f'{100 * self.state.bus_load.load:.1f} % of '
                               f'{self.state.drive_config.can_bitrate} bit/s (worst case)')

    def shutdown(self) -> None:
        """BLOCKING, idempotent: every row at once: 0x60FF = 0, disable, NMT pre-operational."""
        with self.state.lock:
            if self.state.shut_down:
                return
            self.state.shut_down = True
            was_running = [unit for unit in self.state.units if unit.running]
            for unit in self.state.units:
                unit.running = False
            workers = [unit.recovery.worker for unit in self.state.units
                       if unit.recovery.worker is not None]
        for worker in workers:          # a drive being configured again: let it finish first
            worker.join(timeout=10.0)
        self.state.drives.canbus.loop_sync(False)     # the drives' shutdown waits on start-up SYNC
        self.release_start_up_sync()
        try:
            self.state.drives.shutdown()
            if was_running:
                self.log(logging.INFO, 'drive shut down (target 0, disabled, pre-operational)'
                         if self.state.implicit else
                         f'drives of rows {", ".join(u.label for u in was_running)} shut down '
                         '(target 0, disabled, pre-operational)')
        except DriveError as exc:
            self.log(logging.ERROR, f'drive shutdown: {exc}')

    def release_start_up_sync(self) -> None:
        hold, self._start_up_sync = self._start_up_sync, None
        if hold is not None:
            hold.__exit__(None, None, None)

    def stop_ramp(self, now: float) -> None:
        """From now on every row's command ramps to 0 at its acceleration limit, whatever the
        ground speed (the shell is gone); `ramped_down` says when all are at 0."""
        with self.state.lock:
            self.state.stopping = True
            self.state.row_loop.stop(now)

    @property
    def ramped_down(self) -> bool:
        with self.state.lock:
            return all(unit.command == 0.0 for unit in self.state.units if unit.running)

    def take_over_sync(self) -> None:
        """The loop's first step: it sends SYNC from now on (if the drives need it); the
        start-up SYNC stops (lock held)."""
        if self._start_up_sync is not None:
            self.state.drives.canbus.loop_sync(self.state.sync_loop)
            self.release_start_up_sync()


def machine_bus_load(cfg: DriveConfig, loop: SyncLoopConfig, rows: int, csp: bool) -> BusLoad:
    """The worst-case CAN bus load of `rows` drives in profile velocity or CSP."""
    return bus_load(rows, cfg.can_bitrate, _timing(cfg, loop), csp)


def _timing(cfg: DriveConfig, loop: SyncLoopConfig) -> BusTiming:
    return BusTiming.of(cfg, loop.control_period, loop.ground_speed_rate)


def checked_bus_load(cfg: DriveConfig, loop: SyncLoopConfig, rows: Sequence[Row]) -> BusLoad:
    """The load a configuration may make before its drives say which mode they run: CSP's
    when `operation_mode` allows CSP and it is the larger; refused above the limit with the
    knobs that fix it (DriveConfigError)."""
    loads = [machine_bus_load(cfg, loop, len(rows), False)]
    if cfg.operation_mode != 'velocity':
        loads.append(machine_bus_load(cfg, loop, len(rows), True))
    worst = max(loads, key=lambda load: load.load)
    check_bus_load(worst, [row.label for row in rows], _timing(cfg, loop))
    return worst
