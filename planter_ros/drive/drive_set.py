"""The drives of a machine on one CAN bus: one `CanopenBus`, one `Cia402Drive` per row.

Enabling and shutting down are BLOCKING (SDO, state-machine waits) and run once, at start-up
and at exit, never in a callback. Both run every drive at once, one thread each, while the
calling thread keeps the drives that are already enabled fed (command 0 every `keep_alive`
period, the master heartbeat every heartbeat period): a drive's watchdog arms on the first
frame it sees, so a drive that does not answer, or one still shutting down, must not leave the
others without frames for their command timeout. A drive that fails to enable is reported and
left out; the others run.
"""

from __future__ import annotations

from dataclasses import replace
import logging
import threading
import time
from typing import TYPE_CHECKING

import can

from .cia402 import CanopenBus, Cia402Drive
from .config import DriveConfig
from .errors import DriveError
from .setup import DriveSetup

if TYPE_CHECKING:
    from collections.abc import Callable

__all__ = ['DriveSet']

log = logging.getLogger(__name__)


class DriveSet:
    """Drives by name (a row's name) on one bus. `node_ids`: name -> CANopen node id."""

    def __init__(self, config: DriveConfig, node_ids: dict[str, int],
                 bus: can.BusABC | None = None,
                 setups: dict[str, DriveSetup] | None = None) -> None:
        """`setups`: name -> what the machine file says of that drive (its gear ratio,
        encoder counts and EDS replace the config's; checked and applied at enable)."""
        self.config = config
        self.canbus = CanopenBus(config, bus)
        setups = setups or {}
        self.drives: dict[str, Cia402Drive] = {}
        for name, node_id in node_ids.items():
            setup = setups.get(name)
            drive_config = replace(config, drive_node_id=node_id)
            if setup is not None:
                drive_config = setup.device(drive_config)
            self.drives[name] = Cia402Drive(drive_config, canbus=self.canbus, setup=setup)
        self.enabled: dict[str, Cia402Drive] = {}    # the drives enable() brought up
        self.failed: dict[str, DriveError] = {}      # the drives left out, and why

    def enable(self, keep_alive: float = 0.02) -> dict[str, DriveError]:
        """Open the bus, enable every drive at once; returns {name: DriveError} of the drives
        left out (BLOCKING; see the module doc). Raises DriveError when the bus cannot open."""
        if not self.drives:
            return {}
        for drive in self.drives.values():
            drive.open()                          # one after the other: the Network's node dict
        done: dict[str, DriveError | None] = {}
        lock = threading.Lock()

        def enable_one(name: str, drive: Cia402Drive) -> None:
            try:
                drive.connect_and_enable()
                outcome = None
            except DriveError as exc:
                outcome = exc
            with lock:
                done[name] = outcome

        threads = [threading.Thread(target=enable_one, args=item, daemon=True,
                                    name=f'enable-{item[0] or "drive"}')
                   for item in self.drives.items()]
        for thread in threads:
            thread.start()
        self._keep_fed(lambda: all(not t.is_alive() for t in threads), done, lock, keep_alive)
        for thread in threads:
            thread.join()
        for name, drive in self.drives.items():
            error = done.get(name)
            if error is None:
                self.enabled[name] = drive
            else:
                self.failed[name] = error
                log.error('%s', error)
                drive.shutdown()                  # leaves the bus: its node is removed
        return dict(self.failed)

    def _keep_fed(self, finished: Callable[[], bool], done: dict[str, DriveError | None],
                  lock: threading.Lock, period: float) -> None:

        """Until `finished()`: command 0 to each drive already enabled, heartbeat on time."""
        next_heartbeat = 0.0
        while not finished():
            now = time.monotonic()
            with lock:
                ready = [self.drives[n] for n, outcome in done.items() if outcome is None]
            try:
                if ready and now >= next_heartbeat:
                    self.canbus.send_heartbeat()
                    next_heartbeat = now + self.config.heartbeat_period
                for drive in ready:
                    drive.send_hold()
            except DriveError as exc:
                log.warning('while enabling: %s', exc)
            time.sleep(period)

    def send_heartbeat(self) -> None:
        """The master heartbeat, once for the bus (NON-BLOCKING; raises DriveError)."""
        self.canbus.send_heartbeat()

    def shutdown(self) -> None:
        """Shut every enabled drive down at once (BLOCKING, idempotent, never raises), then
        close the bus."""
        drives = list(self.enabled.values())
        self.enabled = {}
        threads = [threading.Thread(target=drive.shutdown, daemon=True) for drive in drives]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        for drive in self.drives.values():
            drive.shutdown()                      # the rest (never enabled): leave the bus
        self.canbus.close()
