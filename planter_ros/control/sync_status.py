"""The sync node's health policy, pure: when to stop commanding the drive, and what its
/diagnostics say, from a drive status snapshot and the phase-locked law's state.

Kept out of the node so the policy is tested without ROS or CAN; the node only turns the
`Report`s into diagnostic_msgs/DiagnosticStatus (levels are the same bytes).
"""

from dataclasses import dataclass
import math

from planter_ros.drive.states import FAULT, OPERATION_ENABLED

OK, WARN, ERROR, STALE = 0, 1, 2, 3
SEND_ERROR_HOLD = 2.0      # s a CAN send error keeps the drive status at ERROR

# the value of a row's phase-lock status saying whether its section is on or off; the monitor
# and replay read it back (`section_states`) so a plant after a section was off has no spacing
SECTION_KEY = 'section'
PHASE_LOCK_TASK = 'phase lock'      # the status of a scene without rows (one implicit row)

# kinds of halt, in the order they are checked
FAULTED, HEARTBEAT_LOST, NOT_ENABLED = 'fault', 'heartbeat lost', 'not enabled'


@dataclass(frozen=True)
class Halt:
    """Why the law is not driving the mechanism: `kind` for code, `text` for people."""

    kind: str
    text: str


NEVER_ENABLED = Halt(NOT_ENABLED, 'drive not enabled')


@dataclass(frozen=True)
class Report:
    """One diagnostics status: task name, level (OK..STALE), message, key/value pairs."""

    task: str
    level: int
    message: str
    values: tuple = ()


def has_feedback(status):
    """The drive has sent motion feedback (a TPDO with position and velocity)."""
    return status.stamp is not None and math.isfinite(status.stamp) and status.stamp > 0.0


def halt_reason(status, heartbeat_timeout):
    """Halt (commanding 0) or None when the drive may be commanded."""
    if status.fault or status.state == FAULT:
        why = status.fault_reason or status.state
        return Halt(FAULTED, f'drive fault 0x{status.error_code:04X} ({why})')
    if status.heartbeat_age > heartbeat_timeout:
        return Halt(HEARTBEAT_LOST, 'drive heartbeat lost')
    if status.state != OPERATION_ENABLED:
        return Halt(NOT_ENABLED, f'drive not enabled ({status.state})')
    return None


def drive_report(status, enabled, shut_down, halt, send_errors, last_send_error, command, now):
    """The drive's status. `last_send_error` = (monotonic time, text) or None."""
    values = [('enabled', enabled), ('send errors', send_errors)]
    if status is None:
        return Report('drive', STALE if shut_down else ERROR,
                      halt.text if halt else 'not enabled', tuple(values))
    values = [('drive state', status.state), ('statusword', f'0x{status.statusword:04X}'),
              ('error code', f'0x{status.error_code:04X}'),
              ('heartbeat age', f'{status.heartbeat_age:.3f} s'),
              ('position', f'{status.position:.4f} rad'),
              ('velocity', f'{status.velocity:.4f} rad/s'),
              ('command', f'{command:.4f} rad/s')] + values
    if last_send_error is not None and now - last_send_error[0] <= SEND_ERROR_HOLD:
        values.append(('last send error', last_send_error[1]))
        return Report('drive', ERROR, f'CAN send error: {last_send_error[1]}', tuple(values))
    if halt is not None:
        return Report('drive', ERROR, halt.text, tuple(values))
    if not has_feedback(status):
        return Report('drive', STALE, 'no feedback from the drive', tuple(values))
    return Report('drive', OK, 'operation enabled', tuple(values))


