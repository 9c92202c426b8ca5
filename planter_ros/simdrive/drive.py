"""A simulated CiA 402 servo drive on a python-can bus, strict to CiA 301 and CiA 402: what tests,
the demo and `planter drive check --simulated` drive instead of a real servo.

Its object dictionary is any EDS (`SimSpec.eds_path`, default config/planter_drive.eds), served
by canopen's `LocalNode` held to the file (`node.StrictNode`: absent objects and read-only
entries abort as a device does, PDO mapping capacity enforced). Everything `LocalNode` does not
do is done here, in one thread that also decodes the received frames:

* the CiA 402 state machine (`control`), profile velocity, cyclic synchronous position (`csp`:
  the interpolation period read from 60C2h) and homing (`homing`);
* CiA 301 PDO timing (`pdo`): a synchronous RPDO acts at the next SYNC, a synchronous TPDO is
  sent only after a SYNC; event PDOs act and report at once and on their timer;
* a motor (`motor`) behind a mechanism (`mechanism`), the heartbeat producer (1017h, sent
  from this thread, no `send_periodic`), the drive's own watchdog (`watchdog`: RPDO deadline
  and heartbeat consumer, answered by 6007h), EMCYs with the error register's bit 0 set with
  any other, and injected faults (`faults`: power cycles, slow SDO, EMCY storms).

Units inside: motor counts and counts/s, as on the bus; introspection for tests is SI (motor
shaft rad, rad/s) unless named counts.
"""
from __future__ import annotations

import logging
import math
import struct
import threading
import time
from typing import TYPE_CHECKING

import can
import canopen
from canopen.emcy import EMCY_STRUCT
from canopen.sdo import SdoAbortedError

from planter_ros.drive import objects as objs
from planter_ros.drive.eds import default_eds_path
from planter_ros.drive.states import EMCY_FOLLOWING_ERROR, NOT_READY, OPERATION_ENABLED, \
    SWITCH_ON_DISABLED
from planter_ros.drive.words import (ERROR_REGISTER_COMMUNICATION, ERROR_REGISTER_GENERIC,
                                     error_register)

from .clock import Gaps, paced, receive, wire_time
from .device import SimulatedDevice
from .faults import InjectedFaults
from .mechanism import Mechanism
from .node import StrictNode
from .pdo import PdoTiming
from .spec import SimSpec
from .views import DriveViews
from .watchdog import Watchdog

if TYPE_CHECKING:
    from canopen.objectdictionary import ODVariable
    from canopen.pdo.base import PdoMap

__all__ = ['SimulatedDrive']

log = logging.getLogger(__name__)
_NMT_CODE = {'INITIALISING': 0x00, 'STOPPED': 0x04, 'OPERATIONAL': 0x05, 'PRE-OPERATIONAL': 0x7F}


