"""Typed messages between the command process, its shell (sync_node) and the demo.

The command process sends plain data over its channel (JSON); the shell turns what matters for
a run's end into these dataclasses at the boundary, so a missing or misspelt field is an error
there, naming the field (`ReportError`), never a `KeyError` at the end of a run:

* `CommandReport` (+ `RowReport`): the run's figures from the command path (`final`), built
  from `CommandEngine.final_report()`;
* `CommandExit`: why the command process ended (`exit`), sent just before it closes its
  channel: a deliberate exit ('stop': its shell asked; 'SIGTERM' / 'SIGINT': a stop signal
  reached it) is never taken for a crash, so nothing restarts it.

Pure: no ROS, no CAN import.
"""
from __future__ import annotations

from dataclasses import MISSING, dataclass, field, fields
import typing
from typing import Any

from planter_ros.errors import PlanterError

__all__ = ['EXIT_REASONS', 'CommandExit', 'CommandReport', 'ReportError', 'RowReport',
           'from_data']

# why a command process ends on purpose ('orphaned' is never sent: its shell is gone)
EXIT_REASONS = ('stop', 'SIGTERM', 'SIGINT', 'start failed')


class ReportError(PlanterError, ValueError):
    """A message that is not the report it claims to be (one line: the type and the field)."""


def from_data(cls: type, data: Any) -> Any:
    """The dataclass `cls` from plain data: every field without a default must be there
    (ReportError naming it), nested dataclasses and lists of them are built too, keys the
    class does not know are ignored (a newer sender)."""
    if not isinstance(data, dict):
        raise ReportError(f'{cls.__name__}: expected a mapping, got {type(data).__name__}')
    hints = typing.get_type_hints(cls)
    values = {}
    for f in fields(cls):
        if f.name not in data:
            if f.default is MISSING and f.default_factory is MISSING:
                raise ReportError(f'{cls.__name__}: no {f.name!r}')
            continue
        values[f.name] = _convert(hints[f.name], data[f.name])
    return cls(**values)


def _convert(hint: Any, value: Any) -> Any:
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if isinstance(hint, type) and hasattr(hint, '__dataclass_fields__'):
        return from_data(hint, value)
    if origin is list and args and hasattr(args[0], '__dataclass_fields__'):
        return [from_data(args[0], item) for item in value]
    return value


@dataclass
class RowReport:
    """One row's figures from the command path."""

    label: str
    faults: int
    last_fault: str
    left_out: str
    loop: dict                         # PeriodStats.summary() of its command frames
    plants_missed: int = 0
    restarts: int = 0
    auto_resets: int = 0
    emcy: int = 0
    recoveries: list = field(default_factory=list)


@dataclass
class CommandReport:
    """The run's figures from the command path (CommandEngine.final_report)."""

    accepted: int                      # ground-speed samples
    rejected: dict                     # reason -> count
    yaw_accepted: int
    yaw_rejected: dict
    phase_slips: int
    send_errors: int
    phase_lock: bool
    turn_compensation: bool
    rows: list[RowReport]
    loop: dict                         # every row's command gaps, PeriodStats.summary()
    command_timeout: float             # s, the drives' RPDO deadline
    receive_errors: int = 0
    loop_histogram: dict = field(default_factory=dict)
    sample_to_frame: dict = field(default_factory=dict)
    sample_to_frame_histogram: dict = field(default_factory=dict)
    sync: dict = field(default_factory=dict)
    sync_histogram: dict = field(default_factory=dict)
    csp: bool = False

    @classmethod
    def from_data(cls, data: dict) -> CommandReport:
        return from_data(cls, data)


@dataclass(frozen=True)
class CommandExit:
    """Why the command process ended on purpose (one of EXIT_REASONS) and whether its drives
    were enabled at any time (False: it never enabled them)."""

    reason: str
    enabled: bool = True

    @classmethod
    def from_data(cls, data: dict) -> CommandExit:
        exit_ = from_data(cls, data)
        if exit_.reason not in EXIT_REASONS:
            raise ReportError(f'CommandExit: reason {exit_.reason!r}: allowed '
                              f'{", ".join(EXIT_REASONS)}')
        return exit_
