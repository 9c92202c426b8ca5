"""The sync node's health policy, pure: when to stop commanding the drive, and what its
/diagnostics say, from a drive status snapshot and the phase-locked law's state.

Kept out of the node so the policy is tested without ROS or CAN; the reports are
planter_ros.diagnostics `Report`s, which that module turns into the node's DiagnosticArray.
No canopen here: the CiA 402 state names come from drive.state_names.
"""

from collections.abc import Iterable
from dataclasses import dataclass, replace
import math
from typing import Any

from planter_ros.diagnostics import (BUS, CONTROL_LOOP, DRIVE, ERROR, GROUND_SPEED, OK,
                                     PHASE_LOCK, SECTION, SECTION_OFF, SECTION_ON, STALE, WARN,
                                     Report, worst)
from planter_ros.drive.state_names import FAULT, OPERATION_ENABLED

from .machine_law import Machine
from .phase_lock import PhaseLock

__all__ = ['SEND_ERROR_HOLD', 'RESTARTED', 'FAULTED', 'HEARTBEAT_LOST', 'NOT_ENABLED', 'Halt',
           'NEVER_ENABLED', 'DriveSide', 'at_sync', 'has_feedback', 'halt_reason', 'drive_report',
           'ground_report', 'phase_report', 'row_report', 'idle_row_report', 'bus_report',
           'LOOP_MARGIN', 'loop_report']

SEND_ERROR_HOLD = 2.0      # s a CAN send error keeps the drive status at ERROR

# kinds of halt, in the order they are checked
RESTARTED = 'restarted'
FAULTED, HEARTBEAT_LOST, NOT_ENABLED = 'fault', 'heartbeat lost', 'not enabled'


@dataclass(frozen=True)
class Halt:
    """Why the law is not driving the mechanism: `kind` for code, `text` for people."""

    kind: str
    text: str


NEVER_ENABLED = Halt(NOT_ENABLED, 'drive not enabled')


def has_feedback(status: Any) -> bool:
    """The drive has sent motion feedback (a TPDO with position and velocity)."""
    return status.stamp is not None and math.isfinite(status.stamp) and status.stamp > 0.0


def at_sync(status: Any, sync_times: Iterable[float]) -> Any:
    """A CSP drive's status with its motion stamped when it was measured: a SYNC-triggered
    TPDO carries the position at its SYNC, so the stamp is the last SYNC sent before the TPDO
    arrived (`sync_times`, monotonic s), not its arrival (which came 1.3-1.8 ms later on the
    development host: a phase error of ω·1.5 ms, and as late joint_states stamps a replay
    that placed plants 0.15 mm later per 0.1 m/s). Unchanged without feedback or an earlier
    SYNC. `status`: a frozen dataclass with `stamp` (a DriveStatus)."""
    if not has_feedback(status):
        return status
    measured = max((t for t in sync_times if t <= status.stamp), default=None)
    return status if measured is None else replace(status, stamp=measured)


def halt_reason(status: Any, heartbeat_timeout: float) -> Halt | None:
    """Halt (commanding 0) or None when the drive may be commanded."""
    restarted = getattr(status, 'restarted', '')
    if restarted:
        return Halt(RESTARTED, f'drive restarted ({restarted}): configuring it again')
    if status.fault or status.state == FAULT:
        why = status.fault_reason or status.state
        return Halt(FAULTED, f'drive fault 0x{status.error_code:04X} ({why})')
    if status.heartbeat_age > heartbeat_timeout:
        return Halt(HEARTBEAT_LOST, 'drive heartbeat lost')
    if status.state != OPERATION_ENABLED:
        return Halt(NOT_ENABLED, f'drive not enabled ({status.state})')
    return None


@dataclass(frozen=True)
class DriveSide:
    """What the loop knows of one row's drive at a moment: its last status snapshot (a
    DriveStatus; None before the first), whether it runs (enabled at start-up, not shut down),
    why the law is not driving it (None: it is), its CAN send errors (how many, and the last:
    (monotonic s, text)) and the speed it was last commanded (rad/s)."""

    status: Any
    enabled: bool
    halt: Halt | None
    send_errors: int
    last_send_error: tuple[float, str] | None
    command: float


