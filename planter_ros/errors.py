"""The root of every error planter_ros raises: `PlanterError`.

Every error the product raises on purpose is a PlanterError with a one-line message that names
what is wrong (the value, the file, the drive) and what is allowed, so a command line prints it
as is and exits 2, and a node refuses the parameter or the message with it. Catch PlanterError
for "planter_ros refused or failed, and said why in one line"; catch a family, or one class of
it, to act on that case only. The families live next to the code that raises them:

* `config.ConfigError`: a value outside its allowed domain (and its kin: `kinematics.DesignError`,
  `scene.SceneError`, `plausibility.PlausibilityError`, `cam.CamInputError`, ...);
* `drive.errors.DriveError`: a drive operation that failed (bus, timeout, refusal, dictionary);
* `recording.errors.RecordingError`: a recording that cannot be read, replayed or written;
* `cam.CamError`, `output_files.OutputError`, `commission.CommissionError`, and the few
  single-class ones of the command line, the analysis engine and the processes.

Each class keeps the builtin base its callers caught before there was a root (a ConfigError is
a ValueError, a DriveError a RuntimeError, ChannelClosed a ConnectionError): the root is added
beside it, never instead of it.

The facts a program acts on are attributes, not words to parse: `where` (the option, parameter,
file or object the error is about), `value` (what was given or found) and `limit` (what is
allowed); each is None when it does not apply. A family adds its own (a DriveError's drive node,
object and SDO abort code). Every attribute survives pickling (an error raised in a worker
process reaches its parent whole), whatever the class's own constructor takes.

Standard library only (layer 0): every package may import it.
"""
from __future__ import annotations

from typing import Any

__all__ = ['PlanterError']


class PlanterError(Exception):
    """Anything planter_ros refuses or fails at; the message is one line (module doc)."""

    where: str | None = None     # the option, parameter, file or object it is about
    value: object = None         # what was given or found
    limit: object = None         # what is allowed (a range, a maximum, the choices)

    def __init__(self, *args: object, where: str | None = None, value: object = None,
                 limit: object = None) -> None:
        super().__init__(*args)
        # only the facts given become instance attributes: a subclass that set its own before
        # calling this keeps them
        if where is not None:
            self.where = where
        if value is not None:
            self.value = value
        if limit is not None:
            self.limit = limit

    def __reduce__(self) -> tuple[Any, ...]:
        # BaseException pickles as cls(*args): wrong for a class whose constructor takes its
        # facts (DesignError(parameter, value, allowed)); rebuilt from args and attributes
        return _rebuilt, (type(self), self.args, dict(self.__dict__))


def _rebuilt(cls: type[PlanterError], args: tuple[object, ...],
             state: dict[str, object]) -> PlanterError:
    """A pickled PlanterError back: its message arguments and attributes, no constructor run."""
    error = cls.__new__(cls, *args)
    error.args = args
    error.__dict__.update(state)
    return error
