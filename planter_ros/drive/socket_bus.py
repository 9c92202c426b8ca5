"""A python-can bus over a local socket pair: CAN frames between two processes on one host.

python-can's `virtual` interface reaches only its own process. The command process and the
simulated drives must run in processes of their own (so a drive sees the master's stalls as a
real drive would: its own clock, its own GIL), so the frames cross a Unix-domain
`SOCK_SEQPACKET` socket pair: the kernel keeps each frame one packet (no framing code, no
partial reads), nothing leaves the host, and either end sees the other's death as end-of-file.
It joins exactly two ends (the master and one process holding every simulated drive of the
bus, as `SimulatedBus` does), which is what a test or the demo needs; a real machine uses
`socketcan`.

python-can accepts a new interface name only through a package entry point, so this bus is
not opened by name: the command process builds it itself when its settings say
``can_interface: planter_socketpair`` (the channel is the file descriptor of its end of the
pair, inherited) and hands the bus object to the master, as tests do with a virtual bus.
A frame is 22 bytes: send time (wall clock, as python-can stamps), arbitration id, DLC, flags
(extended id, remote, error), 8 data bytes.
"""
from __future__ import annotations

import select
import socket
import struct
import time
from typing import TYPE_CHECKING

import can

if TYPE_CHECKING:
    from can.typechecking import CanFilters

__all__ = ['INTERFACE', 'SocketPairBus', 'socket_pair']

INTERFACE = 'planter_socketpair'
_FRAME = struct.Struct('<dIBB8s')
_EXTENDED, _REMOTE, _ERROR = 1, 2, 4


def socket_pair() -> tuple[socket.socket, socket.socket]:
    """Two connected ends (SOCK_SEQPACKET, Unix domain), inheritable by a child process."""
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    for end in (a, b):
        end.set_inheritable(True)
    return a, b


class SocketPairBus(can.BusABC):
    """One end of a CAN socket pair. `channel`: a socket, or its file descriptor (int or text).
    A send that finds the peer's queue full raises CanOperationError (as SocketCAN's ENOBUFS);
    the peer gone raises CanOperationError on send and receive."""

    def __init__(self, channel: socket.socket | int | str, can_filters: CanFilters | None = None,
                 **kwargs: object) -> None:

        if isinstance(channel, socket.socket):
            sock = channel
        else:
            sock = socket.socket(fileno=int(channel))
        sock.setblocking(False)
        self._sock = sock
        self.channel_info = f'socket pair fd {sock.fileno()}'
        super().__init__(channel=str(sock.fileno()), can_filters=can_filters, **kwargs)

    def fileno(self) -> int:
        return self._sock.fileno()

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        flags = ((_EXTENDED if msg.is_extended_id else 0) | (_REMOTE if msg.is_remote_frame else 0)
                 | (_ERROR if msg.is_error_frame else 0))
        packet = _FRAME.pack(time.time(), msg.arbitration_id, msg.dlc, flags,
                             bytes(msg.data).ljust(8, b'\0'))
        try:
            self._sock.send(packet)
            return
        except BlockingIOError:
            if not timeout:
                raise can.CanOperationError('socket pair: transmit queue full') from None
        except OSError as exc:
            raise can.CanOperationError(f'socket pair: {exc}') from None
        _, writable, _ = select.select([], [self._sock], [], timeout)
        if not writable:
            raise can.CanOperationError('socket pair: transmit queue full')
        try:
            self._sock.send(packet)
        except OSError as exc:
            raise can.CanOperationError(f'socket pair: {exc}') from None

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        try:
            packet = self._sock.recv(64)
        except BlockingIOError:
            if timeout == 0:
                return None, False
            readable, _, _ = select.select([self._sock], [], [], timeout)
            if not readable:
                return None, False
            try:
                packet = self._sock.recv(64)
            except BlockingIOError:
                return None, False
            except OSError as exc:
                raise can.CanOperationError(f'socket pair: {exc}') from None
        except OSError as exc:
            raise can.CanOperationError(f'socket pair: {exc}') from None
        if not packet:
            raise can.CanOperationError('socket pair: the other end closed')
        stamp, can_id, dlc, flags, data = _FRAME.unpack(packet)
        return can.Message(timestamp=stamp, arbitration_id=can_id, dlc=dlc,
                           data=data[:dlc], is_extended_id=bool(flags & _EXTENDED),
                           is_remote_frame=bool(flags & _REMOTE),
                           is_error_frame=bool(flags & _ERROR), channel=self.channel_info,
                           is_rx=True), False

    def shutdown(self) -> None:
        super().shutdown()
        try:
            self._sock.close()
        except OSError:
            pass