def drive_report(drive: DriveSide, shut_down: bool, now: float) -> Report:
    """The drive's status (`shut_down`: the loop shut the drives down)."""
    status, halt, last_send_error = drive.status, drive.halt, drive.last_send_error
    values: list[tuple[str, object]] = [('enabled', drive.enabled),
                                        ('send errors', drive.send_errors)]
    if status is None:
        return Report(DRIVE, STALE if shut_down else ERROR,
                      halt.text if halt else 'not enabled', tuple(values))
    values = [('drive state', status.state), ('statusword', f'0x{status.statusword:04X}'),
              ('error code', f'0x{status.error_code:04X}'),
              ('heartbeat age', f'{status.heartbeat_age:.3f} s'),
              ('position', f'{status.position:.4f} rad'),
              ('velocity', f'{status.velocity:.4f} rad/s'),
              ('command', f'{drive.command:.4f} rad/s')] + values
    if last_send_error is not None and now - last_send_error[0] <= SEND_ERROR_HOLD:
        values.append(('last send error', last_send_error[1]))
        return Report(DRIVE, ERROR, f'CAN send error: {last_send_error[1]}', tuple(values))
    if halt is not None:
        return Report(DRIVE, ERROR, halt.text, tuple(values))
    if not has_feedback(status):
        return Report(DRIVE, STALE, 'no feedback from the drive', tuple(values))
    return Report(DRIVE, OK, 'operation enabled', tuple(values))


def ground_report(law: PhaseLock, now: float, machine: Machine | None = None,
                  stale_state: str | None = None) -> Report:
    """The ground-speed input: fresh, rejecting samples, or stale. `law` runs at the machine's
    reference point; `machine` (control.machine_law.Machine) adds the yaw rate; `stale_state` says
    what the rows do meanwhile (default: `law.state`)."""
    rejected = sum(law.rejected.values())
    values = [('ground speed', f'{law.ground_speed_value:.4f} m/s'),
              ('travelled', f'{law.travelled(now):.4f} m'),
              ('accepted samples', law.accepted), ('rejected samples', rejected)]
    values += [(f'rejected {k}', v) for k, v in law.rejected.items()]
    yaw_rejected = 0
    if machine is not None:
        yaw = machine.filter.yaw
        yaw_rejected = sum(yaw.rejected.values())
        values += [('yaw rate', f'{machine.yaw_rate_value:.4f} rad/s'),
                   ('turn compensation', 'on' if machine.turn.turn_compensation else 'off'),
                   ('accepted yaw-rate samples', yaw.accepted),
                   ('rejected yaw-rate samples', yaw_rejected)]
        values += [(f'rejected yaw rate {k}', v) for k, v in yaw.rejected.items()]
    if law.stale(now):
        return Report(GROUND_SPEED, STALE, stale_state or law.state(now), tuple(values))
    if rejected or yaw_rejected:
        return Report(GROUND_SPEED, WARN, f'{rejected} speed and {yaw_rejected} yaw-rate '
                      'sample(s) rejected since start' if machine is not None else
                      f'{rejected} sample(s) rejected since start', tuple(values))
    return Report(GROUND_SPEED, OK, 'fresh', tuple(values))


