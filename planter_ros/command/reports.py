"""Typed messages between the command process, its shell (sync_node) and the demo.

The command engine builds these dataclasses where it makes the figures (a missing field fails
there, not at the end of a run); they cross the command process's channel as plain data
(`to_data()`, JSON) and are built again at the shell (`from_data()`), where a missing or misspelt
field is an error naming the field (`ReportError`), never a `KeyError` later:

* `Reply`: the answer to a request (a section switch, a fault reset, an operator's enable);
* `Snapshot` (+ `RowSnapshot`): each row's command, speed and state, sent every control period
  for the demo's progress lines;
* `Ready`: the command process runs (or, held, waits for an operator): its rows, mode, pid,
  what real time it was refused;
* `CommandReport` (+ `RowReport`, `Recovery`): the run's figures from the command path
  (`final`), built by `CommandEngine.final_report()`;
* `CommandExit`: why the command process ended (`exit`), sent just before it closes its
  channel: a deliberate exit ('stop': its shell asked; 'SIGTERM' / 'SIGINT': a stop signal
  reached it) is never taken for a crash, so nothing restarts it.

Pure: no ROS, no CAN import.
"""
from __future__ import annotations

from collections.abc import Callable
import copy
from dataclasses import MISSING, dataclass, field, fields
import functools
import typing
from typing import Any, TypeVar

from planter_ros.errors import PlanterError

__all__ = ['EXIT_REASONS', 'CommandExit', 'CommandReport', 'Ready', 'Recovery', 'Reply',
           'ReportError', 'RowReport', 'RowSnapshot', 'Snapshot', 'from_data']

# why a command process ends on purpose ('orphaned' is never sent: its shell is gone)
EXIT_REASONS = ('stop', 'SIGTERM', 'SIGINT', 'start failed')

T = TypeVar('T')


class ReportError(PlanterError, ValueError):
    """A message that is not the report it claims to be (one line: the type and the field)."""


def from_data(cls: type[T], data: Any) -> T:
    """The dataclass `cls` from plain data: every field without a default must be there
    (ReportError naming it), nested dataclasses and lists or tuples of them are built too,
    keys the class does not know are ignored (a newer sender)."""
    if not isinstance(data, dict):
        raise ReportError(f'{cls.__name__}: expected a mapping, got {type(data).__name__}')
    values = {}
    for name, required, convert in _fields(cls):
        if name not in data:
            if required:
                raise ReportError(f'{cls.__name__}: no {name!r}')
            continue
        values[name] = data[name] if convert is None else convert(data[name])
    return cls(**values)


_FIELDS: dict[type, tuple[tuple[str, bool, Callable[[Any], Any] | None], ...]] = {}


def _fields(cls: type) -> tuple[tuple[str, bool, Callable[[Any], Any] | None], ...]:
    """(name, required, conversion: None for a value taken as it is) of each field (type hints
    resolved and the conversion chosen once per class: the shell reads a snapshot every
    control period)."""
    known = _FIELDS.get(cls)
    if known is None:
        hints = typing.get_type_hints(cls)
        known = _FIELDS[cls] = tuple(
            (f.name, f.default is MISSING and f.default_factory is MISSING,
             _converter(hints[f.name]))
            for f in fields(cls))
    return known


def _converter(hint: Any) -> Callable[[Any], Any] | None:
    """How a field of type `hint` is built from plain data (None: the value as it is)."""
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if isinstance(hint, type) and hasattr(hint, '__dataclass_fields__'):
        return functools.partial(from_data, hint)
    if origin in (list, tuple) and args and hasattr(args[0], '__dataclass_fields__'):
        return functools.partial(_items, origin, args[0])
    if origin is tuple:
        return _tuple
    return None


def _items(container: type, item: type, value: Any) -> Any:
    if not isinstance(value, (list, tuple)):
        raise ReportError(f'{item.__name__}: expected a list, got {type(value).__name__}')
    return container(from_data(item, element) for element in value)


