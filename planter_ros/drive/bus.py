"""One CAN bus with its canopen Network, the master's heartbeat and the SYNC producer.

`CanopenBus` owns the python-can bus and the Network (its notifier thread runs every drive's
callbacks); the drives on it (`Cia402Drive`) add their nodes and never open or close it.

SYNC (COB-ID 80h) comes from one place per bus. While the control loop runs it sends the SYNC
itself, one per step (`send_sync`, exact timing: the targets follow it). Before and between the
loop's steps a drive still needs SYNC: a strict CiA 301 drive sends a synchronous TPDO only
after a SYNC and acts on a synchronous RPDO only at the next one, so enabling it, homing it,
configuring it again after a power cycle and shutting it down all wait on SYNC. For those the
bus has `start_up_sync()`: while any caller holds it and the loop does not produce SYNC
(`loop_sync(False)`), a thread of this process sends one every `sync_period`, from before the
NMT start until the hold ends. A thread, not `send_periodic` (on SocketCAN a kernel job that
goes on for a hung process): it stops with the process.
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
import threading
import time

import can
import canopen

from . import objects as od
from .config import BusConfig
from .errors import BusError, NotConnectedError, bus_error, can_calls

__all__ = ['CanopenBus', 'ReceiveErrors']


class ReceiveErrors(can.Listener):
    """Keeps the Network's notifier thread alive through receive errors (bus-off, an
    interface gone down): python-can's notifier ends its thread on an error no listener
    handles, and then no frame of any drive would arrive again. Counted; the error is taken off
    the notifier (canopen's `send_message` raises a notifier's error on every later send); the
    thread waits a little before it reads again (no busy loop while the bus is off)."""

    PAUSE = 0.02        # s between reads while receiving fails

    def __init__(self) -> None:
        self.count = 0
        self.last: tuple[float, str] | None = None      # (monotonic s, text)
        self.notifier: can.Notifier | None = None

    def on_message_received(self, msg: can.Message) -> None:
        pass

    def on_error(self, exc: Exception) -> None:
        self.count += 1
        self.last = (time.monotonic(), f'{type(exc).__name__}: {exc}')
        if self.notifier is not None and self.notifier.exception is exc:
            self.notifier.exception = None
        time.sleep(self.PAUSE)


class CanopenBus:
    """One python-can bus with its canopen Network, the master's heartbeat and SYNC (module
    doc). Uses the bus fields of `config`; `bus` = an open python-can bus to use (left open on
    close)."""

    def __init__(self, config: BusConfig, bus: can.BusABC | None = None) -> None:
        self.config = config
        self._given_bus = bus
        self._bus: can.BusABC | None = None
        self.network: canopen.Network | None = None
        self._lock = threading.Lock()
        #: receive errors survived by the notifier thread (bus-off, interface down)
        self.receive_errors = ReceiveErrors()
        #: SYNC frames sent (by the loop and the start-up producer) and the last one's instant
        self.syncs_sent = 0
        self.last_sync = -float('inf')
        self._sync = threading.Condition()
        self._holds = 0
        self._loop_sync = False
        self._producer: threading.Thread | None = None

    @property
    def where(self) -> str:
        return f'{self.config.can_interface}:{self.config.can_channel}'

    def open(self) -> canopen.Network:
        """Open the bus and start the Network (idempotent). Raises BusError."""
        with self._lock:
            if self.network is not None:
                return self.network
            cfg = self.config
            with can_calls(f'open bus: {self.where}'):
                self._bus = self._given_bus or can.Bus(
                    interface=cfg.can_interface, channel=cfg.can_channel, bitrate=cfg.can_bitrate)
            network = canopen.Network(self._bus)
            network.NOTIFIER_CYCLE = 0.05                 # close() waits at most this long
            network.connect()
            notifier = network.notifier
            if notifier is None:                          # connect() always starts one
                raise BusError(f'open bus: {self.where}: canopen started no notifier')
            notifier.add_listener(self.receive_errors)
            self.receive_errors.notifier = notifier
            self.network = network
            return network

    def _send(self, what: str, cob_id: int, data: bytes) -> None:
        network = self.network
        if network is None:
            raise NotConnectedError(f'CAN bus {self.where}: not open (no {what} sent)')
        try:
            network.send_message(cob_id, data)
        except Exception as exc:            # (the text is made only on a failure: hot path)
            raise bus_error(exc, f'CAN send of {what} failed on {self.where}') from None

    def send_heartbeat(self) -> None:
        """Our heartbeat frame (NMT state operational), for every drive's consumer.
        NON-BLOCKING. Raises NotConnectedError before open(), BusError on a send error."""
        self._send('heartbeat', od.heartbeat_cob(self.config.master_node_id), b'\x05')

    def send_sync(self) -> None:
        """One SYNC frame (COB-ID 80h, no data): the drives act on the synchronous RPDOs
        received since the last one and send their synchronous TPDOs. NON-BLOCKING; raises
        NotConnectedError / BusError."""
        self._send('SYNC', od.SYNC_COB, b'')
        self.syncs_sent += 1
        self.last_sync = time.monotonic()

    # ---------------------------------------------------------------- the start-up SYNC
    def loop_sync(self, on: bool) -> None:
        """The control loop produces SYNC from now on (`on`), or no longer: the start-up
        producer stays silent meanwhile."""
        with self._sync:
            self._loop_sync = bool(on)
            self._sync.notify_all()

    @contextmanager
    def start_up_sync(self) -> Iterator[None]:
        """SYNC every `sync_period` while this is held and the loop produces none (module doc).
        Re-entrant and shared: one producer per bus however many drives hold it."""
        with self._sync:
            self._holds += 1
            if self._producer is None or not self._producer.is_alive():
                self._producer = threading.Thread(target=self._produce, daemon=True,
                                                  name='start-up-sync')
                self._producer.start()
            self._sync.notify_all()
        try:
            yield
        finally:
            with self._sync:
                self._holds -= 1
                self._sync.notify_all()

    @property
    def producing_sync(self) -> bool:
        """The start-up producer is sending (held, and the loop produces none)."""
        return self._holds > 0 and not self._loop_sync

    def _produce(self) -> None:
        period = self.config.sync_period
        while True:
            with self._sync:
                while self._holds > 0 and self._loop_sync:
                    self._sync.wait(0.1)
                if self._holds <= 0 or self.network is None:
                    self._producer = None
                    return
                wait = self.last_sync + period - time.monotonic()
                if wait > 0:
                    self._sync.wait(wait)
                    continue
            try:
                self.send_sync()
            except (BusError, NotConnectedError):
                time.sleep(period)             # a bus-off or closed bus: try again later

    def close(self) -> None:
        """Stop the Network's notifier; shut the bus down if this object opened it."""
        with self._lock:
            network, self.network = self.network, None
            if network is not None and network.notifier is not None:
                network.notifier.stop(1.0)
            if self._given_bus is None and self._bus is not None:
                self._bus.shutdown()
            self._bus = None
        with self._sync:
            self._sync.notify_all()
