"""The command path without ROS: the CAN bus, the CiA 402 masters, the heartbeat, the row loop,
section control, fault resets and the sync node's diagnostics, behind one object.

The command process (`planter_ros.command.process`) runs it on its own, fed over a local
channel; `sync_node` runs the same object in its own process when given a bus object (tests).
Either way nothing here imports rclpy: inputs are plain values, outputs are drive frames (sent
here), `diagnostics.Report`s, typed results (`reports`) and log lines through the
`log(level, text)` callable.

`CommandEngine` builds the shared state (`state.EngineState`: configuration, rows, drives, lock,
the run's flags) and the parts that each own theirs: `lifecycle.Lifecycle` (enable, stop ramp,
shutdown), `design_change.DesignChange` (the design in force, cam planning),
`control_step.ControlStep` (the step, SYNC and frame timing), `watch.RowWatch` (fault
recovery) and `status.EngineStatus` (reports, built from the state); the operators' requests
(section, fault reset) are its own. Thread-safe: every public method takes the state's lock.
"""
from __future__ import annotations

from collections.abc import Sequence
import logging
from typing import Any

import can

from planter_ros import diagnostics
from planter_ros.control.loop_timing import PeriodStats, SyncLoopConfig
from planter_ros.control.machine_law import Machine
from planter_ros.control.phase_lock import PhaseLock
from planter_ros.control.row_loop import RowLoop
from planter_ros.design import Design
from planter_ros.drive.bus_load import BusLoad
from planter_ros.drive.config import DriveConfig
from planter_ros.drive.drive_set import DriveSet
from planter_ros.drive.states import FAULT

from .control_step import ControlStep
from .design_change import DesignChange
from .lifecycle import Lifecycle, checked_bus_load
from .reports import CommandReport, Reply, Snapshot
from .settings import CommandSettings
from .state import EngineState, Feedback, Log, RowUnit
from .status import EngineStatus
from .watch import RowWatch

__all__ = ['CommandEngine']


def _print_log(level: int, text: str) -> None:
    logging.getLogger('planter_ros.command').log(level, '%s', text)


