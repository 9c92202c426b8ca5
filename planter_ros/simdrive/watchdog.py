"""The simulated drive's own watchdog on the master: RPDO deadline monitoring (the event timer
of the RPDO carrying the controlword, CiA 301: EMCY 8250h) and the heartbeat consumer (1016h:1,
EMCY 8130h), each answered by the abort connection option 6007h. Each judges a frame by its
time on the bus (`wire_time`), as a drive's hardware receives it; both arm on the first frame
they see and re-arm on the next after a trip. Plain state: the drive's lock is held."""
from __future__ import annotations

from planter_ros.drive.states import EMCY_HEARTBEAT, EMCY_RPDO_TIMEOUT

__all__ = ['Watchdog']


class Watchdog:
    """Deadline and heartbeat consumer of one drive (module doc)."""

    def __init__(self) -> None:
        self.deadline = 0.0                       # s, 0: off
        self.last_rpdo: float | None = None
        self.consumer_node = 0
        self.consumer_timeout = 0.0               # s, 0: off
        self.heartbeat: float | None = None       # the master's last heartbeat (monotonic s)
        #: trips, newest last: (reason, EMCY code)
        self.trips: list[tuple[str, int]] = []

    def consume(self, value: int) -> int:
        """1016h:1 written: the node watched (0: none) and its timeout."""
        self.consumer_node = (value >> 16) & 0x7F
        self.consumer_timeout = (value & 0xFFFF) / 1000.0
        self.heartbeat = None
        return self.consumer_node

    def check(self, now: float) -> tuple[str, int] | None:
        """(reason, EMCY code) of a trip now, or None (call only while operation enabled)."""
        rpdo_late = (self.deadline > 0 and self.last_rpdo is not None
                     and now - self.last_rpdo > self.deadline)
        hb_late = (self.consumer_timeout > 0 and self.heartbeat is not None
                   and now - self.heartbeat > self.consumer_timeout)
        if rpdo_late:
            self.last_rpdo = None              # re-armed by the next RPDO
        if hb_late:
            self.heartbeat = None              # re-armed by the next heartbeat
        if rpdo_late:
            trip = ('RPDO deadline (0x1400:5) expired', EMCY_RPDO_TIMEOUT)
        elif hb_late:
            trip = ('master heartbeat (0x1016) lost', EMCY_HEARTBEAT)
        else:
            return None
        self.trips.append(trip)
        return trip