def _tuple(value: Any) -> Any:
    return tuple(value) if isinstance(value, list) else value     # JSON has lists only


# values to_data() takes as they are (dataclasses.asdict deep-copies them: the same object)
_ATOMIC = frozenset({str, int, float, bool, type(None)})
_NAMES: dict[type, tuple[str, ...]] = {}


def _plain(value: Any) -> Any:
    """dataclasses.asdict's result for `value` without its per-value deep copy of atoms:
    dataclasses as dicts of their fields, lists, tuples (named ones too) and dicts rebuilt,
    any other value deep-copied."""
    kind = type(value)
    if kind in _ATOMIC:
        return value
    if hasattr(kind, '__dataclass_fields__'):
        names = _NAMES.get(kind)
        if names is None:
            names = _NAMES[kind] = tuple(f.name for f in fields(value))
        return {name: _plain(getattr(value, name)) for name in names}
    if isinstance(value, tuple) and hasattr(value, '_fields'):
        return kind(*[_plain(v) for v in value])
    if isinstance(value, (list, tuple)):
        return kind(_plain(v) for v in value)
    if isinstance(value, dict):
        return kind((_plain(k), _plain(v)) for k, v in value.items())
    return copy.deepcopy(value)


class _Data:
    """to_data() / from_data() of a message dataclass."""

    def to_data(self) -> dict[str, Any]:
        """Plain data for the channel (JSON)."""
        return _plain(self)

    @classmethod
    def from_data(cls: type[T], data: Any) -> T:
        return from_data(cls, data)


@dataclass(frozen=True)
class Reply(_Data):
    """The answer to a request: whether it was done, in one line, and whether it changed
    anything (a section that was already so: False)."""

    ok: bool
    message: str
    changed: bool = False


@dataclass(frozen=True)
class RowSnapshot(_Data):
    """One row with a drive, as the last control step left it."""

    label: str
    command: float                     # rad/s
    velocity: float                    # rad/s measured (0 before any status)
    state: str                         # CiA 402 state ('-' before any status)
    running: bool


@dataclass(frozen=True)
class Snapshot(_Data):
    """What the demo's progress lines show: each row's command, speed and state, and the
    spacing in force (m; None before a design)."""

    rows: tuple[RowSnapshot, ...] = ()
    spacing: float | None = None


@dataclass(frozen=True)
class Ready(_Data):
    """The command process is built and its drives enabled (`ready`) or held for an operator
    (`held`: running 0, mode '')."""

    pid: int
    priority: int                      # SCHED_FIFO priority asked
    realtime: tuple[str, ...] = ()     # what real time it was refused, in words
    running: int = 0                   # rows whose drives run
    mode: str = ''                     # the CiA 402 mode, in words


@dataclass(frozen=True)
class Recovery(_Data):
    """A row's halt, closed once the row was back in step (or after recovery.EPISODE_LIMIT)."""

    cause: str                         # the first halt's text
    restarted: bool                    # the drive restarted during it
    bus: bool                          # it began while (or just after) the bus failed
    halted_s: float                    # s from the halt until the drive was commanded again
    back_in_step_s: float              # s from the halt until back on its grid
    plants_missed: int
    in_step: bool                      # False: closed at the limit, not back in step
    auto_resets: int = 0


@dataclass
class RowReport(_Data):
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
    recoveries: list[Recovery] = field(default_factory=list)


@dataclass
class CommandReport(_Data):
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


@dataclass(frozen=True)
class CommandExit(_Data):
    """Why the command process ended on purpose (one of EXIT_REASONS) and whether its drives
    were enabled at any time (False: it never enabled them)."""

    reason: str
    enabled: bool = True

    @classmethod
    def from_data(cls, data: Any) -> CommandExit:
        exit_ = from_data(cls, data)
        if exit_.reason not in EXIT_REASONS:
            raise ReportError(f'CommandExit: reason {exit_.reason!r}: allowed '
                              f'{", ".join(EXIT_REASONS)}')
        return exit_
