"""What the command engine reports, built from its state under the lock: /diagnostics reports
(per row, the ground speed, the bus, the loop), the joint feedback and commands the shell
publishes, the section states, the demo's `reports.Snapshot` and the run's
`reports.CommandReport`.

Owns nothing: it reads `state.EngineState` and the control step's timing figures.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

from planter_ros import diagnostics
from planter_ros.control import sync_status
from planter_ros.control.loop_timing import PeriodStats

from .control_step import ControlStep
from .reports import CommandReport, RowReport, RowSnapshot, Snapshot
from .state import EngineState, Feedback, RowUnit

__all__ = ['EngineStatus']


class EngineStatus:
    """The engine's reports (see the module doc)."""

    def __init__(self, state: EngineState, control: ControlStep) -> None:
        self.state = state
        self.control = control

    def _recovery_values(self, unit: RowUnit) -> tuple:
        rec = unit.recovery
        values: list[tuple[str, Any]] = [('plants missed (halts)', rec.plants_missed),
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

    def feedback(self) -> list[Feedback]:
        """Every running row's last measured motion (for joint_states)."""
        with self.state.lock:
            return [Feedback(unit.joint, unit.status.position, unit.status.velocity,
                             unit.status.stamp)
                    for unit in self.state.units
                    if unit.running and unit.joint is not None and unit.status is not None
                    and sync_status.has_feedback(unit.status)]

    def take_feedback(self) -> list[list[Feedback]]:
        """What the shell publishes: here, where the shell runs the loop itself, the newest
        sample of each step (CommandClient.take_feedback: every sample its process sent)."""
        feedback = self.feedback()
        return [feedback] if feedback else []

    def commands(self) -> list[tuple[str, float]]:
        """(joint, command rad/s) of every running row with a design ('' joint: implicit)."""
        with self.state.lock:
            if self.state.implicit:
                return [('', self.state.units[0].command)]
            return [(unit.joint, unit.command) for unit in self.state.units
                    if unit.running and unit.joint is not None]

    def sections(self) -> dict[str, bool]:
        with self.state.lock:
            return {unit.row.name: unit.law.section_on for unit in self.state.units
                    if unit.drive is not None}

    def _row_values(self, unit: RowUnit, now: float) -> tuple:
        law = unit.law
        return (('lateral offset', f'{unit.row.lateral_offset:.3f} m'),
                ('drive node id', unit.row.drive_node_id),
                ('row speed', f'{law.ground_speed_value:.4f} m/s'),
                ('row travelled', f'{law.travelled(now):.4f} m'))

    def _drive_report(self, unit: RowUnit, now: float) -> diagnostics.Report:
        drive = sync_status.DriveSide(unit.status, unit.running, unit.halt, unit.send_errors,
                                      unit.last_send_error, unit.command)
        report = sync_status.drive_report(drive, self.state.shut_down, now)
        return replace(report, values=report.values + self._recovery_values(unit))

    def reports(self, now: float,
                shared: Sequence[diagnostics.Report] = ()) -> list[tuple[diagnostics.Report, str]]:
        """(Report, hardware id) of every status, in the order published; `shared` are the
        shell's own (who set the design, the command process), added after the loop's."""
        state = self.state
        with state.lock:
            states = [unit.law.state(now) for unit in state.units if unit.running]
            ramping = [text for text in states if text.startswith('ramping')]
            ground = sync_status.ground_report(state.machine.reference, now, state.machine,
                                               next(iter(ramping or states), None))
            errors = [e for e in (state.last_bus_error,
                                  state.drives.canbus.receive_errors.last) if e is not None]
            bus = sync_status.bus_report(state.bus_load, max(errors, default=None), now)
            bus = replace(bus, values=bus.values + (
                ('send errors', state.send_errors),
                ('receive errors', state.drives.canbus.receive_errors.count)))
            loop = sync_status.loop_report(
                [('' if state.implicit else unit.label, unit.period) for unit in state.units
                 if unit.drive is not None], state.drive_config.command_timeout)
            tail = [(loop, state.bus_id)] + [(report, state.bus_id) for report in shared]
            if state.implicit:
                unit = state.units[0]
                drive = self._drive_report(unit, now)
                if unit.status is None and unit.left_out:
                    drive = diagnostics.Report(diagnostics.DRIVE, diagnostics.ERROR,
                                               unit.left_out, drive.values)
                return [(drive, unit.hardware_id), (ground, unit.hardware_id),
                        (sync_status.phase_report(unit.law, now, unit.command),
                         unit.hardware_id), (bus, state.bus_id)] + tail
            reports = [(ground, state.bus_id), (bus, state.bus_id)]
            for unit in state.units:
                values = self._row_values(unit, now)
                if unit.running or (unit.status is not None and state.shut_down):
                    report = sync_status.row_report(
                        unit.label, self._drive_report(unit, now),
                        sync_status.phase_report(unit.law, now, unit.command), values)
                else:
                    level = diagnostics.OK if unit.drive is None else (
                        diagnostics.ERROR if unit.left_out else diagnostics.STALE)
                    report = sync_status.idle_row_report(unit.label, state.idle_reason(unit),
                                                         level, values)
                reports.append((report, unit.hardware_id))
            return reports + tail

    def snapshot(self) -> Snapshot:
        """What the demo's progress lines show: each row's command, speed and state."""
        with self.state.lock:
            return Snapshot(tuple(
                RowSnapshot(unit.label, unit.command,
                            unit.status.velocity if unit.status else 0.0,
                            unit.status.state if unit.status else '-', unit.running)
                for unit in self.state.units if unit.drive is not None), self.state.law.spacing)

    def final_report(self) -> CommandReport:
        """The run's figures from the command path."""
        state = self.state
        with state.lock:
            law, yaw = state.law, state.machine.filter.yaw
            everything = PeriodStats()
            rows = []
            for unit in state.units:
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
                phase_slips=sum(unit.law.phase_slips for unit in state.units),
                send_errors=state.send_errors, phase_lock=law.config.phase_lock,
                turn_compensation=state.machine.turn.turn_compensation, rows=rows,
                loop=everything.summary(), command_timeout=state.drive_config.command_timeout,
                receive_errors=state.drives.canbus.receive_errors.count,
                loop_histogram=everything.histogram(),
                sample_to_frame=self.control.sample_latency.summary(),
                sample_to_frame_histogram=self.control.sample_latency.histogram(),
                sync=self.control.sync_intervals.summary(),
                sync_histogram=self.control.sync_intervals.histogram(), csp=state.csp)
