"""Several simulated drives as devices on one cable: one python-can bus and one canopen Network
for all of them (one receiving bus in the process, not one per drive, so a frame sent to N
drives is copied once, as on a real bus), run from one thread."""
from __future__ import annotations

from collections.abc import Iterable
import threading
from typing import Any

import can
import canopen

from .clock import paced, receive
from .drive import SimulatedDrive
from .spec import SimSpec

__all__ = ['SimulatedBus']


class SimulatedBus:
    """`drives[i]` has node id `node_ids[i]`; keyword arguments (SimSpec fields) go to every
    drive, `node_kwargs` (node id, int or its text -> fields) to one drive alone (its gear,
    wiring, mechanical offset, EDS), over the common ones."""

    def __init__(self, channel: str | can.BusABC, node_ids: Iterable[int], *,
                 interface: str = 'virtual', tick: float = 0.002,
                 node_kwargs: dict | None = None, **drive_kwargs: Any) -> None:
        """`channel`: a channel name of `interface` (opened here), or an open python-can bus
        (e.g. one end of a socket pair to a master in another process; shut down on stop)."""
        self.bus = (channel if isinstance(channel, can.BusABC)
                    else can.Bus(interface=interface, channel=channel))
        self.network = canopen.Network(self.bus)
        self.tick = float(tick)
        common = SimSpec().with_options(**drive_kwargs)
        own = {int(node): dict(kwargs) for node, kwargs in (node_kwargs or {}).items()}
        self.drives = [SimulatedDrive(self.bus, node_id, common.with_options(
                           **own.get(node_id, {})), network=self.network, tick=tick)
                       for node_id in node_ids]
        self._stop_event = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Boot every drive and run them all from one thread (one wake-up per tick for the
        whole bus, not one per drive)."""
        for drive in self.drives:
            drive.start(thread=False)
        self._thread = threading.Thread(target=self._run, name='sim-bus', daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            for dt, now in paced(self._stop_event, self.tick,
                                 lambda: receive(self.bus, self.network)):
                for drive in self.drives:
                    if not drive.step(dt, now):
                        return
        except (can.CanError, OSError):
            if not self._stop_event.is_set():
                raise

    def stop(self) -> None:
        self._stop_event.set()
        for drive in self.drives:
            drive._stop_event.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        for drive in self.drives:
            drive.stop()
        self.bus.shutdown()

    @property
    def watchdog_trips(self) -> list[tuple[int, str, int]]:
        """(node id, reason, EMCY code) of every drive's watchdog reactions."""
        return [(d.node_id, why, code) for d in self.drives for why, code in d.watchdog_trips]
