"""The row loop as one pure step: every row's drive command and status from the machine's law,
the drives' feedback and the time. No ROS, no CAN: the sync node (in-process) and the command
process (planter_ros.command) call `RowLoop.step` with the drives' status snapshots and send
what it returns; tests call it with made-up snapshots.

Per running row, in this order: the drive's feedback (angle, speed, stamp) goes into the row's
`PhaseLock`; the health policy (`sync_status.halt_reason`) says whether the drive may be
commanded; if so the law's command for `now`, else 0 and the law is told it halted (its next
commands ramp up from 0). A row whose halt reason changed is flagged (`changed`), so the caller
logs it once. The master heartbeat is due once per `heartbeat_period` (`LoopStep.heartbeat`).
After `stop(now)` every row ramps from its last command to 0 at its acceleration limit.

Inputs the caller feeds between steps go to the `Machine` (`loop.machine`): ground-speed
samples (`sample`), designs (`set_design`), section switches (`switch`).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math
from typing import Any

from . import sync_status
from .machine_law import Machine
from .phase_lock import PhaseLock
from .sync_status import Halt

__all__ = ['CSP_LEAD', 'RowStep', 'LoopStep', 'RowLoop', 'cam_csp_target', 'csp_setpoint']

# SYNC periods from a CSP step to when the drive's set point reaches the target it sends: the
# target goes out right after SYNC k, the drive takes it at SYNC k+1 and interpolates to it
# over one period (60C2h), reaching it at SYNC k+2
CSP_LEAD = 2


def csp_setpoint(target: float, command: float, period: float, ahead: float = 0.0) -> float:
    """The position target (rad) a CSP row sends after a SYNC: its angle `target`, which is
    the row's angle `ahead` s from now (0: now), carried on at `command` (rad/s) to the
    instant the drive's set point reaches it (CSP_LEAD periods on). Without the lead the set
    point trails the law by two periods (20 ms at 10 ms SYNC), which the phase correction
    only makes up at its own pace: 0.6-0.9 mm behind in every ramp of the demo's profile."""
    return target + command * max(CSP_LEAD * period - ahead, 0.0)


def cam_csp_target(law: PhaseLock, target: float, at: float, step: float) -> float | None:
    """A cam row's CSP target: the integrated `target` pulled onto θ(s) of the row's distance
    at the SYNC it applies at (`at`), by at most 1.5 times the law's correction bound over
    `step` s (so a cam row's targets are θ(s) itself while it tracks, and a row catching up
    after a halt closes in gradually). None for rows without a cam or not tracking: they keep
    the integrated target. The command process and `planter simulate` both use it."""
    want = law.cam_target(at)
    if want is None:
        return None
    pull = 1.5 * law.config.max_correction * step
    return target + min(max(want - target, -pull), pull)


@dataclass(frozen=True)
class RowStep:
    """What one row does this step."""

    command: float                 # mechanism speed to send (rad/s), 0 while halted
    halt: Halt | None              # why the law is not driving the row (None: it is)
    changed: bool                  # `halt` differs from the row's previous step
    running: bool                  # the row takes part (False: nothing to send)


@dataclass(frozen=True)
class LoopStep:
    rows: tuple[RowStep, ...]
    heartbeat: bool                # the master heartbeat is due (send it after the commands)


class RowLoop:
    """Every row of a `Machine`, stepped at once (see the module doc)."""

    def __init__(self, machine: Machine, heartbeat_period: float,
                 heartbeat_timeout: float) -> None:
        if not (heartbeat_period > 0 and heartbeat_timeout > 0):
            raise ValueError('heartbeat_period and heartbeat_timeout must be > 0 s')
        self.machine = machine
        self.heartbeat_period = float(heartbeat_period)
        self.heartbeat_timeout = float(heartbeat_timeout)
        n = len(machine.laws)
        self.halts: list[Halt | None] = [sync_status.NEVER_ENABLED] * n
        self.commands: list[float] = [0.0] * n
        self._last_heartbeat = -math.inf
        self._stop: tuple[float, list[float]] | None = None     # (time, commands then)

    def enabled(self, i: int) -> None:
        """Row i's drive was just enabled: nothing halts it (a later halt is a change)."""
        self.halts[i] = None

    def stop(self, now: float) -> None:
        """From `now` on, every row's command ramps from its last value to 0 at the row's
        acceleration limit, whatever the law says (the shell is gone: stop the machine)."""
        if self._stop is None:
            self._stop = (now, list(self.commands))

    @property
    def stopping(self) -> bool:
        return self._stop is not None

    def step(self, statuses: Sequence[Any], running: Sequence[bool], now: float) -> LoopStep:
        """One step at `now` (monotonic s): `statuses[i]` is row i's drive status snapshot
        (a `DriveStatus` or anything with its fields; None before the first), `running[i]`
        whether row i takes part."""
        if len(statuses) != len(self.halts) or len(running) != len(self.halts):
            raise ValueError(f'RowLoop.step: {len(self.halts)} rows, got {len(statuses)} '
                             f'statuses and {len(running)} running flags')
        rows = []
        for i, (status, runs) in enumerate(zip(statuses, running)):
            if not runs or status is None:
                rows.append(RowStep(0.0, self.halts[i], False, bool(runs) and status is not None))
                continue
            rows.append(self._step_row(i, status, now))
        heartbeat = any(row.running for row in rows) and (
            now - self._last_heartbeat >= self.heartbeat_period)
        if heartbeat:
            self._last_heartbeat = now
        return LoopStep(tuple(rows), heartbeat)

    def _step_row(self, i: int, status: Any, now: float) -> RowStep:
        law = self.machine.laws[i]
        if sync_status.has_feedback(status):
            law.feedback(status.position, status.velocity, status.stamp)
        halt = sync_status.halt_reason(status, self.heartbeat_timeout)
        changed = halt != self.halts[i]
        self.halts[i] = halt
        if self._stop is not None:
            t_stop, commands = self._stop
            ramp = law.config.max_acceleration * max(now - t_stop, 0.0)
            command = max(commands[i] - ramp, 0.0) if halt is None else 0.0
            law.halt(now)
        elif halt is None:
            command = law.command(now)
        else:
            command = 0.0
            law.halt(now)
        self.commands[i] = command
        return RowStep(command, halt, changed, True)
