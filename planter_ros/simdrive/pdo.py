"""CiA 301 PDO timing in the simulated drive, to the letter:

* an RPDO of transmission type 0..240 (synchronous) is buffered when received and acted on at
  the next SYNC (a newer one before that SYNC replaces it); 254/255 (event) act at once;
* a TPDO of type 1..240 is sent after every n-th SYNC, of type 0 after a SYNC when its data
  changed; of type 254/255 on its event timer (sub-index 5) and when the statusword it carries
  changes, never sooner than its inhibit time (sub-index 3) after the last; 252/253 (remote
  request only): never sent by itself;
* nothing is received or sent outside NMT operational; the configuration is read from the
  drive's own object dictionary at the NMT start (what the master wrote by SDO).

The entries are decoded and encoded with canopen's `PdoMap` (the mapping as written).
`act(entries)` and `sample()` are the drive's: they write received entries into the dictionary
(controlword last) and read the live values."""
from __future__ import annotations

from collections.abc import Callable
import math
from typing import TYPE_CHECKING

from planter_ros.drive import objects as od
from planter_ros.drive.dictionary import pdo_maps

if TYPE_CHECKING:
    from canopen.pdo.base import PdoMap

    from .node import StrictNode

__all__ = ['PdoTiming', 'synchronous']

Entries = list[tuple[int, int, bytes]]


def synchronous(trans_type: int | None) -> bool:
    return trans_type is not None and 0 <= trans_type <= 240


class PdoTiming:
    """The PDOs of one simulated drive (module doc)."""

    def __init__(self, node: StrictNode, act: Callable[[Entries], None]) -> None:
        self.node = node
        self.rpdos, self.tpdos = pdo_maps(node.rpdo), pdo_maps(node.tpdo)
        # (number, map) of each TPDO, taken once: canopen makes a node's maps with the node
        # (reading the dictionary refills them), and they are walked at every step
        self._tpdo_items = tuple(self.tpdos.items())
        self.act = act
        self.operational = False
        self._buffered: dict[int, Entries] = {}      # synchronous RPDOs waiting for SYNC
        self._timing: dict[int, tuple[float, float]] = {}   # TPDO: (event timer s, inhibit s)
        self._last_sent: dict[int, float] = {}
        self._last_data: dict[int, bytes] = {}
        self._syncs = 0
        self._sent_statusword: int | None = None
        self.deadline = 0.0                          # s: the controlword RPDO's event timer
        self.rpdo_count = 0
        self.tpdo_count = 0

    # ---------------------------------------------------------------- NMT
    def start(self) -> None:
        """NMT operational: the configuration as the dictionary now holds it."""
        node = self.node
        node.rpdo.read()
        node.tpdo.read()
        self._buffered.clear()
        self._timing.clear()
        self._last_sent.clear()
        self._last_data.clear()
        self._syncs = 0
        self._sent_statusword = None
        deadline = 0.0
        for number, pdo_map in self.rpdos.items():
            timer = node.value(0x1400 + number - 1, 5, 0) if pdo_map.enabled else 0
            if timer and any(var.index == od.CONTROLWORD.index for var in pdo_map):
                deadline = timer / 1000.0
        self.deadline = deadline
        for number in self.tpdos:
            comm = 0x1800 + number - 1
            self._timing[number] = (node.value(comm, 5, 0) / 1000.0,
                                    node.value(comm, 3, 0) / 10_000.0)
        self.operational = True

    def stop(self) -> None:
        self.operational = False
        self._buffered.clear()

    # ---------------------------------------------------------------- receiving
    def received(self, pdo_map: PdoMap) -> None:
        """An RPDO: act now (event types) or at the next SYNC (synchronous)."""
        if not self.operational:
            return
        self.rpdo_count += 1
        entries = [(var.index, var.subindex, bytes(var.get_data())) for var in pdo_map]
        entries.sort(key=lambda e: e[0] == od.CONTROLWORD.index)       # controlword last
        if synchronous(pdo_map.trans_type):
            number = next(n for n, m in self.rpdos.items() if m is pdo_map)
            self._buffered[number] = entries
        else:
            self.act(entries)

    def sync_rpdos(self) -> None:
        """At a SYNC: act on the synchronous RPDOs received since the last one (targets
        first, controlwords last)."""
        buffered, self._buffered = self._buffered, {}
        entries = [e for number in sorted(buffered) for e in buffered[number]]
        entries.sort(key=lambda e: e[0] == od.CONTROLWORD.index)
        if entries:
            self.act(entries)

    # ---------------------------------------------------------------- sending
    def sync_tpdos(self, now: float) -> None:
        """At a SYNC: the synchronous TPDOs due (sampled now)."""
        if not self.operational:
            return
        self._syncs += 1
        for number, pdo_map in self._tpdo_items:
            trans = pdo_map.trans_type
            if not pdo_map.enabled or not synchronous(trans):
                continue
            if trans == 0:
                data = self._sample(pdo_map)
                if data != self._last_data.get(number):
                    self._send(number, pdo_map, now, data)
            elif self._syncs % trans == 0:
                self._send(number, pdo_map, now, self._sample(pdo_map))

    def event_tpdos(self, now: float, statusword: int) -> None:
        """Event TPDOs (254/255): their timer expired, or the statusword they carry changed;
        each no sooner than its inhibit time after its last."""
        if not self.operational:
            return
        changed = statusword != self._sent_statusword
        for number, pdo_map in self._tpdo_items:
            if not pdo_map.enabled or pdo_map.trans_type not in (254, 255):
                continue
            timer, inhibit = self._timing.get(number, (0.0, 0.0))
            last = self._last_sent.get(number, -math.inf)
            if now - last < inhibit:
                continue
            expired = timer > 0 and now - last >= timer
            if not (changed or expired):        # most steps: nothing due
                continue
            carries = any(var.index == od.STATUSWORD.index for var in pdo_map)
            if (carries and changed) or expired:
                self._send(number, pdo_map, now, self._sample(pdo_map))
                if carries:
                    self._sent_statusword = statusword

    def _sample(self, pdo_map: PdoMap) -> bytes:
        for var in pdo_map:
            var.set_data(self.node.get_data(var.index, var.subindex))
        return bytes(pdo_map.data)

    def _send(self, number: int, pdo_map: PdoMap, now: float, data: bytes) -> None:
        if pdo_map.cob_id is None:               # no COB-ID read from 18xxh:1: nothing to send
            return
        self.node.network.send_message(pdo_map.cob_id, data)
        self._last_sent[number] = now
        self._last_data[number] = data
        self.tpdo_count += 1
