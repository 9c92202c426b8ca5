"""SDO access to one drive, by the master's own object declarations (drive.objects): values are
encoded and decoded from their declared types, not from the EDS, so a read of an object the
file lacks still asks the drive, and nothing fails inside canopen's object lookup. Every
failure is one line in the right family (drive.errors.sdo_error: no answer, no such object,
any other abort, CAN send failed).

BLOCKING (each call waits for the drive's answer): never from a bus callback or the loop.
"""
from __future__ import annotations

import struct
from typing import TYPE_CHECKING, Literal, overload

from canopen.sdo import SdoAbortedError

from . import objects as od
from .errors import DriveError, SdoTransfer, sdo_error

if TYPE_CHECKING:
    from canopen import RemoteNode

    from .config import DriveConfig

__all__ = ['SDO_ATTEMPTS', 'Sdo']

SDO_ATTEMPTS = 2            # each SDO request is sent at most this often (sdo_timeout each)


class Sdo:
    """SDO reads and writes of one node (module doc)."""

    def __init__(self, node: RemoteNode, config: DriveConfig) -> None:
        self.node = node
        self.config = config
        node.sdo.RESPONSE_TIMEOUT = config.sdo_timeout
        node.sdo.MAX_RETRIES = SDO_ATTEMPTS             # a request or answer lost: asked again

    def fail(self, step: str, detail: str, kind: type[DriveError] = DriveError) -> DriveError:
        node = self.config.drive_node_id
        return kind(f'drive node {node}: {step}: {detail}', node=node)

    def _wait_text(self) -> str:
        return (f' within {SDO_ATTEMPTS} x {self.config.sdo_timeout:g} s (sdo_timeout, asked '
                f'{SDO_ATTEMPTS} times)')

    def _error(self, step: str, obj: od.Obj, verb: str, exc: Exception) -> DriveError:
        cfg = self.config
        return sdo_error(exc, SdoTransfer(cfg.drive_node_id, step, verb, obj.index, obj.subindex,
                                          obj.name, self._wait_text(),
                                          f'{cfg.can_interface}:{cfg.can_channel}'))

    @overload
    def read(self, step: str, obj: od.Obj, optional: Literal[False] = False) -> int: ...

    @overload
    def read(self, step: str, obj: od.Obj, optional: bool) -> int | None: ...

    def read(self, step: str, obj: od.Obj, optional: bool = False) -> int | None:
        """The value of `obj`; None for an `optional` one the drive does not have."""
        try:
            data = self.node.sdo.upload(obj.index, obj.subindex)
        except Exception as exc:             # python-can: CanError, OSError, ValueError...
            if optional and isinstance(exc, SdoAbortedError):
                return None
            raise self._error(step, obj, 'reading', exc) from None
        size = struct.calcsize('<' + obj.fmt)
        data = bytes(data[:size]).ljust(size, b'\xff' if data and data[-1] & 0x80
                                        and obj.fmt.islower() else b'\x00')
        value: int = struct.unpack('<' + obj.fmt, data)[0]      # every fmt of od is an integer
        return value

    def write(self, step: str, obj: od.Obj, value: int) -> None:
        """`obj` = `value` (expedited download of its declared type)."""
        try:
            data = struct.pack('<' + obj.fmt, value)
        except struct.error:
            raise self.fail(step, f'0x{obj.index:04X} {obj.name} = {value} is out of range '
                                  f'of {obj.type_name}', DriveError) from None
        try:
            self.node.sdo.download(obj.index, obj.subindex, data)
        except Exception as exc:             # python-can: CanError, OSError, ValueError...
            raise self._error(step, obj, 'writing', exc) from None