class CommandEngine:
    """The rows, their drives and the row loop (see the module doc)."""

    def __init__(self, settings: CommandSettings, bus: can.BusABC | None = None,
                 log: Log | None = None) -> None:
        """`settings`: the drive, loop, rows, law and drive setups (its log level and hold are
        the command process's)."""
        drive_config, loop_config = settings.drive, settings.loop
        rows, setups = settings.rows, settings.setups
        machine = Machine([row.lateral_offset for row in rows], *settings.law)
        enabled = [row for row in rows if row.enabled]
        load = checked_bus_load(drive_config, loop_config, enabled)
        # a row without a node id of its own: the drive configuration's (rows)
        node_ids = {row.name: row.drive_node_id if row.drive_node_id is not None
                    else drive_config.drive_node_id for row in enabled}
        drives = DriveSet(drive_config, node_ids, bus=bus, setups=setups)
        self.state = EngineState(settings, machine, drives, load, log or _print_log)
        self.lifecycle = Lifecycle(self.state)
        self.design = DesignChange(self.state)
        self.watch = RowWatch(self.state)
        self.control = ControlStep(self.state, self.lifecycle, self.watch)
        self.status = EngineStatus(self.state, self.control)

    # ---------------------------------------------------------------- what it holds
    @property
    def drive_config(self) -> DriveConfig:
        return self.state.drive_config

    @property
    def loop(self) -> SyncLoopConfig:
        return self.state.loop

    @property
    def log(self) -> Log:
        return self.state.log

    @property
    def implicit(self) -> bool:
        """A scene without rows: one drive, its statuses named as before rows."""
        return self.state.implicit

    @property
    def machine(self) -> Machine:
        return self.state.machine

    @property
    def row_loop(self) -> RowLoop:
        return self.state.row_loop

    @property
    def drives(self) -> DriveSet:
        return self.state.drives

    @property
    def units(self) -> list[RowUnit]:
        return self.state.units

    @property
    def bus_load(self) -> BusLoad:
        """The CAN bus load (worst case before the drives said their mode, then theirs)."""
        return self.state.bus_load

    @property
    def bus_id(self) -> str:
        return self.state.bus_id

    @property
    def hardware_id(self) -> str:
        return self.state.hardware_id

    @property
    def law(self) -> PhaseLock:
        """The first row's law."""
        return self.state.law

    @property
    def send_errors(self) -> int:
        return self.state.send_errors

    @property
    def running(self) -> int:
        """Rows whose drives run."""
        return self.state.running

    @property
    def shut_down(self) -> bool:
        return self.state.shut_down

    @property
    def csp(self) -> bool:
        """Some row runs CSP: SYNC every step, position targets."""
        return self.state.csp

    @property
    def period(self) -> float:
        """The loop's period: the SYNC period when a row runs CSP, else the control period."""
        return self.state.period

    @property
    def design_key(self) -> tuple | None:
        return self.design.design_key

    @property
    def mechanism(self) -> str | None:
        return self.design.mechanism

    @property
    def sync_intervals(self) -> PeriodStats:
        return self.control.sync_intervals

    @property
    def sample_latency(self) -> PeriodStats:
        return self.control.sample_latency

    def unit(self, name: str) -> RowUnit:
        return self.state.unit(name)

    def idle_reason(self, unit: RowUnit) -> str:
        with self.state.lock:
            return self.idle_reason(unit)

    def mode_text(self) -> str:
        """The CiA 402 mode the enabled drives run, in words."""
        return self.state.mode_text()

    # ---------------------------------------------------------------- life cycle
    def enable(self) -> None:
        """BLOCKING: configure and enable every row's drive at once (start-up only). A row whose
        drive does not answer is reported and left out; raises DriveError when no row runs."""
        self.lifecycle.enable()

    def shutdown(self) -> None:
        """BLOCKING, idempotent: every row at once: 0x60FF = 0, disable, NMT pre-operational."""
        self.lifecycle.shutdown()

    def stop_ramp(self, now: float) -> None:
        """From now on every row's command ramps to 0 at its acceleration limit, whatever the
        ground speed (the shell is gone); `ramped_down` says when all are at 0."""
        self.lifecycle.stop_ramp(now)

    @property
    def ramped_down(self) -> bool:
        return self.lifecycle.ramped_down

    # ---------------------------------------------------------------- inputs
    def sample(self, v: float, yaw_rate: float, now: float) -> None:
        """A ground-speed sample (m/s, rad/s) received at `now`: in profile velocity the rows'
        frames go at once; in CSP the targets go with the next SYNC."""
        self.control.sample(v, yaw_rate, now)

    def step(self, now: float) -> None:
        """One command per running row and the master heartbeat when due (control_step)."""
        self.control.step(now)

    def set_design(self, design: Design, text: str, now: float,
                   planned: tuple[Any, str] | None = None,
                   arrived: float | None = None) -> bool:
        """A design for every row (design_change.DesignChange.set_design); False when it is
        the one in force already."""
        return self.design.set_design(design, text, now, planned, arrived)

    def configure(self, law_values: Sequence[Any]) -> None:
        self.design.configure(law_values)

    def reset_fault(self, name: str) -> Reply:
        unit = self.unit(name)
        with self.state.lock:
            if not unit.running:
                return Reply(False, f'row {unit.label} does not run ({self.idle_reason(unit)})')
            status = unit.bus_drive.status()
            if not status.fault and status.state != FAULT:
                return Reply(False, f'no drive fault to reset (state {status.state})')
            unit.bus_drive.request_fault_reset()
            message = (f'fault reset requested (error 0x{status.error_code:04X}); the drive '
                       're-enables if the cause is gone')
        self.log(logging.WARNING, message if self.implicit else f'row {unit.label}: {message}')
        return Reply(True, message)

    def section(self, name: str, on: bool, now: float) -> Reply:
        """Switch row `name`'s section (`changed`: it was not so already)."""
        unit = self.unit(name)
        with self.state.lock:
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

    # ---------------------------------------------------------------- outputs
    def feedback(self) -> list[Feedback]:
        """Every running row's last measured motion (for joint_states)."""
        return self.status.feedback()

    def take_feedback(self) -> list[list[Feedback]]:
        """What the shell publishes: here, where the shell runs the loop itself, the newest
        sample of each step (CommandClient.take_feedback: every sample its process sent)."""
        return self.status.take_feedback()

    def commands(self) -> list[tuple[str, float]]:
        """(joint, command rad/s) of every running row with a design ('' joint: implicit)."""
        return self.status.commands()

    def sections(self) -> dict[str, bool]:
        return self.status.sections()

    def reports(self, now: float,
                shared: Sequence[diagnostics.Report] = ()) -> list[tuple[diagnostics.Report, str]]:
        """(Report, hardware id) of every status, in the order published; `shared` are the
        shell's own (who set the design, the command process), added after the loop's."""
        return self.status.reports(now, shared)

    def snapshot(self) -> Snapshot:
        """What the demo's progress lines show: each row's command, speed and state."""
        return self.status.snapshot()

    def final_report(self) -> CommandReport:
        """The run's figures from the command path."""
        return self.status.final_report()
