"""What the command engine does about a real CAN bus's faults, each step, per running row
(doc/command.md, "Faults and their recovery"; the plain per-row state and counts are
`recovery.RowRecovery`): EMCYs counted and logged without flooding, a restarted drive
configured again and a silent one asked whether it restarted (worker threads), a drive its
watchdog stopped while the bus failed re-enabled once the bus is back, and each halt's episode
tracked until the row is back in step (the plants it cost).

Owns when the bus last failed and whether its return was said.
"""
from __future__ import annotations

import logging
import math
import threading
import time

from planter_ros.control import sync_status
from planter_ros.control.row_loop import RowStep
from planter_ros.drive.errors import DriveError

from . import recovery
from .recovery import communication_fault
from .state import EngineState, RowUnit

__all__ = ['RowWatch']


class RowWatch:
    """The rows' fault recovery (see the module doc)."""

    def __init__(self, state: EngineState) -> None:
        self.state = state
        self.log = state.log
        self._bus_trouble_at = -math.inf    # the last CAN send or receive error (monotonic s)
        self._bus_back_said = True

    def bus_trouble(self, now: float) -> bool:
        """Whether the bus failed (send or receive errors) within the last BUS_WINDOW s; says
        once in the log when it is back."""
        state = self.state
        receive_errors = state.drives.canbus.receive_errors
        stamps = [state.last_bus_error, receive_errors.last]
        stamps += [unit.last_send_error for unit in state.units]
        latest = max((stamp[0] for stamp in stamps if stamp is not None), default=-math.inf)
        if latest > self._bus_trouble_at:
            self._bus_trouble_at = latest
            self._bus_back_said = False
        quiet = now - self._bus_trouble_at
        if not self._bus_back_said and quiet >= recovery.BUS_QUIET:
            self._bus_back_said = True
            state.log(logging.WARNING, f'CAN bus {state.bus_id} back (no error for '
                                       f'{recovery.BUS_QUIET:g} s): {state.send_errors} send and '
                                       f'{receive_errors.count} receive error(s) since start')
        return quiet <= recovery.BUS_WINDOW

    def watch(self, unit: RowUnit, now: float) -> None:
        """Per running row, each step (lock held): EMCYs counted and logged without flooding;
        a restarted drive configured again (worker thread); a lost heartbeat asked about; a
        drive its watchdog stopped while the bus failed re-enabled once the bus is back."""
        rec, status, drive = unit.recovery, unit.measured, unit.bus_drive
        line = rec.emcy_line(now, drive.emcy_count, drive.last_emcy_code)
        if line:
            self.log(logging.WARNING, self.state.row_text(unit, line))
        if status.restarted:
            if (not rec.reconfiguring and not rec.probing and now >= rec.next_reconfigure
                    and not self.state.shut_down):      # one SDO user of the drive at a time
                rec.reconfiguring = True
                rec.worker = threading.Thread(target=self._reconfigure, args=(unit,),
                                              daemon=True, name=f'reconfigure-{unit.label}')
                rec.worker.start()
            return
        episode = rec.episode
        if episode is None:
            return
        if (status.fault_reason == 'drive heartbeat lost' and not rec.probing
                and now - episode.since >= recovery.PROBE_AFTER and now >= rec.next_probe):
            rec.probing = True
            rec.next_probe = now + recovery.PROBE_RETRY
            rec.worker = threading.Thread(target=self._probe, args=(unit,), daemon=True,
                                          name=f'probe-{unit.label}')
            rec.worker.start()
        cfg = self.state.drive_config
        if (episode.bus and episode.resets < recovery.AUTO_RESETS and not status.resetting
                and now >= rec.next_auto_reset
                and now - self._bus_trouble_at >= recovery.BUS_QUIET
                and status.heartbeat_age < cfg.drive_heartbeat_timeout
                and communication_fault(sync_status.halt_reason(
                    status, cfg.drive_heartbeat_timeout), status.error_code,
                    status.fault_reason)):
            episode.resets += 1
            rec.auto_resets += 1
            rec.next_auto_reset = now + cfg.reset_timeout + 0.2
            drive.request_fault_reset()
            self.log(logging.WARNING, self.state.row_text(
                unit, f'the CAN bus is back: re-enabling the drive its communication stopped '
                      f'({status.fault_reason}, error 0x{status.error_code:04X}; attempt '
                      f'{episode.resets} of {recovery.AUTO_RESETS})'))

    def _reconfigure(self, unit: RowUnit) -> None:
        """Worker thread: the drive restarted; configure and enable it again (its one
        start-up path), then the row loop resumes it."""
        rec, start = unit.recovery, time.monotonic()
        why = unit.status.restarted if unit.status is not None else ''
        try:
            unit.bus_drive.reconfigure()
        except DriveError as exc:
            with self.state.lock:
                rec.reconfiguring = False
                rec.next_reconfigure = time.monotonic() + recovery.RECONFIGURE_RETRY
                first, rec.reconfigure_error = not rec.reconfigure_error, str(exc)
            if first:
                self.log(logging.WARNING, self.state.row_text(
                    unit, f'configuring the restarted drive again failed ({exc}): trying '
                          f'again every {recovery.RECONFIGURE_RETRY:g} s'))
            return
        with self.state.lock:
            rec.reconfiguring = False
            rec.reconfigure_error = ''
            rec.restarts += 1
            rec.resumed = True
            unit.target = None                  # CSP: on from where the drive is
        self.log(logging.WARNING, self.state.row_text(
            unit, f'the drive restarted ({why}): configured again and enabled in '
                  f'{time.monotonic() - start:.2f} s ({self.state.mode_text()})'))

    def _probe(self, unit: RowUnit) -> None:
        """Worker thread: the drive's heartbeat is lost; if it answers and its heartbeat
        setting is gone, it restarted (its boot-up message was lost): `status().restarted`."""
        try:
            unit.bus_drive.probe_restart()
        except DriveError:
            pass                                 # still silent: asked again later
        finally:
            with self.state.lock:
                unit.recovery.probing = False

    def track(self, unit: RowUnit, row: RowStep, now: float, trouble: bool) -> None:
        """The row's halt episodes and the plants they cost (lock held)."""
        rec, law = unit.recovery, unit.law
        if row.halt is not None:
            if row.halt.kind != sync_status.NOT_ENABLED or rec.episode is not None:
                rec.halted(now, row.halt, law.phase_slips, trouble)
            return
        if rec.episode is None:
            return
        pitch = 2.0 * math.pi / law.plants_per_revolution
        in_step = (not law.section_on or law.stale(now) or law.spacing is None
                   or (law.anchored and abs(law.last_error) < recovery.BACK_IN_STEP * pitch))
        record = rec.running(now, in_step, law.phase_slips)
        if record is None:
            return
        restarted = 'the drive restarted; ' if record.restarted else ''
        back = 'back in step' if record.in_step else 'not back in step'
        level = logging.WARNING if record.plants_missed else logging.INFO
        self.log(level, self.state.row_text(
            unit, f'{back} {record.back_in_step_s:.2f} s after: {record.cause} '
                  f'({restarted}halted {record.halted_s:.2f} s): '
                  f'{record.plants_missed} plant(s) missed'))
