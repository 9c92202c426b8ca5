"""The command path without ROS: the CAN bus, the CiA 402 masters, the heartbeat, the row loop,
section control, fault resets and the sync node's diagnostics, in one object.

The command process (`planter_ros.command.process`) runs it on its own, fed over a local
channel; `sync_node` runs the same object in its own process when given a bus object (tests).
Either way nothing here imports rclpy: inputs are plain values, outputs are drive frames (sent
here), `diagnostics.Report`s and log lines through the `log(level, text)` callable.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
import logging
import math
import threading
import time
from typing import TYPE_CHECKING, Any

import can

from planter_ros import diagnostics, interfaces
from planter_ros.control import sync_status
from planter_ros.control.cam_law import plan_for_design
from planter_ros.control.loop_timing import PeriodStats, SyncLoopConfig
from planter_ros.control.machine_law import Machine
from planter_ros.control.phase_lock import PhaseLock, planting_angles
from planter_ros.control.row_loop import RowLoop, RowStep, cam_csp_target, csp_setpoint
from planter_ros.control.sync_status import Halt
from planter_ros.design import Design
from planter_ros.drive.bus_load import BusLoad, bus_load, check_bus_load
from planter_ros.drive.config import DriveConfig
from planter_ros.drive.drive_set import DriveSet
from planter_ros.drive.errors import DriveError
from planter_ros.drive.setup import DriveSetup
from planter_ros.drive.states import FAULT
from planter_ros.rows import IMPLICIT, Row

from . import recovery
from .recovery import communication_fault
from .reports import CommandReport, Reply, RowReport, RowSnapshot, Snapshot
from .state import Feedback, RowUnit

if TYPE_CHECKING:
    from planter_ros.drive.cia402 import Cia402Drive, DriveStatus

__all__ = ['CommandEngine', 'Log', 'bottom_angle', 'checked_bus_load', 'machine_bus_load']

Log = Callable[[int, str], None]        # (logging level, one line)


def _print_log(level: int, text: str) -> None:
    logging.getLogger('planter_ros.command').log(level, '%s', text)


class CommandEngine:
    """The rows, their drives and the row loop (see the module doc). Thread-safe: every public
    method takes the engine's lock."""

    def __init__(self, drive_config: DriveConfig, loop_config: SyncLoopConfig,
                 rows: Sequence[Row], law_values: Sequence[Any], bus: can.BusABC | None = None,
                 log: Log | None = None, setups: dict[str, DriveSetup] | None = None) -> None:
        """`setups`: row name -> what the machine file says of its drive (checked, applied
        at enable; its phase offset places the joint angle), none without a machine file."""
        self.drive_config = cfg = drive_config
        self.loop = loop_config
        self.log = log or _print_log
        self.rows = list(rows)
        self.implicit = len(self.rows) == 1 and self.rows[0].name == IMPLICIT
        self.machine = Machine([row.lateral_offset for row in self.rows], *law_values)
        self.row_loop = RowLoop(self.machine, cfg.heartbeat_period, cfg.drive_heartbeat_timeout)
        enabled = [row for row in self.rows if row.enabled]
        self.bus_load: BusLoad = checked_bus_load(cfg, loop_config, enabled)
        self.drives = DriveSet(cfg, {row.name: row.drive_node_id for row in enabled}, bus=bus,
                               setups=setups)
        self.bus_id = f'{cfg.can_interface}:{cfg.can_channel}'
        self.units = [RowUnit(row, self.machine.laws[row.index], self.drives.drives.get(row.name),
                              f'{self.bus_id} node {row.drive_node_id}')
                      for row in self.rows]
        self.hardware_id = self.units[0].hardware_id
        self._lock = threading.RLock()
        self._shut_down = False
        self.design_key: tuple | None = None
        self._planning: str | None = None   # the design whose cam is being planned
        self.mechanism: str | None = None
        self._bus_send_errors = 0
        self._last_bus_error: tuple[float, str] | None = None
        self.stopping = False               # ramping to zero before a shutdown
        self.csp = False                    # some row runs CSP: SYNC every step, targets
        self.sync_loop = False              # the loop sends SYNC (CSP, or feedback on SYNC)
        self._start_up_sync = None          # the bus's start-up SYNC, held until the loop's
        self._syncs: deque[float] = deque(maxlen=4)     # when the last SYNCs were sent
        self.sync_intervals = PeriodStats()              # between SYNCs sent
        # profile velocity: from a sample's receive time (the shell's, same clock) to the last
        # row's frame sent for it (10 µs bins up to 0.1 s)
        self.sample_latency = PeriodStats(1e-5, 0.1)
        self._bus_trouble_at = -math.inf    # the last CAN send or receive error (monotonic s)
        self._bus_back_said = True

    # ---------------------------------------------------------------- the first row
    @property
    def law(self) -> PhaseLock:
        return self.units[0].law

    @property
    def send_errors(self) -> int:
        return self._bus_send_errors + sum(unit.send_errors for unit in self.units)

    @property
    def running(self) -> int:
        """Rows whose drives run."""
        return sum(unit.running for unit in self.units)

    @property
    def shut_down(self) -> bool:
        return self._shut_down

    def unit(self, name: str) -> RowUnit:
        return next(unit for unit in self.units if unit.row.name == name)

    # ---------------------------------------------------------------- life cycle
    def enable(self) -> None:
        """BLOCKING: configure and enable every row's drive at once (start-up only). A row whose
        drive does not answer is reported and left out; raises DriveError when no row runs."""
        # SYNC from before the drives' NMT start until the loop's first step sends its own
        # (drive.bus: a strict CiA 301 drive acts and reports on SYNC only)
        self._start_up_sync = self.drives.canbus.start_up_sync()
        self._start_up_sync.__enter__()
        try:
            failures = self.drives.enable(keep_alive=self.loop.control_period)
        except BaseException:
            self._release_start_up_sync()
            raise
        with_drive = [unit for unit in self.units if unit.drive is not None]
        if self.implicit and failures:
            raise next(iter(failures.values()))
        if with_drive and all(unit.row.name in failures for unit in with_drive):
            raise DriveError('no row\'s drive answered: '
                             + '; '.join(f'{u.label}: {failures[u.row.name]}'
                                         for u in with_drive))
        with self._lock:
            for unit in with_drive:
                if unit.row.name in failures:
                    unit.left_out = str(failures[unit.row.name])
                    self.log(logging.ERROR, f'row {unit.label} left out: {unit.left_out}')
                else:
                    unit.running = True
                    unit.halt = None
                    self.row_loop.enabled(unit.row.index)
            self.csp = any(unit.csp for unit in self.units if unit.running)
            # the loop produces SYNC while a running drive needs it (CSP, or feedback on SYNC)
            self.sync_loop = any(unit.drive.plan is not None and unit.drive.plan.needs_sync
                                 for unit in self.units if unit.running)
            self.bus_load = machine_bus_load(self.drive_config, self.loop,
                                             len(with_drive), self.csp)
        running = [unit.label for unit in self.units if unit.running]
        mode = self.mode_text()
        if self.implicit:
            self.log(logging.INFO, f'drive {self.hardware_id} enabled ({mode})')
        else:
            self.log(logging.INFO, f'drives enabled ({mode}): rows '
                                   f'{", ".join(running)} on {self.bus_id}')
        self.log(logging.INFO, f'{len(with_drive)} row(s) on {self.bus_id}: CAN bus load '
                               f'{100 * self.bus_load.load:.1f} % of '
                               f'{self.drive_config.can_bitrate} bit/s (worst case)')

    def shutdown(self) -> None:
        """BLOCKING, idempotent: every row at once: 0x60FF = 0, disable, NMT pre-operational."""
        with self._lock:
            if self._shut_down:
                return
            self._shut_down = True
            was_running = [unit for unit in self.units if unit.running]
            for unit in self.units:
                unit.running = False
            workers = [unit.recovery.worker for unit in self.units
                       if unit.recovery.worker is not None]
        for worker in workers:          # a drive being configured again: let it finish first
            worker.join(timeout=10.0)
        self.drives.canbus.loop_sync(False)     # the drives' shutdown waits on start-up SYNC
        self._release_start_up_sync()
        try:
            self.drives.shutdown()
            if was_running:
                self.log(logging.INFO, 'drive shut down (target 0, disabled, pre-operational)'
                         if self.implicit else
                         f'drives of rows {", ".join(u.label for u in was_running)} shut down '
                         '(target 0, disabled, pre-operational)')
        except DriveError as exc:
            self.log(logging.ERROR, f'drive shutdown: {exc}')

    def _release_start_up_sync(self) -> None:
        hold, self._start_up_sync = self._start_up_sync, None
        if hold is not None:
            hold.__exit__(None, None, None)

    def stop_ramp(self, now: float) -> None:
        """From now on every row's command ramps to 0 at its acceleration limit, whatever the
        ground speed (the shell is gone); `ramped_down` says when all are at 0."""
        with self._lock:
            self.stopping = True
            self.row_loop.stop(now)

    @property
    def ramped_down(self) -> bool:
        with self._lock:
            return all(unit.command == 0.0 for unit in self.units if unit.running)

    # ---------------------------------------------------------------- inputs
    @property
    def period(self) -> float:
        """The loop's period: the SYNC period when a row runs CSP, else the control period."""
        return self.drive_config.sync_period if self.csp else self.loop.control_period

    def sample(self, v: float, yaw_rate: float, now: float) -> None:
        """A ground-speed sample (m/s, rad/s) received at `now`: in profile velocity the rows'
        frames go at once; in CSP the targets go with the next SYNC."""
        with self._lock:
            self.machine.sample(v, yaw_rate, now)
            if not self.csp and any(unit.running for unit in self.units):
                self.step(now)
                self.sample_latency.add(time.monotonic() - now)

    def set_design(self, design: Design, text: str, now: float,
                   planned: tuple[Any, str] | None = None,
                   arrived: float | None = None) -> bool:
        """A design for every row (at its next planting instant); False when it is the one in
        force already. Where the mechanism plants is found in a worker thread. With
        `speed_profile: cam` the cam is planned first, in a worker thread too (it takes up to
        tens of ms: not on the SYNC loop), and the design applies once it is; `planned`:
        (profile or None, why not) when the caller planned it (the command process's shell),
        `arrived` when the design reached it (monotonic s)."""
        if planned is not None:
            with self._lock:
                if self.design_key is not None and text == self.design_key[2]:
                    return False
                self._planning = None
            return self._apply_design(design, text, now, *planned, since=arrived)
        with self._lock:
            if self.design_key is not None and text == self.design_key[2]:
                return False
            if self.law.config.speed_profile == 'cam':
                if self._planning == text:
                    return False
                self._planning = text
                threading.Thread(target=self._plan_cam, args=(design, text, now), daemon=True,
                                 name='cam-plan').start()
                return True
        return self._apply_design(design, text, now, None)

    def _plan_cam(self, design: Design, text: str, now: float) -> None:
        """Plan the design's cam and the change to it (worker thread), then apply the design
        with it; a plan or change over the drive's limits is refused (logged, not applied)."""
        from planter_ros.cam import CamError
        previous = next((unit.law.cam for unit in self.units if unit.law.cam is not None),
                        None)
        try:
            profile, why = plan_for_design(design, self.law.config.cam_rule, previous)
            with self._lock:
                if self._planning != text:       # a newer design arrived meanwhile
                    return
                self._planning = None
                self._apply_design(design, text, time.monotonic(), profile, why, since=now)
        except CamError as exc:
            with self._lock:
                if self._planning == text:
                    self._planning = None
            self.log(logging.ERROR, f'design refused, the rows keep theirs: {exc}')

    def _apply_design(self, design: Design, text: str, now: float, cam: Any,
                      why: str = '', since: float | None = None) -> bool:
        with self._lock:
            self._place_bottom(bottom_angle(design))
            spacing, n = design.plant_spacing, design.plants_per_revolution
            joints = [unit.row.joint(design.mechanism) for unit in self.units]
            cams = None
            if self.law.config.speed_profile == 'cam':
                cams = []
                for unit in self.units:
                    fallback = why
                    if not fallback and unit.drive is not None and not unit.csp:
                        fallback = ('the drive runs profile velocity (no CSP): the cam falls '
                                    'back to the mean speed (constant profile)')
                    cams.append(None if fallback else cam)
                    if fallback and fallback != unit.law.cam_fallback:
                        self.log(logging.WARNING, fallback if self.implicit
                                 else f'row {unit.label}: {fallback}')
                    unit.law.cam_fallback = fallback
            self.machine.set_design(spacing, n, now, cams=cams, since=since)
            key = (spacing, n, text)
            self.design_key = key
            self.mechanism = design.mechanism
            for unit, joint in zip(self.units, joints):
                unit.joint = joint
        threading.Thread(target=self._find_planting_angles, args=(design, key), daemon=True,
                         name='planting-angles').start()
        return True

    def _place_bottom(self, bottom: float) -> None:
        """Rows with a phase offset (a machine file): the joint angle = the drive's - the
        phase offset + the design's bottom angle `bottom` (where its tip is lowest), so the law
        and the monitor plant where the design plants. Every angle the row holds follows a
        change (lock held; before the design anchors the grid)."""
        for unit in self.units:
            if unit.phase_offset is None:
                continue
            shift = bottom - unit.phase_offset
            delta = shift - unit.angle_shift
            if delta == 0.0:
                continue
            unit.angle_shift = shift
            unit.law.shift_angle(delta)
            if unit.target is not None:
                unit.target += delta
            if unit.status is not None:
                unit.status = self._shifted(unit, unit.status)

    @staticmethod
    def _shifted(unit: RowUnit, status: DriveStatus) -> DriveStatus:
        """The drive's status with the row's joint angle (see RowUnit.angle_shift)."""
        if unit.angle_shift == 0.0 and unit.phase_offset is None:
            return status
        return replace(status, position=status.position + unit.angle_shift,
                       commanded_position=status.commanded_position + unit.angle_shift)

    def _find_planting_angles(self, design: Design, key: tuple) -> None:
        planting = planting_angles(design)
        with self._lock:
            if key == self.design_key:
                self.machine.set_planting(planting)

    def configure(self, law_values: Sequence[Any]) -> None:
        with self._lock:
            self.machine.configure(*law_values)

    def reset_fault(self, name: str) -> Reply:
        unit = self.unit(name)
        with self._lock:
            if not unit.running:
                return Reply(False, f'row {unit.label} does not run ({self.idle_reason(unit)})')
            status = unit.drive.status()
            if not status.fault and status.state != FAULT:
                return Reply(False, f'no drive fault to reset (state {status.state})')
            unit.drive.request_fault_reset()
            message = (f'fault reset requested (error 0x{status.error_code:04X}); the drive '
                       're-enables if the cause is gone')
        self.log(logging.WARNING, message if self.implicit else f'row {unit.label}: {message}')
        return Reply(True, message)

    def section(self, name: str, on: bool, now: float) -> Reply:
        """Switch row `name`'s section (`changed`: it was not so already)."""
        unit = self.unit(name)
        with self._lock:
            if unit.drive is None:
                return Reply(False, f'row {unit.label} is disabled in the scene: it never plants')
            was = unit.law.section_on
            unit.law.switch(on, now)
            if was == on:
                message = f'row {unit.label} is already {"on" if on else "off"}'
            elif on:
                message = f'row {unit.label} on: a new grid starts here'
            else:
                stop = unit.law.stop_angle
                message = (f'row {unit.label} off: coming to rest'
                           + (f' at {stop:.3f} rad' if stop is not None else ''))
        self.log(logging.INFO, message)
        return Reply(True, message, was != on)

    # ---------------------------------------------------------------- the control step
    def step(self, now: float) -> None:
        """One command per running row and the master heartbeat when due. With rows in CSP:
        first the SYNC (the drives apply the targets sent last period), then each row's
        target for the next SYNC: its last target advanced by the row loop's speed over one
        SYNC period (phase-locked through the law; a halted row restarts from where its
        drive is)."""
        with self._lock:
            if not any(unit.running for unit in self.units):
                return
            if self._start_up_sync is not None:     # the loop takes the SYNC over
                self.drives.canbus.loop_sync(self.sync_loop)
                self._release_start_up_sync()
            if self.sync_loop and (self.csp or now - self.drives.canbus.last_sync
                                   >= 0.9 * self.loop.control_period):
                try:
                    sent = time.monotonic()
                    self.drives.canbus.send_sync()
                    self._syncs.append(sent)        # the instant SYNC-triggered TPDOs measure
                    self.sync_intervals.event(sent)
                except DriveError as exc:
                    self._send_failed(now, exc, None)
            for unit in self.units:
                if unit.running:
                    status = unit.drive.status()
                    if unit.csp:
                        status = sync_status.at_sync(status, self._syncs)
                    unit.status = self._shifted(unit, status)
                    self._watch(unit, now)
            step = self.row_loop.step([unit.status if unit.running else None
                                       for unit in self.units],
                                      [unit.running for unit in self.units], now)
            trouble = self._bus_trouble(now)
            for unit, row in zip(self.units, step.rows):
                if not row.running:
                    continue
                if row.changed:
                    self._report_halt(unit, row.halt, unit.status)
                unit.halt = row.halt
                self._track(unit, row, now, trouble)
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
                        unit.drive.send_velocity(row.command)
                except DriveError as exc:
                    self._send_failed(now, exc, unit)
                unit.period.event(time.monotonic())      # when the frame went
                unit.command = row.command
            if step.heartbeat:      # after the commands (they are what is waited for)
                try:
                    self.drives.send_heartbeat()
                except DriveError as exc:
                    self._send_failed(now, exc, None)

    # ---------------------------------------------------------------- recovery
    def _row_text(self, unit: RowUnit, text: str) -> str:
        return text if self.implicit else f'row {unit.label}: {text}'

    def _bus_trouble(self, now: float) -> bool:
        """Whether the bus failed (send or receive errors) within the last BUS_WINDOW s; says
        once in the log when it is back."""
        stamps = [self._last_bus_error, self.drives.canbus.receive_errors.last]
        stamps += [unit.last_send_error for unit in self.units]
        latest = max((stamp[0] for stamp in stamps if stamp is not None), default=-math.inf)
        if latest > self._bus_trouble_at:
            self._bus_trouble_at = latest
            self._bus_back_said = False
        quiet = now - self._bus_trouble_at
        if not self._bus_back_said and quiet >= recovery.BUS_QUIET:
            self._bus_back_said = True
            self.log(logging.WARNING, f'CAN bus {self.bus_id} back (no error for '
                                      f'{recovery.BUS_QUIET:g} s): {self.send_errors} send and '
                                      f'{self.drives.canbus.receive_errors.count} receive '
                                      'error(s) since start')
        return quiet <= recovery.BUS_WINDOW

    def _watch(self, unit: RowUnit, now: float) -> None:
        """Per running row, each step (lock held): EMCYs counted and logged without flooding;
        a restarted drive configured again (worker thread); a lost heartbeat asked about; a
        drive its watchdog stopped while the bus failed re-enabled once the bus is back."""
        rec, status, drive = unit.recovery, unit.status, unit.drive
        line = rec.emcy_line(now, drive.emcy_count, drive.last_emcy_code)
        if line:
            self.log(logging.WARNING, self._row_text(unit, line))
        if status.restarted:
            if (not rec.reconfiguring and not rec.probing and now >= rec.next_reconfigure
                    and not self._shut_down):          # one SDO user of the drive at a time
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
        cfg = self.drive_config
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
            self.log(logging.WARNING, self._row_text(
                unit, f'the CAN bus is back: re-enabling the drive its communication stopped '
                      f'({status.fault_reason}, error 0x{status.error_code:04X}; attempt '
                      f'{episode.resets} of {recovery.AUTO_RESETS})'))

    def _reconfigure(self, unit: RowUnit) -> None:
        """Worker thread: the drive restarted; configure and enable it again (its one
        start-up path), then the row loop resumes it."""
        rec, start = unit.recovery, time.monotonic()
        why = unit.status.restarted if unit.status is not None else ''
        try:
            unit.drive.reconfigure()
        except DriveError as exc:
            with self._lock:
                rec.reconfiguring = False
                rec.next_reconfigure = time.monotonic() + recovery.RECONFIGURE_RETRY
                first, rec.reconfigure_error = not rec.reconfigure_error, str(exc)
            if first:
                self.log(logging.WARNING, self._row_text(
                    unit, f'configuring the restarted drive again failed ({exc}): trying '
                          f'again every {recovery.RECONFIGURE_RETRY:g} s'))
            return
        with self._lock:
            rec.reconfiguring = False
            rec.reconfigure_error = ''
            rec.restarts += 1
            rec.resumed = True
            unit.target = None                  # CSP: on from where the drive is
        self.log(logging.WARNING, self._row_text(
            unit, f'the drive restarted ({why}): configured again and enabled in '
                  f'{time.monotonic() - start:.2f} s ({self.mode_text()})'))

    def _probe(self, unit: RowUnit) -> None:
        """Worker thread: the drive's heartbeat is lost; if it answers and its heartbeat
        setting is gone, it restarted (its boot-up message was lost): `status().restarted`."""
        try:
            unit.drive.probe_restart()
        except DriveError:
            pass                                 # still silent: asked again later
        finally:
            with self._lock:
                unit.recovery.probing = False

    def _track(self, unit: RowUnit, row: RowStep, now: float, trouble: bool) -> None:
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
        state = 'back in step' if record.in_step else 'not back in step'
        self.log(logging.WARNING if record.plants_missed else logging.INFO, self._row_text(
            unit, f'{state} {record.back_in_step_s:.2f} s after: {record.cause} '
                  f'({restarted}halted {record.halted_s:.2f} s): '
                  f'{record.plants_missed} plant(s) missed'))

    def _recovery_values(self, unit: RowUnit) -> tuple:
        rec = unit.recovery
        values = [('plants missed (halts)', rec.plants_missed),
                  ('drive restarts', rec.restarts),
                  ('automatic re-enables', rec.auto_resets),
                  ('EMCY received', rec.emcy_count)]
        if rec.recoveries:
            last = rec.recoveries[-1]
            values.append(('last recovery', f'{last.cause}: back in step after '
                                            f'{last.back_in_step_s:.2f} s, '
                                            f'{last.plants_missed} plant(s) missed'))
        if rec.reconfigure_error:
            values.append(('configuring again', rec.reconfigure_error))
        return tuple(values)

    def _send_target(self, unit: RowUnit, row: RowStep, now: float) -> None:
        """The row's position for the next SYNC: advanced by its speed over the time since the
        last target (a late step is made up: the angle stays on the distance travelled)."""
        period = self.drive_config.sync_period
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
            fresh = now - unit.status.stamp <= 3.0 * period
            unit.target = unit.status.position if row.halt is None and fresh else None
            unit.behind = 0.0
        else:
            # time owed since the last target; at most two periods' worth per SYNC, so a late
            # step is made up over the next SYNCs at up to twice the speed, never in one jump
            owed = max(now - unit.target_time, 0.0) + unit.behind
            step = min(owed, 2.0 * period)
            unit.behind = min(owed - step, 0.5)
            unit.target += row.command * step
            on_cam = None if self.stopping else cam_csp_target(unit.law, unit.target,
                                                               now + period, step)
            if on_cam is not None:          # a cam row's target is its angle at the next SYNC
                unit.target, ahead = on_cam, period
        unit.target_time = now
        if unit.target is None:
            unit.drive.send_hold()
        else:
            unit.drive.send_position(csp_setpoint(unit.target, row.command, period, ahead)
                                     - unit.angle_shift)

    def feedback(self) -> list[Feedback]:
        """Every running row's last measured motion (for joint_states)."""
        with self._lock:
            return [Feedback(unit.joint, unit.status.position, unit.status.velocity,
                             unit.status.stamp)
                    for unit in self.units
                    if unit.running and unit.joint is not None and unit.status is not None
                    and sync_status.has_feedback(unit.status)]

    def take_feedback(self) -> list[list[Feedback]]:
        """What the shell publishes: here, where the shell runs the loop itself, the newest
        sample of each step (CommandClient.take_feedback: every sample its process sent)."""
        feedback = self.feedback()
        return [feedback] if feedback else []

    def commands(self) -> list[tuple[str, float]]:
        """(joint, command rad/s) of every running row with a design ('' joint: implicit)."""
        with self._lock:
            if self.implicit:
                return [('', self.units[0].command)]
            return [(unit.joint, unit.command) for unit in self.units
                    if unit.running and unit.joint is not None]

    def sections(self) -> dict[str, bool]:
        with self._lock:
            return {unit.row.name: unit.law.section_on for unit in self.units
                    if unit.drive is not None}

    def _report_halt(self, unit: RowUnit, halt: Halt | None, status: DriveStatus | None) -> None:

        row = '' if self.implicit else f'row {unit.label}: '
        if halt is not None and halt.kind != sync_status.NOT_ENABLED:
            unit.faults += 1
            unit.last_fault = halt.text
        if halt is None:
            self.log(logging.INFO, f'{row}drive back in operation: resuming')
        elif halt.kind == sync_status.FAULTED:
            service = interfaces.RESET_FAULT.for_row(unit.row.name)
            self.log(logging.ERROR, f'{row}{halt.text} (state {status.state}): commanding 0; '
                                    f'call the {service} service once the cause is cleared')
        else:
            self.log(logging.WARNING, f'{row}{halt.text}: commanding 0')

    def _send_failed(self, now: float, exc: Exception, unit: RowUnit | None) -> None:
        last = self._last_bus_error if unit is None else unit.last_send_error
        first = last is None or now - last[0] > sync_status.SEND_ERROR_HOLD
        if unit is None:
            self._bus_send_errors += 1
            self._last_bus_error = (now, str(exc))
        else:
            unit.send_errors += 1
            unit.last_send_error = (now, str(exc))
        if first:
            self.log(logging.ERROR, f'CAN send failed: {exc}')

    # ---------------------------------------------------------------- diagnostics
    def idle_reason(self, unit: RowUnit) -> str:
        if unit.drive is None:
            return 'disabled in the scene: never enabled on the bus'
        if unit.left_out:
            return f'left out at start-up: {unit.left_out}'
        return 'shut down' if self._shut_down else 'not enabled yet'

    def _row_values(self, unit: RowUnit, now: float) -> tuple:
        law = unit.law
        return (('lateral offset', f'{unit.row.lateral_offset:.3f} m'),
                ('drive node id', unit.row.drive_node_id),
                ('row speed', f'{law.ground_speed_value:.4f} m/s'),
                ('row travelled', f'{law.travelled(now):.4f} m'))

    def _drive_report(self, unit: RowUnit, now: float) -> diagnostics.Report:
        report = sync_status.drive_report(unit.status, unit.running, self._shut_down,
                                          unit.halt, unit.send_errors, unit.last_send_error,
                                          unit.command, now)
        return replace(report, values=report.values + self._recovery_values(unit))

    def reports(self, now: float,
                shared: Sequence[diagnostics.Report] = ()) -> list[tuple[diagnostics.Report, str]]:
        """(Report, hardware id) of every status, in the order published; `shared` are the
        shell's own (who set the design, the command process), added after the loop's."""
        with self._lock:
            states = [unit.law.state(now) for unit in self.units if unit.running]
            ramping = [state for state in states if state.startswith('ramping')]
            ground = sync_status.ground_report(self.machine.reference, now, self.machine,
                                               (ramping or states or [None])[0])
            errors = [e for e in (self._last_bus_error,
                                  self.drives.canbus.receive_errors.last) if e is not None]
            bus = sync_status.bus_report(self.bus_load, max(errors, default=None), now)
            bus = replace(bus, values=bus.values + (
                ('send errors', self.send_errors),
                ('receive errors', self.drives.canbus.receive_errors.count)))
            loop = sync_status.loop_report(
                [('' if self.implicit else unit.label, unit.period) for unit in self.units
                 if unit.drive is not None], self.drive_config.command_timeout)
            tail = [(loop, self.bus_id)] + [(report, self.bus_id) for report in shared]
            if self.implicit:
                unit = self.units[0]
                drive = self._drive_report(unit, now)
                if unit.status is None and unit.left_out:
                    drive = diagnostics.Report(diagnostics.DRIVE, diagnostics.ERROR,
                                               unit.left_out, drive.values)
                return [(drive, unit.hardware_id), (ground, unit.hardware_id),
                        (sync_status.phase_report(unit.law, now, unit.command),
                         unit.hardware_id), (bus, self.bus_id)] + tail
            reports = [(ground, self.bus_id), (bus, self.bus_id)]
            for unit in self.units:
                values = self._row_values(unit, now)
                if unit.running or (unit.status is not None and self._shut_down):
                    report = sync_status.row_report(
                        unit.label, self._drive_report(unit, now),
                        sync_status.phase_report(unit.law, now, unit.command), values)
                else:
                    level = diagnostics.OK if unit.drive is None else (
                        diagnostics.ERROR if unit.left_out else diagnostics.STALE)
                    report = sync_status.idle_row_report(unit.label, self.idle_reason(unit),
                                                         level, values)
                reports.append((report, unit.hardware_id))
            return reports + tail

    def mode_text(self) -> str:
        """The CiA 402 mode the enabled drives run, in words."""
        return (f'cyclic synchronous position, SYNC every '
                f'{1e3 * self.drive_config.sync_period:g} ms' if self.csp
                else 'profile velocity')

    def snapshot(self) -> Snapshot:
        """What the demo's progress lines show: each row's command, speed and state."""
        with self._lock:
            return Snapshot(tuple(
                RowSnapshot(unit.label, unit.command,
                            unit.status.velocity if unit.status else 0.0,
                            unit.status.state if unit.status else '-', unit.running)
                for unit in self.units if unit.drive is not None), self.law.spacing)

    def final_report(self) -> CommandReport:
        """The run's figures from the command path."""
        with self._lock:
            law, yaw = self.law, self.machine.filter.yaw
            everything = PeriodStats()
            rows = []
            for unit in self.units:
                if unit.drive is None:
                    continue
                everything.merge(unit.period)
                rec = unit.recovery
                rows.append(RowReport(
                    unit.label, unit.faults, unit.last_fault, unit.left_out,
                    unit.period.summary(), plants_missed=rec.plants_missed,
                    restarts=rec.restarts, auto_resets=rec.auto_resets, emcy=rec.emcy_count,
                    recoveries=list(rec.recoveries)))
            return CommandReport(
                accepted=law.accepted, rejected=dict(law.rejected),
                yaw_accepted=yaw.accepted, yaw_rejected=dict(yaw.rejected),
                phase_slips=sum(unit.law.phase_slips for unit in self.units),
                send_errors=self.send_errors, phase_lock=law.config.phase_lock,
                turn_compensation=self.machine.turn.turn_compensation, rows=rows,
                loop=everything.summary(), command_timeout=self.drive_config.command_timeout,
                receive_errors=self.drives.canbus.receive_errors.count,
                loop_histogram=everything.histogram(),
                sample_to_frame=self.sample_latency.summary(),
                sample_to_frame_histogram=self.sample_latency.histogram(),
                sync=self.sync_intervals.summary(),
                sync_histogram=self.sync_intervals.histogram(), csp=self.csp)