def ground_report(law, now, machine=None, stale_state=None):
    """The ground-speed input: fresh, rejecting samples, or stale. `law` runs at the machine's
    reference point; `machine` (control.machine.Machine) adds the yaw rate; `stale_state` says
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
        return Report('ground speed', STALE, stale_state or law.state(now), tuple(values))
    if rejected or yaw_rejected:
        return Report('ground speed', WARN, f'{rejected} speed and {yaw_rejected} yaw-rate '
                      'sample(s) rejected since start' if machine is not None else
                      f'{rejected} sample(s) rejected since start', tuple(values))
    return Report('ground speed', OK, 'fresh', tuple(values))


def phase_report(law, now, command):
    """The phase lock: waiting for a design, tracking, or slipping plants."""
    error = law.last_error
    metres = error * law.plants_per_revolution * law.spacing / (2 * math.pi) \
        if law.spacing else 0.0
    values = (('mode', 'phase-locked' if law.config.phase_lock else 'speed-only'),
              ('state', law.state(now)), ('phase error', f'{error:.4f} rad'),
              ('phase error along row', f'{metres:.4f} m'),
              ('phase slips', law.phase_slips),
              ('command', f'{command:.4f} rad/s'),
              (SECTION_KEY, 'on' if law.section_on else 'off'))
    if law.spacing is None:
        return Report(PHASE_LOCK_TASK, STALE, 'waiting for design', values)
    if law.phase_slips:
        return Report(PHASE_LOCK_TASK, WARN,
                      f'{law.phase_slips} plant(s) skipped to stay on the grid', values)
    return Report(PHASE_LOCK_TASK, OK, law.state(now), values)


# how bad a level is, for merging (diagnostic_msgs numbers STALE above ERROR)
_SEVERITY = {OK: 0, WARN: 1, STALE: 2, ERROR: 3}


def row_report(name, drive, phase, row_values=()):
    """One status per row of a machine: the row's drive and phase lock reports merged (the
    worse level; the drive's message unless the drive is fine) plus the row's own values."""
    worst = max((drive, phase), key=lambda r: _SEVERITY[r.level])
    message = drive.message if drive.level != OK else phase.message
    return Report(name, worst.level, message,
                  tuple(row_values) + tuple(drive.values) + tuple(phase.values))


def idle_row_report(name, reason, level, row_values=()):
    """A row that does not run: disabled in the scene (OK) or left out at start-up (ERROR)."""
    return Report(name, level, reason, tuple(row_values))


def bus_report(load, last_send_error, now):
    """The CAN bus: its worst-case load (drive.bus_load.BusLoad) and heartbeat send errors."""
    values = tuple(load.values())
    if last_send_error is not None and now - last_send_error[0] <= SEND_ERROR_HOLD:
        return Report('bus', ERROR, f'CAN send error: {last_send_error[1]}',
                      values + (('last send error', last_send_error[1]),))
    return Report('bus', OK, f'load {100 * load.load:.1f} % of {load.bitrate} bit/s '
                  f'({load.rows} drive(s))', values)


# the control loop keeps its margin while no gap between two command frames of a row exceeds
# this share of the drive's RPDO deadline (command_timeout)
LOOP_MARGIN = 0.5


def loop_report(periods, deadline):
    """How the control loop keeps the drives' command deadline: per row (label, PeriodStats of
    its command frames; label '' without rows) the largest gap and p99.9. WARN once a gap ate
    half the deadline, ERROR once one reached it (the drive has quick-stopped)."""
    values = []
    worst = 0.0
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
        worst = max(worst, stats.max_gap)
        p999 = max(p999, stats.quantile(0.999))
    values.append(('drive command deadline', f'{deadline * 1e3:.0f} ms'))
    text = (f'command gap max {worst * 1e3:.1f} ms, p99.9 {p999 * 1e3:.1f} ms (deadline '
            f'{deadline * 1e3:.0f} ms)')
    if worst >= deadline:
        return Report('control loop', ERROR, f'deadline missed: {text}', tuple(values))
    if worst >= LOOP_MARGIN * deadline:
        return Report('control loop', WARN, f'less than half the deadline left: {text}',
                      tuple(values))
    return Report('control loop', OK, text, tuple(values))

def section_states(statuses):
    """{row name: section on (bool)} from diagnostic statuses (objects with `name` and `values`
    of `key`/`value`, as diagnostic_msgs has them): the sync node's status of each row
    (`<node>: <row>`) or, in a scene without rows, its phase-lock status (row name '').
    Statuses without the section value are not the sync node's: left out."""
    states = {}
    for status in statuses:
        for item in status.values:
            if item.key == SECTION_KEY and item.value in ('on', 'off'):
                task = status.name.rsplit(': ', 1)[-1]
                states['' if task == PHASE_LOCK_TASK else task] = item.value == 'on'
                break
    return states


def section_breaks(reports):
    """Per row name, the times (start, end) across which its section was off, from reports
    [(t, {row name: on})] in time order: from the last report saying off to the first saying
    on again. The first plant after such a break has no spacing."""
    breaks, last_off = {}, {}
    for t, states in reports:
        for row, on in states.items():
            if not on:
                last_off[row] = t
            elif row in last_off:
                breaks.setdefault(row, []).append((last_off.pop(row), t))
    return breaks