class SimulatedDrive(DriveViews):
    """A CiA 402 drive on the bus (module doc). `bus_or_channel`: a python-can bus this drive
    uses (left open on stop()), or a channel name for a bus of `interface` that it opens and
    closes itself; `network`: a canopen Network shared with other simulated drives
    (`SimulatedBus`, its owner connects and stops it); `spec`: what the drive is built as."""

    def __init__(self, bus_or_channel: can.BusABC | str, node_id: int = 1,
                 spec: SimSpec | None = None, *, network: canopen.Network | None = None,
                 interface: str = 'virtual', tick: float = 0.002) -> None:
        self.spec = spec = spec if spec is not None else SimSpec()
        if not tick > 0:
            raise ValueError(f'tick = {tick!r} is out of range: allowed > 0')
        self._owns_bus = isinstance(bus_or_channel, str)
        self._bus: can.BusABC = (can.Bus(interface=interface, channel=bus_or_channel)
                                 if isinstance(bus_or_channel, str) else bus_or_channel)
        self.node_id, self.tick = node_id, float(tick)
        self._lock = threading.RLock()
        self._tx_lock = threading.Lock()
        self._stop_event = threading.Event()
        self._thread: threading.Thread | None = None
        self.network = network if network is not None else canopen.Network(self._bus)
        self.node = StrictNode(node_id, str(spec.eds_path or default_eds_path()))
        # our thread sends the heartbeat, never a send_periodic task: drop the NMT slave's
        # 1017h hook that would start one
        self.node._write_callbacks.remove(self.node.nmt.on_write)
        self.node.add_write_callback(self._on_write)
        self.node.add_read_callback(self._on_read)
        self.network.add_node(self.node)
        # SDO requests and NMT commands through our own handlers (a drive powered off hears
        # nothing; a slow one answers late), which call LocalNode's
        self.network.unsubscribe(self.node.sdo.rx_cobid, self.node.sdo.on_request)
        self.network.unsubscribe(0, self.node.nmt.on_command)
        self.network.subscribe(self.node.sdo.rx_cobid, self._on_sdo_request)
        self.network.subscribe(0, self._on_nmt_command)
        self.network.subscribe(objs.SYNC_COB, self._on_sync)
        self.mechanism = Mechanism(spec)
        self.faults = InjectedFaults(spec, node_id)
        self.watchdog = Watchdog()
        self.pdo = PdoTiming(self.node, self._act)
        for pdo_map in self.pdo.rpdos.values():
            pdo_map.add_callback(self._on_rpdo)
        self._hb_enabled = True
        self._last_hb_sent = -math.inf
        #: gaps between command frames, SYNCs and the master's heartbeats, on this drive's
        #: own clock; SYNC late = over 1.5 periods (1006h), missing = whole periods without
        self.rpdo_gaps, self.sync_gaps, self.heartbeat_gaps = Gaps(), Gaps(), Gaps()
        self.sync_count = self.sync_late = self.sync_missing = 0
        self.following_error_faults = 0
        self.emcy_sent = 0
        self._reset_application()

    # ---------------------------------------------------------------- life cycle
    def _reset_application(self, kept: tuple | None = None) -> None:
        """The dictionary at its EDS defaults, the device at NOT READY (`kept`: what a power
        cycle keeps, `SimulatedDevice.kept`)."""
        with self._lock:
            self.node.data_store.clear()
            if self.node.has(objs.ENCODER_INCREMENTS.index, 1):
                self.node.data_store.setdefault(objs.ENCODER_INCREMENTS.index, {})[1] = \
                    struct.pack('<I', self.spec.counts_per_motor_rev)
            self.device = SimulatedDevice(self.spec, self.node, self.mechanism, kept)
            self._last_sync: float | None = None
            self._heartbeat_period = self.node.value(0x1017, 0, 0) / 1000.0
            self._abort_option = self.node.value(objs.ABORT_CONNECTION.index, 0, 1)
            self.watchdog.deadline = 0.0
            self.watchdog.last_rpdo = None
            self.watchdog.consume(0)

    def start(self, thread: bool = True) -> None:
        """Boot (boot-up message, pre-operational, SWITCH ON DISABLED) and start the thread
        (`thread` False: the caller runs `step()` instead, as SimulatedBus does)."""
        if self._thread is not None:
            return
        self._boot()
        if thread:
            self._thread = threading.Thread(target=self._run, name=f'sim-drive-{self.node_id}',
                                            daemon=True)
            self._thread.start()

    def _boot(self) -> None:
        self.node.nmt.state = 'INITIALISING'          # sends the boot-up frame
        self.node.nmt.state = 'PRE-OPERATIONAL'
        self.node.nmt.stop_heartbeat()                # our thread produces the heartbeat
        with self._lock:
            self.pdo.stop()
            self.device.control.state = SWITCH_ON_DISABLED   # transition 1 after self-test

    def stop(self) -> None:
        """Stop the thread; close the bus if this drive opened it."""
        self._stop_event.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        if self._owns_bus:
            self._bus.shutdown()

    # ---------------------------------------------------------------- test / demo knobs
    def inject_fault(self, error_code: int = 0x7500, persistent: bool = False) -> None:
        """Fault now: fault reaction (quick-stop ramp) -> FAULT, 603Fh and an EMCY. A
        persistent fault survives fault-reset requests (the cause is still there)."""
        with self._lock:
            self.device.control.fault(error_code, persistent)
        self._send_emcy(error_code, error_register(ERROR_REGISTER_GENERIC))
        self._event_tpdos()

    def clear_persistent_fault(self) -> None:
        """The fault cause went away: the next fault-reset edge clears it."""
        with self._lock:
            self.device.control.fault_persistent = False

    def send_emcy(self, error_code: int) -> None:
        """An EMCY without a state change (a warning-class event such as over-temperature)."""
        self._send_emcy(error_code, error_register(ERROR_REGISTER_GENERIC))

    def set_heartbeat_enabled(self, on: bool) -> None:
        """Switch the heartbeat producer off/on (simulates a drive whose heartbeat is lost)."""
        with self._lock:
            self._hb_enabled = bool(on)

    def hold_state(self, state: str | None) -> None:
        """Refuse every transition out of `state` (e.g. STO active keeps SWITCHED ON)."""
        with self._lock:
            self.device.control.held = state

    def power_cycle(self, off_time: float = 0.5) -> None:
        """Power off now for `off_time` s, then boot again: off, the drive sends and hears
        nothing and its load coasts down; at power-on it sends its boot-up message and comes
        up pre-operational in SWITCH ON DISABLED with its dictionary at the EDS defaults. What
        a drive keeps in non-volatile memory stays: its absolute encoder's position, the
        polarity 607Eh and the home offset."""
        with self._lock:
            self.faults.power_off(time.monotonic(), off_time)
            self.device.control.state = NOT_READY            # power stage off: coasting
            self.pdo.stop()
        for gaps in (self.rpdo_gaps, self.sync_gaps, self.heartbeat_gaps):
            gaps.restart()

    def _power_on(self) -> None:
        with self._lock:
            self._reset_application(self.device.kept())
            self._last_hb_sent = -math.inf
            self.faults.powered = True
        self._boot()

    def emcy_storm(self, rate: float, seconds: float, code: int = 0x4210) -> None:
        """From now on for `seconds`, `rate` EMCY frames per second with `code` (a warning:
        the drive's state does not change), as a drive with a chattering sensor sends them."""
        with self._lock:
            self.faults.storm(time.monotonic(), rate, seconds, code)

    @property
    def powered(self) -> bool:
        return self.faults.powered

    # ---------------------------------------------------------------- the dictionary's hooks
    def _on_read(self, index: int, subindex: int, od: ODVariable) -> int | None:
        """Live values for SDO uploads and TPDO sampling."""
        with self._lock:
            return self.device.read(index, subindex)

    def _on_write(self, index: int, subindex: int, od: ODVariable, data: bytes) -> None:
        """SDO downloads and the entries of RPDOs acted on land here before they are stored."""
        value = od.decode_raw(data)
        if not isinstance(value, int):          # strings and domains: stored, nothing to act on
            return
        with self._lock:
            done = self.device.write(index, subindex, value)
            if index == objs.HEARTBEAT_PRODUCER.index:
                self._heartbeat_period = value / 1000.0
            elif index == objs.HEARTBEAT_CONSUMER.index and subindex == 1:
                consumed = self.watchdog.consume(value)
                if consumed:
                    self.network.subscribe(objs.heartbeat_cob(consumed),
                                           self._on_consumed_heartbeat)
            elif index == objs.ABORT_CONNECTION.index:
                self._abort_option = value
        if done is not None:                       # a controlword
            if done.reset_done:
                self._send_emcy(0x0000, 0)
            self._event_tpdos()

    def _act(self, entries: list[tuple[int, int, bytes]]) -> None:
        """Received RPDO entries, acted on (controlword last)."""
        try:
            for index, subindex, data in entries:
                self.node.set_data(index, subindex, data)
        except SdoAbortedError as exc:
            log.warning('simulated drive: RPDO entry refused: %s', exc)

    # ---------------------------------------------------------------- frames received
    def _on_sdo_request(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """An SDO request: answered at once, or by a slow drive later, or never while off."""
        if not self.faults.powered:
            return
        with self._lock:
            now = self.faults.sdo_request(time.monotonic(), can_id, data, timestamp)
        if now:
            self.node.sdo.on_request(can_id, data, timestamp)

    def _on_nmt_command(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """An NMT command: LocalNode applies it to node.nmt, then the drive reacts."""
        if not self.faults.powered:
            return
        self.node.nmt.on_command(can_id, data, timestamp)
        state = self.node.nmt.state
        if state == 'INITIALISING':                  # reset node / reset communication
            if data[0] == 0x81:
                self._reset_application()
            self._boot()
        elif state == 'OPERATIONAL' and not self.pdo.operational:
            with self._lock:
                self.pdo.start()
                self.watchdog.deadline = self.pdo.deadline
                self.watchdog.last_rpdo = None       # monitoring starts at the next RPDO
            self._event_tpdos()
        elif state != 'OPERATIONAL':
            with self._lock:
                self.pdo.stop()
            self.rpdo_gaps.restart()

    def _on_rpdo(self, pdo_map: PdoMap) -> None:
        if not self.pdo.operational:
            return
        stamp = wire_time(pdo_map.timestamp)
        self.rpdo_gaps.event(stamp)
        with self._lock:
            self.watchdog.last_rpdo = stamp
        self.pdo.received(pdo_map)

    def _on_consumed_heartbeat(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if self.faults.powered and (can_id & 0x7F) == self.watchdog.consumer_node:
            self.watchdog.heartbeat = wire_time(timestamp)
            self.heartbeat_gaps.event(self.watchdog.heartbeat)

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """SYNC (its time on the bus, as a drive's hardware sees it): the motor up to that
        instant; the synchronous TPDOs sampled and sent; the synchronous RPDOs received since
        the last SYNC acted on; in CSP the new segment to the target taken."""
        if not self.faults.powered:
            return
        now = wire_time(timestamp)
        with self._lock:
            self._step_motor(now)
            self.sync_count += 1
            self.sync_gaps.event(now)
            period = self.node.value(0x1006, 0, 0) / 1e6
            if self._last_sync is not None and period > 0:
                gap = now - self._last_sync
                if gap > 1.5 * period:
                    self.sync_late += 1
                    self.sync_missing += max(int(round(gap / period)) - 1, 0)
            self._last_sync = now
        try:
            with self._tx_lock:
                self.pdo.sync_tpdos(now)
        except (can.CanError, RuntimeError, OSError) as exc:
            log.debug('simulated drive: TPDO send failed: %s', exc)
        self.pdo.sync_rpdos()
        with self._lock:
            self.device.sync(now)

    # ---------------------------------------------------------------- frames sent
    def _send_emcy(self, code: int, register: int) -> None:
        if not self.faults.powered:
            return
        self.emcy_sent += 1
        try:
            self.network.send_message(objs.emcy_cob(self.node_id),
                                      EMCY_STRUCT.pack(code, register, b''))
        except (can.CanError, RuntimeError, OSError) as exc:
            log.debug('simulated drive: EMCY send failed: %s', exc)

    def _event_tpdos(self) -> None:
        """The event TPDOs due now (a statusword change, a timer)."""
        with self._lock:
            sw = self.device.statusword()
        try:
            with self._tx_lock:
                self.pdo.event_tpdos(time.monotonic(), sw)
        except (can.CanError, RuntimeError, OSError) as exc:
            log.debug('simulated drive: TPDO send failed: %s', exc)

    # ---------------------------------------------------------------- the thread
    def _run(self) -> None:
        for dt, now in paced(self._stop_event, self.tick,
                             lambda: receive(self._bus, self.network)):
            if not self.step(dt, now):
                break

    def step(self, dt: float, now: float) -> bool:
        """One step of the drive's own work (motor, watchdogs, TPDOs, heartbeat); False once
        stopped."""
        try:
            if not self.faults.powered:
                with self._lock:
                    self._step_motor(now)             # the load coasts, nothing is sent
                if now >= self.faults.power_on_at:
                    self._power_on()
                return True
            self._step_faults(now)
            with self._lock:
                self._step_motor(now)
                trip = self.watchdog.check(now) if (
                    self.device.control.state == OPERATION_ENABLED) else None
                if trip is not None:
                    self.device.control.communication_error(trip[1], self._abort_option)
            if trip is not None:
                log.info('simulated drive: %s -> abort connection option %d', trip[0],
                         self._abort_option)
                self._send_emcy(trip[1], error_register(ERROR_REGISTER_COMMUNICATION))
            self._event_tpdos()
            self._send_heartbeat(now)
        except (can.CanError, RuntimeError, OSError) as exc:
            if self._stop_event.is_set():
                return False
            log.warning('simulated drive: bus error: %s', exc)
        return True

    def _step_faults(self, now: float) -> None:
        with self._lock:
            due = self.faults.due_sdo(now)
            burst, code = self.faults.storm_burst(now)
        for _, can_id, data, stamp in due:
            self.node.sdo.on_request(can_id, data, stamp)
        for _ in range(burst):
            self._send_emcy(code, error_register(ERROR_REGISTER_GENERIC))

    def _send_heartbeat(self, now: float) -> None:
        with self._lock:
            due = (self._hb_enabled and self._heartbeat_period > 0
                   and now - self._last_hb_sent >= self._heartbeat_period)
            if due:
                self._last_hb_sent = now
        if due:
            self.network.send_message(objs.heartbeat_cob(self.node_id),
                                      bytes([_NMT_CODE.get(self.node.nmt.state, 0x7F)]))

    def _step_motor(self, now: float) -> None:
        """The motor up to `now` (lock held); a following error beyond its time-out faults."""
        device = self.device
        if device.advance(now):
            log.warning('simulated drive %d: %s', self.node_id, device.csp.last_fault)
            self.following_error_faults += 1
            device.csp.since = None
            device.control.fault(EMCY_FOLLOWING_ERROR)
            self._send_emcy(EMCY_FOLLOWING_ERROR, error_register(ERROR_REGISTER_GENERIC))