def machine_bus_load(cfg: DriveConfig, loop: SyncLoopConfig, rows: int, csp: bool) -> BusLoad:
    """The worst-case CAN bus load of `rows` drives in profile velocity or CSP."""
    return bus_load(rows, cfg.can_bitrate, loop.control_period, loop.ground_speed_rate,
                    cfg.feedback_period, cfg.drive_heartbeat_period, cfg.heartbeat_period,
                    cfg.sync_period if csp else 0.0, csp)


def checked_bus_load(cfg: DriveConfig, loop: SyncLoopConfig, rows: Sequence[Row]) -> BusLoad:
    """The load a configuration may make before its drives say which mode they run: CSP's
    when `operation_mode` allows CSP and it is the larger; refused above the limit with the
    knobs that fix it (DriveConfigError)."""
    loads = [machine_bus_load(cfg, loop, len(rows), False)]
    if cfg.operation_mode != 'velocity':
        loads.append(machine_bus_load(cfg, loop, len(rows), True))
    worst = max(loads, key=lambda load: load.load)
    check_bus_load(worst, [row.label for row in rows], loop.control_period,
                   loop.ground_speed_rate, cfg.feedback_period, cfg.drive_heartbeat_period,
                   cfg.heartbeat_period)
    return worst


def bottom_angle(design: Design) -> float:
    """The shaft angle (rad) at which the design's tip is lowest: the five-bar's π (θ = 0 at
    the top), a tip path's lowest sample."""
    import math
    path = getattr(design, 'tip_path', None)
    if path is None:
        return math.pi
    import numpy as np
    return float(np.asarray(path.angle)[int(np.argmin(np.asarray(path.y)))])
