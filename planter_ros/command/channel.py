"""The local channel between the ROS shell (sync_node) and the command process: JSON messages
`[kind, payload]` over one end of a Unix-domain SOCK_SEQPACKET socket pair (one message = one
packet, nothing leaves the host, a dead peer reads as end-of-file).

Two kinds of sending, as the command path needs them:
* `send(kind, payload, latest=True)` (ground speed): never waits and never queues; when the
  peer's buffer is full the value is dropped (counted in `dropped`): the next one supersedes it.
* `send(kind, payload)` (designs, sections, resets, replies, diagnostics): never lost; queued
  in order when the peer's buffer is full and sent before anything newer (`flush`).
The receiver takes every waiting message at once (`receive`); of several ground-speed samples
it uses the newest; it reads every message the peer sent before it went, even after a send to
the gone peer failed, then end-of-file.

The side that ends the channel on purpose (the command process) ends it with `finish()`: its
queued messages out, no more input (SHUT_RD), its unread input dropped, then closed. A plain
close with unread input makes the kernel report "connection reset" to the peer *before* the
messages still waiting for it: a final report and the reason of a deliberate exit would be lost.
"""
from __future__ import annotations

from collections import deque
import json
import select
import socket
import time
import threading
from typing import Any

from planter_ros.errors import PlanterError

__all__ = ['ChannelClosed', 'Channel', 'MAX_MESSAGE']

MAX_MESSAGE = 1 << 18          # bytes; a diagnostics array of 8 rows is about 10 kB


class ChannelClosed(PlanterError, ConnectionError):
    """The other end is gone (closed, or its process died)."""


class Channel:
    """One end of the shell <-> command process channel (see the module doc). Thread-safe for
    one receiving thread and any number of sending threads."""

    def __init__(self, sock: socket.socket) -> None:
        sock.setblocking(False)
        self.sock = sock
        self._pending: deque[bytes] = deque()
        self._lock = threading.Lock()
        self.dropped = 0              # latest-value messages dropped (peer's buffer full)
        self.closed = False           # this end closed
        self.peer_gone = False        # a send found the peer gone

    def fileno(self) -> int:
        return self.sock.fileno()

    def send(self, kind: str, payload: Any = None, latest: bool = False) -> bool:
        """Send one message (see the module doc); False when a latest-value one was dropped.
        Raises ChannelClosed when the peer is gone."""
        data = json.dumps([kind, payload], separators=(',', ':')).encode()
        if len(data) > MAX_MESSAGE:
            raise ValueError(f'channel message {kind!r} of {len(data)} bytes is too long: '
                             f'allowed <= {MAX_MESSAGE}')
        with self._lock:
            self._flush_locked()
            if latest:
                if self._pending:
                    self.dropped += 1
                    return False
                try:
                    self.sock.send(data)
                except BlockingIOError:
                    self.dropped += 1
                    return False
                except OSError as exc:
                    raise self._closed(exc) from None
                return True
            self._pending.append(data)
            self._flush_locked()
            return True

    def flush(self) -> None:
        """Send what waits (reliable messages the peer had no room for)."""
        with self._lock:
            self._flush_locked()

    @property
    def waiting(self) -> int:
        return len(self._pending)

    def _flush_locked(self) -> None:
        while self._pending:
            try:
                self.sock.send(self._pending[0])
            except BlockingIOError:
                return
            except OSError as exc:
                raise self._closed(exc) from None
            self._pending.popleft()

    def _closed(self, exc: BaseException | None = None) -> ChannelClosed:
        self.peer_gone = True
        return ChannelClosed(f'channel closed ({exc})' if exc else 'channel closed')

    def receive(self, timeout: float | None) -> list[tuple[str, Any]]:
        """Every waiting message, waiting up to `timeout` s for the first (None: forever).
        Raises ChannelClosed at end-of-file (or once this end is closed)."""
        if self.closed:
            raise ChannelClosed('channel closed')
        if self._pending and not self.peer_gone:
            try:
                self.flush()
            except ChannelClosed:
                pass                   # what the peer sent before it went is still read
        out: list[tuple[str, Any]] = []
        readable, _, _ = select.select([self.sock], [], [], timeout)
        if not readable:
            return out
        while True:
            try:
                data = self.sock.recv(MAX_MESSAGE)
            except BlockingIOError:
                return out
            except OSError as exc:
                raise self._closed(exc) from None
            if not data:
                if out:
                    return out          # the end-of-file is seen by the next call
                raise self._closed()
            kind, payload = json.loads(data)
            out.append((kind, payload))

    def drain(self, timeout: float) -> bool:
        """Wait up to `timeout` s until every queued message is sent (before a close: a final
        report queued because the peer's buffer was full is not lost); True when none waits.
        Raises ChannelClosed when the peer is gone."""
        deadline = time.monotonic() + timeout
        while True:
            self.flush()
            if not self._pending:
                return True
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            select.select([], [self.sock], [], min(remaining, 0.05))

    def finish(self, timeout: float) -> None:
        """End the channel on purpose (see the module doc): what is queued is sent (up to
        `timeout` s), no more input is taken, the unread input is dropped, then it closes."""
        try:
            self.drain(timeout)
        except ChannelClosed:
            pass
        try:
            self.sock.shutdown(socket.SHUT_RD)
            while self.sock.recv(MAX_MESSAGE):
                pass
        except OSError:                # nothing left to read (or the peer is gone)
            pass
        self.close()

    def close(self) -> None:
        self.closed = True
        try:
            self.sock.close()
        except OSError:
            pass
