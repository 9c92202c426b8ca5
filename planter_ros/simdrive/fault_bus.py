"""A python-can bus that has the faults a real CAN bus has, around any other python-can bus.

`FaultBus(bus, ...)` is a `can.BusABC` like the bus it wraps (a `virtual` bus, one end of a
`SocketPairBus`, a SocketCAN bus): the master or the simulated drives are handed it instead of
the bus and see, on demand:

* **frame loss** (`loss`, 0..1): each frame sent or received is lost with that probability,
  independently per direction and per COB-ID, from a seeded random stream per (direction,
  COB-ID): the k-th heartbeat of a node is lost or not whatever else the bus carries, so a run
  is reproducible although threads interleave differently. A lost send looks sent (no error:
  a CAN controller does not know a frame was not received).
* **send errors** (`send_error_rate`, 0..1): `send` raises `can.CanOperationError`, as
  SocketCAN's ENOBUFS (a full transmit queue) does.
* **a given frame lost** (`drop(can_id, count)`): the next `count` frames received with that
  COB-ID are lost (a boot-up message that never arrives); `drop(can_id, count, sent=True)`:
  the next `count` sent (an NMT command no drive heard).
* **bus-off** (`bus_off(seconds)`): for that long every send raises `CanOperationError`
  ('bus-off') and every receive raises it too (an interface gone down), then the bus is back
  (the controller's automatic restart, `restart-ms`). Nothing sent or received meanwhile.

Counts of what was done are kept (`counts`) so a test checks the faults really happened.
No fault is on unless asked for: `FaultBus(bus)` passes every frame.
"""
from __future__ import annotations

import random
import threading
import time
from typing import Any

import can

__all__ = ['FaultBus']


class FaultBus(can.BusABC):
    """`bus` with seeded frame loss, send errors and bus-off (see the module doc). `bus` is
    shut down with this one."""

    def __init__(self, bus: can.BusABC, loss: float = 0.0, send_error_rate: float = 0.0,
                 seed: int = 0, **kwargs: Any) -> None:
        for name, value in (('loss', loss), ('send_error_rate', send_error_rate)):
            if not 0.0 <= value <= 1.0:
                raise ValueError(f'{name} = {value!r} is out of range: allowed 0..1')
        self.bus = bus
        self.loss = float(loss)
        self.send_error_rate = float(send_error_rate)
        self.seed = int(seed)
        self._streams: dict[tuple[str, int], random.Random] = {}
        self._lock = threading.Lock()
        self._bus_off_until = 0.0
        self._drops: dict[tuple[bool, int], int] = {}
        self.counts = {'sent': 0, 'received': 0, 'lost_sent': 0, 'lost_received': 0,
                       'send_errors': 0, 'bus_off_sends': 0, 'bus_off_receives': 0}
        self.channel_info = f'faults on {getattr(bus, "channel_info", bus)}'
        super().__init__(channel=bus.channel_info, **kwargs)      # (BusABC only names it)

    # ---------------------------------------------------------------- knobs
    def bus_off(self, seconds: float) -> None:
        """Bus-off from now for `seconds`: sends and receives raise CanOperationError."""
        with self._lock:
            self._bus_off_until = time.monotonic() + float(seconds)

    def drop(self, can_id: int, count: int = 1, sent: bool = False) -> None:
        """Lose the next `count` received (or `sent`) frames with COB-ID `can_id`."""
        with self._lock:
            key = (sent, can_id)
            self._drops[key] = self._drops.get(key, 0) + int(count)

    def _dropped(self, can_id: int, sent: bool = False) -> bool:
        with self._lock:
            left = self._drops.get((sent, can_id), 0)
            if left:
                self._drops[(sent, can_id)] = left - 1
            return bool(left)

    @property
    def is_bus_off(self) -> bool:
        return time.monotonic() < self._bus_off_until

    def _draw(self, direction: str, can_id: int) -> float:
        with self._lock:
            stream = self._streams.get((direction, can_id))
            if stream is None:
                stream = random.Random(f'{self.seed}:{direction}:{can_id}')
                self._streams[(direction, can_id)] = stream
            return stream.random()

    # ---------------------------------------------------------------- python-can
    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self.is_bus_off:
            self.counts['bus_off_sends'] += 1
            raise can.CanOperationError('bus-off: the CAN controller is off the bus')
        if self.send_error_rate and self._draw('error', msg.arbitration_id) < \
                self.send_error_rate:
            self.counts['send_errors'] += 1
            raise can.CanOperationError('Failed to transmit: No buffer space available '
                                        '[Error Code 105]')
        if (self._drops and self._dropped(msg.arbitration_id, sent=True)) or (
                self.loss and self._draw('send', msg.arbitration_id) < self.loss):
            self.counts['lost_sent'] += 1
            return
        self.bus.send(msg, timeout)
        self.counts['sent'] += 1

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            if self.is_bus_off:
                self.counts['bus_off_receives'] += 1
                self._drain()               # what the bus carried meanwhile never reached us
                time.sleep(min(0.01, timeout or 0.01))
                raise can.CanOperationError('bus-off: the CAN controller is off the bus')
            remaining = None if deadline is None else max(deadline - time.monotonic(), 0.0)
            msg = self.bus.recv(remaining)
            if msg is None:
                return None, False
            if (self._drops and self._dropped(msg.arbitration_id)) or (
                    self.loss and self._draw('recv', msg.arbitration_id) < self.loss):
                self.counts['lost_received'] += 1
                if deadline is not None and time.monotonic() >= deadline:
                    return None, False
                continue
            self.counts['received'] += 1
            return msg, False

    def _drain(self) -> None:
        while self.bus.recv(0.0) is not None:
            pass

    def fileno(self) -> int:
        return self.bus.fileno()

    def shutdown(self) -> None:
        super().shutdown()
        self.bus.shutdown()
