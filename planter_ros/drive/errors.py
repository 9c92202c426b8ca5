"""The drive's exception family: one base, one subclass per way a drive operation fails, so a
caller reacts to the kind of failure, never to the wording. Every message is one line; the
facts a program acts on are attributes: the drive's `node` id, the object (`index`,
`subindex`) a failed SDO transfer was about and the drive's SDO `abort_code` (CiA 301), each
None when it does not apply.

`sdo_error` is the one place an SDO transfer's failure becomes a drive error:

* no answer (canopen's `SdoCommunicationError`): `DriveTimeoutError`;
* the drive aborts because the object or sub-index does not exist (06020000h, 06090011h): a
  `DictionaryError` naming the object: the drive is not what its EDS describes;
* any other abort (`SdoAbortedError`): `DriveRefusedError` with the abort's code and text;
* anything else (python-can failing to send: CanError, OSError, ValueError ...): `BusError`.

`bus_error` is the one place a python-can failure becomes a `BusError` (opening the bus, a frame
sent, an NMT command, an SDO transfer's send); `can_calls` applies it to a block of python-can
calls.
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from planter_ros.config import ConfigError
from planter_ros.errors import PlanterError

__all__ = ['NO_SUCH_OBJECT', 'BusError', 'DictionaryError', 'DriveConfigError', 'DriveError',
           'DriveRefusedError', 'DriveTimeoutError', 'NotConnectedError', 'SdoTransfer',
           'bus_error', 'can_calls', 'sdo_error']

# CiA 301 SDO abort codes of an entry the drive does not have: object, sub-index
NO_SUCH_OBJECT = (0x06020000, 0x06090011)


class DriveError(PlanterError, RuntimeError):
    """A drive operation failed (base of the family)."""

    node: int | None = None            # the drive's CANopen node id
    index: int | None = None           # the object a failed SDO transfer was about
    subindex: int | None = None
    abort_code: int | None = None      # the drive's SDO abort code (CiA 301), when it aborted

    def __init__(self, *args: object, node: int | None = None, index: int | None = None,
                 subindex: int | None = None, abort_code: int | None = None,
                 **facts: Any) -> None:
        super().__init__(*args, **facts)
        for name, given in (('node', node), ('index', index), ('subindex', subindex),
                            ('abort_code', abort_code)):
            if given is not None:
                setattr(self, name, given)


class DriveConfigError(DriveError, ConfigError):
    """A drive setting out of range (before anything touches the bus)."""


class NotConnectedError(DriveError):
    """A command before connect_and_enable() succeeded, or after shutdown()."""


class BusError(DriveError):
    """The CAN bus could not be opened, or a frame could not be sent."""


class DriveTimeoutError(DriveError):
    """The drive did not answer (SDO) or did not reach a state in time."""


class DriveRefusedError(DriveError):
    """The drive answered no: an SDO abort, or it is not the drive the configuration says
    (device type, operation modes, encoder resolution)."""


class DictionaryError(DriveConfigError):
    """The drive's EDS/DCF cannot be read, or lacks what the row's mode needs: one line naming
    the object, what it is for and what to do (before anything moves)."""


def bus_error(exc: BaseException, what: str, node: int | None = None,
              **facts: Any) -> BusError:
    """The BusError python-can's failure `exc` means (it raises CanError, OSError, ValueError
    ...), one line: `<what>: <exception type>: <text>`."""
    return BusError(f'{what}: {type(exc).__name__}: {exc}', node=node, **facts)


@contextmanager
def can_calls(what: str, node: int | None = None) -> Iterator[None]:
    """Around python-can calls: any exception they raise leaves as `bus_error(exc, what,
    node)`."""
    try:
        yield
    except Exception as exc:
        raise bus_error(exc, what, node) from None


@dataclass(frozen=True)
class SdoTransfer:
    """One SDO transfer, as its failure names it: the drive's `node`, the `step` of the
    master's work, `verb` 'reading' or 'writing', the object (`index`, `subindex`, `name`),
    `waited` how long and how often the master asked (the text after "no SDO answer ..."),
    `bus` the interface:channel a reader is asked to check."""

    node: int
    step: str
    verb: str
    index: int
    subindex: int = 0
    name: str = ''
    waited: str = ''
    bus: str = ''


def sdo_error(exc: BaseException, transfer: SdoTransfer) -> DriveError:
    """The drive error an SDO transfer's exception `exc` means (module doc), one line:
    `drive node <node>: <step>: ...`."""
    # lazy: canopen costs 70-120 ms (python -X importtime) and this module is read by every
    # user of a drive setting (replay and analyze: test_offline_imports); an SDO exception to
    # map means canopen is loaded already
    from canopen.sdo import SdoAbortedError, SdoCommunicationError
    t = transfer
    head = f'drive node {t.node}: {t.step}: '
    obj = f'0x{t.index:04X}' + (f':{t.subindex}' if t.subindex else '')
    facts: dict[str, Any] = {'node': t.node, 'index': t.index, 'subindex': t.subindex}
    if isinstance(exc, SdoCommunicationError):
        where = (f'is the drive on {t.bus} as node {t.node}? ' if t.verb == 'reading' and t.bus
                 else '')
        return DriveTimeoutError(f'{head}no SDO answer {t.verb} 0x{t.index:04X}{t.waited} '
                                 f'({where}{exc})', **facts)
    if isinstance(exc, SdoAbortedError):
        if exc.code in NO_SUCH_OBJECT:
            return DictionaryError(f'{head}the drive has no {obj} {t.name} ({exc}) although '
                                   'its EDS lists it: use the EDS of this drive and firmware',
                                   abort_code=exc.code, **facts)
        return DriveRefusedError(f'{head}drive refused {t.verb} {obj} ({exc})',
                                 abort_code=exc.code, **facts)
    return bus_error(exc, f'{head}CAN send failed', **facts)