def phase_report(law: PhaseLock, now: float, command: float) -> Report:
    """The phase lock: waiting for a design, tracking, or slipping plants."""
    error = law.last_error
    metres = error * law.plants_per_revolution * law.spacing / (2 * math.pi) \
        if law.spacing else 0.0
    values: tuple[tuple[str, object], ...] = (
        ('mode', 'phase-locked' if law.config.phase_lock else 'speed-only'),
        ('state', law.state(now)), ('phase error', f'{error:.4f} rad'),
        ('phase error along row', f'{metres:.4f} m'),
        ('phase slips', law.phase_slips),
        ('command', f'{command:.4f} rad/s'),
        (SECTION, SECTION_ON if law.section_on else SECTION_OFF))
    if law.config.speed_profile == 'cam':
        values += (('speed profile', law.speed_profile),)
        if law.cam_fallback and law.spacing is not None:
            return Report(PHASE_LOCK, WARN, law.cam_fallback, values)
    if law.spacing is None:
        return Report(PHASE_LOCK, STALE, 'waiting for design', values)
    if law.phase_slips:
        return Report(PHASE_LOCK, WARN,
                      f'{law.phase_slips} plant(s) skipped to stay on the grid', values)
    return Report(PHASE_LOCK, OK, law.state(now), values)


def row_report(name: str, drive: Report, phase: Report,
               row_values: Iterable[tuple[str, Any]] = ()) -> Report:
    """One status per row of a machine: the row's drive and phase lock reports merged (the
    worse level; the drive's message unless the drive is fine) plus the row's own values."""
    message = drive.message if drive.level != OK else phase.message
    return Report(name, worst((drive.level, phase.level)), message,
                  tuple(row_values) + tuple(drive.values) + tuple(phase.values))


def idle_row_report(name: str, reason: str, level: int,
                    row_values: Iterable[tuple[str, Any]] = ()) -> Report:
    """A row that does not run: disabled in the scene (OK) or left out at start-up (ERROR)."""
    return Report(name, level, reason, tuple(row_values))


def bus_report(load: Any, last_send_error: tuple[float, str] | None, now: float) -> Report:
    """The CAN bus: its worst-case load (drive.bus_load.BusLoad) and heartbeat send errors."""
    values = tuple(load.values())
    if last_send_error is not None and now - last_send_error[0] <= SEND_ERROR_HOLD:
        return Report(BUS, ERROR, f'CAN send error: {last_send_error[1]}',
                      values + (('last send error', last_send_error[1]),))
    return Report(BUS, OK, f'load {100 * load.load:.1f} % of {load.bitrate} bit/s '
                  f'({load.rows} drive(s))', values)


# the control loop keeps its margin while no gap between two command frames of a row exceeds
# this share of the drive's RPDO deadline (command_timeout)
LOOP_MARGIN = 0.5


def loop_report(periods: Iterable[tuple[str, Any]], deadline: float) -> Report:
    """How the control loop keeps the drives' command deadline: per row (label, PeriodStats of
    its command frames; label '' without rows) the largest gap and p99.9. WARN once a gap ate
    half the deadline, ERROR once one reached it (the drive has quick-stopped)."""
    values: list[tuple[str, object]] = []
    longest = 0.0
    p999 = 0.0
    for label, stats in periods:
        prefix = f'{label} ' if label else ''
        if not stats.gaps:
            values.append((f'{prefix}command frames', 0))
            continue
        values += [(f'{prefix}command frames', stats.gaps + 1),
                   (f'{prefix}command gap mean', f'{stats.mean * 1e3:.1f} ms'),
                   (f'{prefix}command gap p99.9', f'{stats.quantile(0.999) * 1e3:.1f} ms'),
                   (f'{prefix}command gap max', f'{stats.max_gap * 1e3:.1f} ms')]
        longest = max(longest, stats.max_gap)
        p999 = max(p999, stats.quantile(0.999))
    values.append(('drive command deadline', f'{deadline * 1e3:.0f} ms'))
    text = (f'command gap max {longest * 1e3:.1f} ms, p99.9 {p999 * 1e3:.1f} ms (deadline '
            f'{deadline * 1e3:.0f} ms)')
    if longest >= deadline:
        return Report(CONTROL_LOOP, ERROR, f'deadline missed: {text}', tuple(values))
    if longest >= LOOP_MARGIN * deadline:
        return Report(CONTROL_LOOP, WARN, f'less than half the deadline left: {text}',
                      tuple(values))
    return Report(CONTROL_LOOP, OK, text, tuple(values))
