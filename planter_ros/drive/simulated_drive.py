"""A simulated CiA 402 servo drive on a python-can bus (canopen LocalNode).

The simulator is what tests and the demo drive instead of a real servo: the object dictionary
comes from ``config/planter_drive.eds``, SDO is served by canopen's ``LocalNode``, and
everything ``LocalNode`` does not do is done here, in one thread that also decodes the received
frames (no listener thread of its own):

* the CiA 402 state machine (controlword -> state, statusword), profile velocity mode only;
* received RPDOs are decoded with canopen's ``PdoMap`` (with the mapping the master wrote by
  SDO) and copied into the object dictionary, because ``LocalNode`` does not do that;
* TPDOs are filled from the live values and sent by this thread at their event timer (and at
  once when the statusword changes), because ``LocalNode`` does not send them;
* a motor model: first-order lag towards the target speed plus an acceleration limit,
  an encoder that integrates the speed into increments (0x6064);
* the heartbeat producer (0x1017), sent from this thread (no ``send_periodic``);
* the drive's own command watchdog: RPDO deadline monitoring (event timer 0x1400:5) and the
  heartbeat consumer (0x1016) trigger the abort connection option (0x6007), e.g. quick stop.
  It judges each frame by its time on the bus (the frame's timestamp), as a drive's hardware
  receives it, and decodes every waiting frame before it judges: the thread that simulates the
  drive running late (a loaded host) is no missed command;
* faults and EMCY on demand, and a switch to silence the heartbeat;
* a mechanism behind a gear (`gear_ratio` motor turns per mechanism turn), possibly wired the
  other way round (`motor_reversed`), whose bottom (the planting tip lowest) sits at an unknown
  `mechanical_offset` from the encoder's zero, with a proximity switch at the bottom wired as
  the drive's home switch (0x60FD bit 2); the polarity 0x607E (bits 7 position, 6 velocity),
  and homing mode 6 (0x6098: 19 home switch, 33/34 index pulse, 35/37 current position; speeds
  0x6099, home offset 0x607C; statusword bit 12 attained, bit 13 error).

Units inside: increments (counts) and counts/s, as on the bus; the introspection properties
for tests are SI (motor shaft rad, rad/s).
"""
from __future__ import annotations

import logging
import math
import random
import struct
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import can
import canopen
from canopen.emcy import EMCY_STRUCT

from planter_ros.drive import objects as objs
from planter_ros.drive.eds import default_eds_path
from planter_ros.drive.states import (
    CYCLIC_SYNC_POSITION, EMCY_FOLLOWING_ERROR, EMCY_HEARTBEAT, EMCY_RPDO_TIMEOUT, FAULT,
    FAULT_REACTION_ACTIVE, MODE_SUPPORTED, NOT_READY, OPERATION_ENABLED, PROFILE_VELOCITY,
    QUICK_STOP_ACTIVE, READY_TO_SWITCH_ON, SWITCH_ON_DISABLED, SWITCHED_ON)

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable, Iterator

    from canopen.objectdictionary import ODVariable
    from canopen.pdo.base import PdoMap

__all__ = ['Gaps', 'SimulatedDrive', 'SimulatedBus', 'simulated_mechanism', 'wire_time',
           'receive']

log = logging.getLogger(__name__)

_STATUS_BITS = {
    NOT_READY: 0x00,
    SWITCH_ON_DISABLED: 0x40,
    READY_TO_SWITCH_ON: 0x31,
    SWITCHED_ON: 0x33,
    OPERATION_ENABLED: 0x37,
    QUICK_STOP_ACTIVE: 0x17,
    FAULT_REACTION_ACTIVE: 0x1F,
    FAULT: 0x08,
}
SW_REMOTE = 1 << 9
SW_TARGET_REACHED = 1 << 10
SW_SPEED_ZERO = 1 << 12         # profile velocity mode: "speed = 0"
SW_FOLLOWS = 1 << 12            # CSP: "drive follows the command value"
SW_FOLLOWING_ERROR = 1 << 13    # CSP: following error beyond the window
SW_HOMING_ATTAINED = 1 << 12    # homing mode
SW_HOMING_ERROR = 1 << 13       # homing mode
HOMING_METHODS = (19, 33, 34, 35, 37)

EMCY_ERROR_RESET = 0x0000

_NMT_CODE = {'INITIALISING': 0x00, 'STOPPED': 0x04, 'OPERATIONAL': 0x05, 'PRE-OPERATIONAL': 0x7F}


def _next_state(state: str, controlword: int, quick_stop_option: int) -> str:
    """One CiA 402 device-control transition for a controlword (bit 7 handled by the caller)."""
    if not controlword & 0x02:                                   # disable voltage
        if state in (READY_TO_SWITCH_ON, SWITCHED_ON, OPERATION_ENABLED, QUICK_STOP_ACTIVE):
            return SWITCH_ON_DISABLED
        return state
    if not controlword & 0x04:                                   # quick stop
        return {READY_TO_SWITCH_ON: SWITCH_ON_DISABLED, SWITCHED_ON: SWITCH_ON_DISABLED,
                OPERATION_ENABLED: QUICK_STOP_ACTIVE}.get(state, state)
    if not controlword & 0x01:                                   # shutdown
        if state in (SWITCH_ON_DISABLED, SWITCHED_ON, OPERATION_ENABLED):
            return READY_TO_SWITCH_ON
        return state
    if controlword & 0x08:                                       # (switch on +) enable operation
        if state == QUICK_STOP_ACTIVE:                           # transition 16: options 5..8 only
            return OPERATION_ENABLED if 5 <= quick_stop_option <= 8 else state
        return {READY_TO_SWITCH_ON: SWITCHED_ON, SWITCHED_ON: OPERATION_ENABLED}.get(state, state)
    return {READY_TO_SWITCH_ON: SWITCHED_ON, OPERATION_ENABLED: SWITCHED_ON}.get(state, state)


def _paced(stop_event: threading.Event, tick: float,
           work: Callable[[], object]) -> Iterator[tuple[float, float]]:
    """Every `tick` s until `stop_event`: run `work()` (read the bus), then yield (seconds since
    the last step, now). A loop that fell behind (a loaded machine) takes up its pace from now
    instead of catching up in a burst."""
    last = time.monotonic()
    next_tick = last
    while not stop_event.is_set():
        next_tick += tick
        delay = next_tick - time.monotonic()
        if delay > 0:
            stop_event.wait(delay)
        else:
            next_tick = time.monotonic()
        work()
        now = time.monotonic()
        dt, last = now - last, now
        yield dt, now


class Gaps:
    """Gaps between events on the receiver's clock: count, largest, and how many exceeded each
    of `limits` (s). Constant memory, one comparison per limit per event."""

    def __init__(self, limits: tuple[float, ...] = (0.05, 0.15, 0.2)) -> None:
        self.limits = tuple(limits)
        self.over = [0] * len(self.limits)
        self.count = 0
        self.max_gap = 0.0
        self._last: float | None = None

    def event(self, now: float) -> None:
        last, self._last = self._last, now
        if last is None:
            return
        gap = now - last
        self.count += 1
        self.max_gap = max(self.max_gap, gap)
        for i, limit in enumerate(self.limits):
            if gap > limit:
                self.over[i] += 1

    def restart(self) -> None:
        """The next event starts a new series (the sender stopped on purpose)."""
        self._last = None

    def summary(self) -> dict:
        return {'gaps': self.count, 'max': self.max_gap,
                'over': {f'{limit * 1e3:g} ms': n for limit, n in zip(self.limits, self.over)}}


class SimulatedDrive:
    """A CiA 402 profile-velocity drive on the bus, with a motor model and its own watchdog."""

    def __init__(self, bus_or_channel: can.BusABC | str, node_id: int = 1,
                 time_constant: float = 0.05, max_acceleration: float = 2000.0,
                 counts_per_motor_rev: int = 4096, *, interface: str = 'virtual',
                 eds_path: str | Path | None = None, tick: float = 0.002,
                 supported_modes: tuple[int, ...] = (PROFILE_VELOCITY,),
                 coast_time_constant: float = 0.5, network: canopen.Network | None = None,
                 gear_ratio: float = 1.0, motor_reversed: bool = False,
                 mechanical_offset: float = 0.0, home_switch_width: float = 0.2,
                 identity: tuple[int, int, int, int] = (0x0000_0000, 0x0000_0402, 1, 0),
                 record_bottom: bool = False,
                 sdo_delay: tuple[float, float] | None = None, sdo_slow_share: float = 1.0,
                 seed: int = 0) -> None:
        """Build the drive (no thread yet, call start()).

        bus_or_channel: a python-can bus this drive uses (left open on stop()), or a channel
        name for a bus of `interface` that the drive opens and closes itself.
        network: a canopen Network on that bus shared with other simulated drives (see
        `SimulatedBus`; its owner connects and stops it), else the drive makes its own.
        time_constant: s, first-order lag of the speed loop. max_acceleration: motor rad/s^2.
        counts_per_motor_rev: encoder increments per motor revolution (0x608F).
        supported_modes: modes the drive accepts in 0x6060 (0x6061 keeps its old value
        otherwise, as many drives do). coast_time_constant: s, speed decay with power off.
        gear_ratio: motor turns per mechanism turn. motor_reversed: the motor is wired so a
        positive motor turn turns the mechanism backwards. mechanical_offset: rad, mechanism
        angle of its bottom (tip lowest) from the encoder's zero, forward. home_switch_width:
        rad of mechanism angle the bottom proximity switch is active for, centred on the
        bottom. identity: 0x1018 vendor-ID, product code, revision, serial number.
        record_bottom: keep the instants the mechanism truly passes its bottom forwards (the
        tip lowest: a plant set; `bottom_times`, monotonic s), the truth a test measures the
        machine's own account of its plants against.
        sdo_delay: (shortest, longest) s a slow drive takes to answer each SDO request (one
        at a time, in order, drawn from a random stream seeded with `seed`); None: at once.
        sdo_slow_share: the share of SDO requests answered that late (the others at once).
        """
        if time_constant <= 0 or max_acceleration <= 0 or counts_per_motor_rev <= 0 or tick <= 0:
            raise ValueError('time_constant, max_acceleration, counts_per_motor_rev and tick '
                             'must be > 0')
        if isinstance(bus_or_channel, str):
            self._bus = can.Bus(interface=interface, channel=bus_or_channel)
            self._owns_bus = True
        else:
            self._bus = bus_or_channel
            self._owns_bus = False
        self.node_id = node_id
        self.time_constant = float(time_constant)
        self.max_acceleration = float(max_acceleration)
        self.counts_per_motor_rev = int(counts_per_motor_rev)
        self.coast_time_constant = float(coast_time_constant)
        self.supported_modes = tuple(supported_modes)
        self.tick = float(tick)
        self.gear_ratio = float(gear_ratio)
        self.motor_reversed = bool(motor_reversed)
        self.mechanical_offset = float(mechanical_offset)
        self.home_switch_width = float(home_switch_width)
        self.identity = tuple(int(v) for v in identity)
        self.record_bottom = bool(record_bottom)
        #: monotonic s at which the mechanism passed its bottom forwards (record_bottom)
        self.bottom_times: list[float] = []
        if sdo_delay is not None and not 0.0 <= sdo_delay[0] <= sdo_delay[1]:
            raise ValueError(f'sdo_delay = {sdo_delay!r}: allowed (shortest, longest) >= 0 s')
        self.sdo_delay = None if sdo_delay is None else (float(sdo_delay[0]),
                                                         float(sdo_delay[1]))
        self.sdo_slow_share = float(sdo_slow_share)
        self._random = random.Random(f'{seed}:{node_id}')

        self._lock = threading.RLock()
        self._stop_event = threading.Event()
        self._thread: threading.Thread | None = None

        self._owns_network = network is None
        self.network = network if network is not None else canopen.Network(self._bus)
        self.node = canopen.LocalNode(node_id, str(eds_path or default_eds_path()))
        # The heartbeat is sent by our thread, never by a send_periodic task: drop the NMT
        # slave's 0x1017 write hook that would start one.
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
        for pdo_map in self.node.rpdo.map.values():
            pdo_map.add_callback(self._on_rpdo)
        self._tx_lock = threading.Lock()          # one TPDO buffer, two sending threads

        self._reset_application()
        self._hb_enabled = True
        self._nmt_operational = False
        self._last_hb_sent = -math.inf
        self._tpdo_last_sent: dict[int, float] = {}
        self._consumed_heartbeat: float | None = None    # monotonic time of the master's last one
        self._sent_statusword: int | None = None
        #: Communication watchdog trips, newest last: (reason, emcy code).
        self.watchdog_trips: list[tuple[str, int]] = []
        #: Frames counted for tests and the demo summary.
        self.rpdo_count = 0
        self.tpdo_count = 0
        #: Gaps between command frames as this drive received them (its own clock).
        self.rpdo_gaps = Gaps()
        #: Gaps between SYNC frames (its own clock); late = over 1.5 periods (0x1006),
        #: missing = whole periods without one.
        self.sync_gaps = Gaps()
        #: Gaps between the master's heartbeats (bus time).
        self.heartbeat_gaps = Gaps()
        self.sync_count = 0
        self.sync_late = 0
        self.sync_missing = 0
        self.following_error_faults = 0
        self.last_following_fault = ''
        self.targets_missing = 0          # CSP: SYNCs that found no new target
        self._motor_time: float | None = None
        # fault injection: power (off until a time), slow SDO answers, EMCY storms
        self._powered = True
        self._power_on_at = 0.0
        self.power_cycles = 0
        self._sdo_queue: list[tuple[float, int, bytes, float]] = []   # (answer at, frame)
        self._sdo_free_at = 0.0
        self.sdo_requests = 0
        self.sdo_slow = 0                 # requests answered late
        self._storm: tuple[float, float, float, int] | None = None    # start, end, rate, code
        self._storm_sent = 0
        self.emcy_sent = 0

    # ---------------------------------------------------------------- life cycle
    def _reset_application(self) -> None:
        with self._lock:
            self.node.data_store.clear()
            self.node.data_store.setdefault(objs.ENCODER_INCREMENTS.index, {})[1] = struct.pack(
                '<I', self.counts_per_motor_rev)
            self._state = NOT_READY
            self._controlword = 0
            self._mode = 0
            self._target = 0                  # counts/s, 0x60FF
            # CSP: the target received since the last SYNC, and the segment the drive
            # interpolates over one SYNC period (from, to, start time)
            self._csp_pending: int | None = None
            self._csp_from = 0.0
            self._csp_to = 0.0
            self._csp_start = -math.inf
            self._csp_extrapolated = 0        # segments in a row without a new target
            self._sync_period = 0.0           # s, 0x1006 (0: not told)
            self._fe_window = math.inf        # counts, 0x6065
            self._fe_timeout = 0.0            # s, 0x6066
            self._fe_since: float | None = None
            self._following_error = 0.0       # counts
            self._last_sync: float | None = None
            self._syncs_seen = 0
            self._velocity = 0.0              # counts/s
            self._position = 0.0              # counts
            self._fault_code = 0
            self._fault_persistent = False
            self._error_code = 0              # 0x603F
            self._quick_stopped = False
            self._hold_state: str | None = None
            self._target_at_enable: int | None = None
            self._last_rpdo: float | None = None
            self._rpdo_deadline = 0.0         # s, 0 = off
            self._consumer_node = 0
            self._consumer_timeout = 0.0      # s, 0 = off
            self._heartbeat_period = self._od_default(objs.HEARTBEAT_PRODUCER.index) / 1000.0
            self._abort_option = self._od_default(objs.ABORT_CONNECTION.index)
            self._quick_stop_option = self._od_default(objs.QUICK_STOP_OPTION.index)
            self._polarity = 0                # 0x607E
            self._home_shift = 0.0            # counts: reported position - sign * motor counts
            self._homing: tuple[str, int, float] | None = None    # (phase, direction, speed)
            self._homing_attained = False
            self._homing_error = False

    def _od_default(self, index: int, subindex: int = 0) -> int:
        obj = self.node.object_dictionary[index]
        if subindex:
            obj = obj[subindex]
        return int(obj.default or 0)

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
            self._nmt_operational = False
            self._state = SWITCH_ON_DISABLED          # transition 1 after self-test

    def stop(self) -> None:
        """Stop the thread and the bus listener; close the bus if this drive opened it."""
        self._stop_event.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        if self._owns_bus:
            self._bus.shutdown()

    # ---------------------------------------------------------------- test / demo knobs
    def inject_fault(self, error_code: int = 0x7500, persistent: bool = False) -> None:
        """Fault now: fault reaction (quick-stop ramp) -> FAULT, 0x603F and an EMCY.

        A persistent fault survives fault-reset requests (the cause is still there)."""
        with self._lock:
            self._fault_code = int(error_code)
            self._fault_persistent = persistent
            self._error_code = int(error_code)
            powered = self._state in (OPERATION_ENABLED, QUICK_STOP_ACTIVE)
            self._state = FAULT_REACTION_ACTIVE if powered else FAULT
        self._send_emcy(error_code, register=0x01)
        self._send_state_tpdos()

    def clear_persistent_fault(self) -> None:
        """The fault cause went away: the next fault-reset edge clears it."""
        with self._lock:
            self._fault_persistent = False

    def send_emcy(self, error_code: int) -> None:
        """An EMCY without a state change (a warning-class event such as over-temperature)."""
        self._send_emcy(error_code, register=0x01)

    def set_heartbeat_enabled(self, on: bool) -> None:
        """Switch the heartbeat producer off/on (simulates a drive whose heartbeat is lost)."""
        with self._lock:
            self._hb_enabled = bool(on)

    def power_cycle(self, off_time: float = 0.5) -> None:
        """Power off now for `off_time` s, then boot again. Off, the drive sends and hears
        nothing and its load coasts down; at power-on it sends its boot-up message (700h + id,
        data 00h) and comes up pre-operational in SWITCH ON DISABLED with its object
        dictionary at the EDS defaults: PDO mapping, mode, SYNC, heartbeat and watchdog
        settings are gone until the master writes them again. What a drive keeps in
        non-volatile memory stays: the position of its absolute multi-turn encoder (0x6064
        goes on from where the shaft is), the polarity 0x607E and the home offset."""
        with self._lock:
            self._powered = False
            self._power_on_at = time.monotonic() + float(off_time)
            self._state = NOT_READY                   # power stage off: the load coasts
            self._nmt_operational = False
            self._storm = None
            self._sdo_queue.clear()
            self.power_cycles += 1
        self.rpdo_gaps.restart()
        self.sync_gaps.restart()
        self.heartbeat_gaps.restart()

    @property
    def powered(self) -> bool:
        return self._powered

    def _power_on(self) -> None:
        """Boot after a power cycle (lock not held): see `power_cycle`."""
        with self._lock:
            kept = (self._position, self._velocity, self._motor_time, self._polarity,
                    self._home_shift)
        self._reset_application()
        with self._lock:
            (self._position, self._velocity, self._motor_time, self._polarity,
             self._home_shift) = kept
            self._consumed_heartbeat = None
            self._sent_statusword = None
            self._tpdo_last_sent.clear()
            self._last_hb_sent = -math.inf
            self._powered = True
        self._boot()

    def emcy_storm(self, rate: float, seconds: float, code: int = 0x4210) -> None:
        """From now on for `seconds`, `rate` EMCY frames per second with `code` (a warning:
        the drive's state does not change), as a drive with a chattering sensor sends them."""
        now = time.monotonic()
        with self._lock:
            self._storm = (now, now + float(seconds), float(rate), int(code))
            self._storm_sent = 0

    def _step_faults(self, now: float) -> None:
        """The injected faults' share of a step: slow SDO answers due, an EMCY storm."""
        with self._lock:
            due = [item for item in self._sdo_queue if item[0] <= now]
            self._sdo_queue = [item for item in self._sdo_queue if item[0] > now]
            storm, burst = self._storm, 0
            if storm is not None:
                start, end, rate, code = storm
                burst = int((min(now, end) - start) * rate) - self._storm_sent
                self._storm_sent += max(burst, 0)
                if now >= end:
                    self._storm = None
        for _, can_id, data, stamp in due:
            self.node.sdo.on_request(can_id, data, stamp)
        for _ in range(burst):
            self._send_emcy(storm[3], register=0x01)

    def _on_sdo_request(self, can_id: int, data: bytes, timestamp: float) -> None:
        """An SDO request: answered at once, or by a slow drive after `sdo_delay` (one at a
        time, in order), or never while powered off."""
        if not self._powered:
            return
        self.sdo_requests += 1
        with self._lock:
            now = time.monotonic()
            slow = (self.sdo_delay is not None
                    and self._random.random() < self.sdo_slow_share)
            if not slow and now >= self._sdo_free_at:
                at = None
            else:
                at = max(now, self._sdo_free_at) + (self._random.uniform(*self.sdo_delay)
                                                    if slow else 0.0)
                self.sdo_slow += slow
                self._sdo_free_at = at
                self._sdo_queue.append((at, can_id, bytes(data), timestamp))
        if at is None:
            self.node.sdo.on_request(can_id, data, timestamp)

    def _on_nmt_command(self, can_id: int, data: bytes, timestamp: float) -> None:
        """An NMT command: LocalNode applies it to node.nmt, then we react (`_on_nmt`)."""
        if not self._powered:
            return
        self.node.nmt.on_command(can_id, data, timestamp)
        self._on_nmt(can_id, data, timestamp)

    def hold_state(self, state: str | None) -> None:
        """Refuse every transition out of `state` (e.g. STO active keeps SWITCHED ON)."""
        with self._lock:
            self._hold_state = state

    # ---------------------------------------------------------------- introspection (SI)
    @property
    def state(self) -> str:
        return self._state

    @property
    def statusword(self) -> int:
        with self._lock:
            return self._statusword()

    @property
    def controlword(self) -> int:
        return self._controlword

    @property
    def nmt_state(self) -> str:
        return self.node.nmt.state

    @property
    def mode_display(self) -> int:
        return self._mode

    @property
    def motor_velocity(self) -> float:
        """Motor shaft speed, rad/s."""
        return self._velocity * 2.0 * math.pi / self.counts_per_motor_rev

    @property
    def motor_position(self) -> float:
        """Motor shaft angle, rad."""
        return self._position * 2.0 * math.pi / self.counts_per_motor_rev

    @property
    def target_velocity(self) -> float:
        """Target velocity 0x60FF as last received, motor rad/s."""
        return self._target * 2.0 * math.pi / self.counts_per_motor_rev

    @property
    def target_counts(self) -> int:
        """Target velocity 0x60FF as last received, counts/s."""
        return self._target

    @property
    def target_at_enable(self) -> int | None:
        """0x60FF (counts/s) at the moment the drive last entered OPERATION ENABLED."""
        return self._target_at_enable

    @property
    def quick_stopped(self) -> bool:
        """A quick stop happened since the drive was last in OPERATION ENABLED."""
        return self._quick_stopped

    @property
    def error_code(self) -> int:
        return self._error_code

    @property
    def heartbeat_period(self) -> float:
        return self._heartbeat_period

    @property
    def following_error(self) -> float:
        """CSP: set point − actual position, motor rad."""
        return self._following_error * 2.0 * math.pi / self.counts_per_motor_rev

    def sync_summary(self) -> dict:
        """SYNC timing as this drive saw it (its own clock)."""
        return {'syncs': self.sync_count, 'late': self.sync_late, 'missing': self.sync_missing,
                'period': self._sync_period, 'gaps': self.sync_gaps.summary(),
                'targets_missing': self.targets_missing,
                'following_error_faults': self.following_error_faults}

    @property
    def mechanism_angle(self) -> float:
        """rad, the mechanism's true angle from its bottom (0 = tip lowest), forward +."""
        with self._lock:
            return self._mechanism_angle(self._position)

    def mechanism_angle_at(self, position: float) -> float:
        """The true mechanism angle from the bottom, wrapped to [-pi, pi), where the drive
        reports `position` (mechanism rad as the master counts them: 0x6064 increments over
        counts_per_motor_rev * gear_ratio, after polarity and homing)."""
        with self._lock:
            user = position * self.counts_per_motor_rev * self.gear_ratio / (2.0 * math.pi)
            counts = self._sign(0x80) * (user - self._home_shift)
            return _wrap_angle(self._mechanism_angle(counts))

    @property
    def home_switch(self) -> bool:
        """The bottom proximity switch is active."""
        with self._lock:
            return self._switch_active(self._position)

    def _mechanism_angle(self, counts: float) -> float:
        turns = counts / (self.counts_per_motor_rev * self.gear_ratio)
        wiring = -1.0 if self.motor_reversed else 1.0
        return wiring * 2.0 * math.pi * turns - self.mechanical_offset

    def _switch_active(self, counts: float) -> bool:
        return abs(_wrap_angle(self._mechanism_angle(counts))) <= 0.5 * self.home_switch_width

    def _sign(self, bit: int) -> float:
        """-1 where 0x607E inverts (bit 7 position, bit 6 velocity), else 1."""
        return -1.0 if self._polarity & bit else 1.0

    def _motor_target(self) -> float:
        """The profile velocity target at the motor (counts/s, polarity applied)."""
        return self._sign(0x40) * self._target

    # ---------------------------------------------------------------- object dictionary hooks
    def _statusword(self) -> int:
        sw = _STATUS_BITS[self._state] | SW_REMOTE
        if self._state == OPERATION_ENABLED and self._mode == CYCLIC_SYNC_POSITION:
            sw |= SW_FOLLOWS
            if abs(self._following_error) > self._fe_window:
                sw |= SW_FOLLOWING_ERROR
        if self._state == OPERATION_ENABLED and self._mode == objs.HOMING:
            if self._homing_attained:
                sw |= SW_HOMING_ATTAINED
            if self._homing_error:
                sw |= SW_HOMING_ERROR
            if self._homing is None:
                sw |= SW_TARGET_REACHED
        if self._state == OPERATION_ENABLED and self._mode == PROFILE_VELOCITY:
            target = self._motor_target()
            if abs(self._velocity - target) <= max(1.0, 0.01 * abs(target)):
                sw |= SW_TARGET_REACHED
            if abs(self._velocity) < 1.0:
                sw |= SW_SPEED_ZERO
        return sw

    def _on_read(self, index: int, subindex: int, od: ODVariable):
        """Live values for SDO uploads and TPDO filling."""
        with self._lock:
            if index == objs.STATUSWORD.index:
                return self._statusword()
            if index == objs.CONTROLWORD.index:
                return self._controlword
            if index == objs.MODES_DISPLAY.index:
                return self._mode
            if index == objs.POSITION_ACTUAL.index:
                return _wrap_i32(round(self._sign(0x80) * self._position + self._home_shift))
            if index == objs.VELOCITY_ACTUAL.index:
                return _clip_i32(round(self._sign(0x40) * self._velocity))
            if index == objs.TARGET_VELOCITY.index:
                return self._target
            if index == objs.TARGET_POSITION.index:
                return _wrap_i32(round(self._sign(0x80) * self._csp_to + self._home_shift))
            if index == objs.SUPPORTED_MODES.index:     # the EDS's, plus CSP if it has it
                return self._od_default(index) | sum(
                    MODE_SUPPORTED.get(mode, 0) for mode in self.supported_modes) | 0x20
            if index == objs.POLARITY.index:
                return self._polarity
            if index == objs.DIGITAL_INPUTS.index:
                return objs.DI_HOME_SWITCH if self._switch_active(self._position) else 0
            if index == objs.VENDOR_ID.index and 1 <= subindex <= 4:
                return self.identity[subindex - 1]
            if index == objs.ERROR_CODE.index:
                return self._error_code
            if index == objs.ERROR_REGISTER.index:
                return 0x01 if self._state in (FAULT, FAULT_REACTION_ACTIVE) else 0x00
        return None

    def _on_write(self, index: int, subindex: int, od: ODVariable, data: bytes) -> None:
        """SDO downloads and decoded RPDO entries land here before they are stored."""
        value = od.decode_raw(data)
        if index == objs.CONTROLWORD.index:
            self._apply_controlword(value)
        elif index == objs.TARGET_VELOCITY.index:
            with self._lock:
                self._target = value
        elif index == objs.TARGET_POSITION.index:
            with self._lock:
                if self._polarity & 0x80 or self._home_shift:     # to the motor's counts
                    value = _wrap_i32(round(self._sign(0x80) * (value - self._home_shift)))
                self._csp_pending = value
                if self._state != OPERATION_ENABLED or self._syncs_seen == 0:
                    self._csp_hold(self._unwrap(value))     # no SYNC yet: a set point
        elif index == objs.COMM_CYCLE_PERIOD.index:
            with self._lock:
                self._sync_period = value / 1e6
        elif index == objs.FOLLOWING_ERROR_WINDOW.index:
            with self._lock:
                self._fe_window = float(value)
        elif index == objs.FOLLOWING_ERROR_TIMEOUT.index:
            with self._lock:
                self._fe_timeout = value / 1000.0
        elif index == objs.MODES_OF_OPERATION.index:
            with self._lock:
                if value in self.supported_modes or value == objs.HOMING:
                    if value != self._mode:
                        self._homing = None
                        self._homing_attained = self._homing_error = False
                    self._mode = value
        elif index == objs.POLARITY.index:
            with self._lock:
                self._polarity = value
        elif index == objs.HEARTBEAT_PRODUCER.index:
            with self._lock:
                self._heartbeat_period = value / 1000.0
        elif index == objs.HEARTBEAT_CONSUMER.index and subindex == 1:
            with self._lock:
                self._consumer_node = (value >> 16) & 0x7F
                self._consumer_timeout = (value & 0xFFFF) / 1000.0
                self._consumed_heartbeat = None
            if self._consumer_node:
                self.network.subscribe(objs.heartbeat_cob(self._consumer_node),
                                       self._on_consumed_heartbeat)
        elif index == objs.ABORT_CONNECTION.index:
            with self._lock:
                self._abort_option = value
        elif index == objs.QUICK_STOP_OPTION.index:
            with self._lock:
                self._quick_stop_option = value

    def _unwrap(self, raw: int) -> float:
        """A 32-bit target position near the current set point (counts, unwrapped)."""
        return self._csp_to + _wrap_i32(int(raw) - round(self._csp_to))

    def _csp_hold(self, position: float) -> None:
        self._csp_from = self._csp_to = float(position)
        self._csp_start = -math.inf

    def _on_sync(self, can_id: int, data: bytes, timestamp: float) -> None:
        """SYNC: count its timing (its time on the bus, as a drive's hardware sees it); in CSP
        bring the motor up to that instant, take the target received since the last SYNC and
        interpolate to it over one period; send the synchronous TPDOs."""
        if not self._powered:
            return
        now = wire_time(timestamp)
        with self._lock:
            self._advance(now)
            self.sync_count += 1
            self.sync_gaps.event(now)
            period = self._sync_period
            if self._last_sync is not None and period > 0:
                gap = now - self._last_sync
                if gap > 1.5 * period:
                    self.sync_late += 1
                    self.sync_missing += max(int(round(gap / period)) - 1, 0)
            self._last_sync = now
            self._syncs_seen += 1
            if self._mode == CYCLIC_SYNC_POSITION and self._state == OPERATION_ENABLED:
                self._next_segment(now)
        if not self._nmt_operational:
            return
        try:
            for pdo_map in self.node.tpdo.map.values():
                if pdo_map.enabled and 1 <= (pdo_map.trans_type or 0) <= 240 and (
                        self._syncs_seen % pdo_map.trans_type == 0):
                    self._send_tpdo(pdo_map)
        except (can.CanError, RuntimeError, OSError) as exc:
            log.debug('simulated drive: TPDO send failed: %s', exc)

    #: a SYNC without a new target (lost on the bus, or late), or a SYNC lost: the set point
    #: goes on at the last segment's speed for at most this many periods, then holds
    EXTRAPOLATE_PERIODS = 1

    def _next_segment(self, now: float) -> None:
        """At a SYNC in CSP (lock held): interpolate from the set point to the target received
        since the last SYNC; without one, go on at the last segment's speed (extrapolation,
        at most EXTRAPOLATE_PERIODS in a row), then hold."""
        if self._csp_pending is not None:
            self._csp_from = self._csp_setpoint(now)
            self._csp_to = self._unwrap(self._csp_pending)
            self._csp_pending = None
            self._csp_extrapolated = 0
        else:
            self.targets_missing += 1
            step = self._csp_to - self._csp_from
            self._csp_from = self._csp_setpoint(now)
            self._csp_extrapolated += 1
            if self._csp_extrapolated > self.EXTRAPOLATE_PERIODS or not math.isfinite(
                    self._csp_start):
                step = 0.0
            self._csp_to = self._csp_from + step
        self._csp_start = now

    def _csp_reach(self) -> float:
        """How many periods the current segment's speed lasts: one, plus the extrapolation
        left when no SYNC comes (a lost SYNC)."""
        return 1.0 + max(self.EXTRAPOLATE_PERIODS - self._csp_extrapolated, 0)

    def _csp_setpoint(self, now: float) -> float:
        """The interpolated position set point (counts) at `now`: linear over one SYNC period
        from the previous target to the newest, extrapolated at that speed while a SYNC is
        missing (lock held)."""
        period = self._sync_period or 0.01
        share = min(max((now - self._csp_start) / period, 0.0), self._csp_reach())
        return self._csp_from + (self._csp_to - self._csp_from) * share

    def _on_consumed_heartbeat(self, can_id: int, data: bytes, timestamp: float) -> None:
        if self._powered and (can_id & 0x7F) == self._consumer_node:
            self._consumed_heartbeat = wire_time(timestamp)
            self.heartbeat_gaps.event(self._consumed_heartbeat)

    # ---------------------------------------------------------------- NMT and PDO
    def _on_nmt(self, can_id: int, data: bytes, timestamp: float) -> None:
        """React to an NMT command LocalNode has already applied to node.nmt."""
        state = self.node.nmt.state
        if state == 'INITIALISING':                  # reset node / reset communication
            if data[0] == 0x81:
                self._reset_application()
            self._boot()
            return
        operational = state == 'OPERATIONAL'
        if operational and not self._nmt_operational:
            self._load_pdo_configuration()
            self._tpdo_last_sent.clear()           # send every TPDO at the next tick
            self._sent_statusword = None
            self._nmt_operational = True
            self._send_state_tpdos()
        elif not operational:
            self._nmt_operational = False
            self.rpdo_gaps.restart()

    def _load_pdo_configuration(self) -> None:
        """Read the PDO mapping the master wrote (from our own object dictionary)."""
        self.node.rpdo.read()
        self.node.tpdo.read()
        deadline = 0.0
        for pdo_map in self.node.rpdo.map.values():
            if pdo_map.enabled and pdo_map.event_timer:
                deadline = pdo_map.event_timer / 1000.0
        with self._lock:
            self._rpdo_deadline = deadline
            self._last_rpdo = None                 # monitoring starts at the next RPDO

    def _on_rpdo(self, pdo_map: PdoMap) -> None:
        """Decode a received RPDO and copy it into the object dictionary (controlword last)."""
        if not self._nmt_operational:
            return
        self.rpdo_count += 1
        self.rpdo_gaps.event(wire_time(pdo_map.timestamp))
        with self._lock:
            self._last_rpdo = wire_time(pdo_map.timestamp)
        entries = sorted(pdo_map, key=lambda var: var.index == objs.CONTROLWORD.index)
        try:
            for var in entries:
                self.node.set_data(var.index, var.subindex, var.get_data())
        except canopen.SdoAbortedError as exc:
            log.warning('simulated drive: RPDO entry refused: %s', exc)

    def _send_tpdo(self, pdo_map: PdoMap) -> None:
        with self._tx_lock:
            for var in pdo_map:
                var.set_data(self.node.get_data(var.index, var.subindex))
            pdo_map.transmit()
            self.tpdo_count += 1

    def _send_state_tpdos(self) -> None:
        """Change-of-state event: send the TPDOs carrying the statusword now."""
        if not self._nmt_operational:
            return
        with self._lock:
            sw = self._statusword()
            if sw == self._sent_statusword:
                return
            self._sent_statusword = sw
        try:
            for number, pdo_map in self.node.tpdo.map.items():
                if pdo_map.enabled and any(var.index == objs.STATUSWORD.index for var in pdo_map):
                    self._send_tpdo(pdo_map)
                    self._tpdo_last_sent[number] = time.monotonic()
        except (can.CanError, RuntimeError, OSError) as exc:
            log.debug('simulated drive: TPDO send failed: %s', exc)

    # ---------------------------------------------------------------- state machine
    def _apply_controlword(self, controlword: int) -> None:
        with self._lock:
            rising_reset = bool(controlword & 0x80) and not self._controlword & 0x80
            homing_edge = bool(controlword & 0x10) and not self._controlword & 0x10
            if self._mode == objs.HOMING and self._state == OPERATION_ENABLED:
                if homing_edge:
                    self._start_homing()
                elif not controlword & 0x10 and self._homing is not None:
                    self._homing = ('stop', 1, 0.0)         # interrupted: stop, not attained
            self._controlword = controlword
            state = self._state
            reset_done = False
            if state == FAULT:
                if rising_reset and not self._fault_persistent:
                    self._fault_code = 0
                    self._error_code = 0
                    self._state = SWITCH_ON_DISABLED
                    reset_done = True
            elif state not in (NOT_READY, FAULT_REACTION_ACTIVE):
                for _ in range(3):
                    new = _next_state(state, controlword, self._quick_stop_option)
                    if new == state or state == self._hold_state:
                        break
                    state = new
                    if state == OPERATION_ENABLED:
                        self._target_at_enable = self._target
                        if self._mode == CYCLIC_SYNC_POSITION:
                            self._csp_hold(self._position)
                        self._quick_stopped = False
                    elif state == QUICK_STOP_ACTIVE:
                        self._quick_stopped = True
                self._state = state
        if reset_done:
            self._send_emcy(EMCY_ERROR_RESET, register=0)
        self._send_state_tpdos()

    def _comm_error(self, reason: str, code: int) -> None:
        """Abort connection option 0x6007: 0 none, 1 fault, 2 disable voltage, 3 quick stop."""
        with self._lock:
            self.watchdog_trips.append((reason, code))
            self._error_code = code
            option = self._abort_option
            if option == 1:
                self._fault_code = code
                self._state = FAULT_REACTION_ACTIVE
            elif option == 2:
                self._state = SWITCH_ON_DISABLED
            elif option == 3:
                self._state = QUICK_STOP_ACTIVE
                self._quick_stopped = True
        log.info('simulated drive: %s -> abort connection option %d', reason, option)
        self._send_emcy(code, register=0x10)
        self._send_state_tpdos()

    def _send_emcy(self, code: int, register: int) -> None:
        if not self._powered:
            return
        self.emcy_sent += 1
        try:
            self.network.send_message(objs.emcy_cob(self.node_id),
                                      EMCY_STRUCT.pack(code, register, b''))
        except (can.CanError, RuntimeError, OSError) as exc:
            log.debug('simulated drive: EMCY send failed: %s', exc)

    # ---------------------------------------------------------------- the thread
    def _run(self) -> None:
        for dt, now in _paced(self._stop_event, self.tick,
                              lambda: receive(self._bus, self.network)):
            if not self.step(dt, now):
                break

    def step(self, dt: float, now: float) -> bool:
        """One step of the drive's own work (motor, watchdogs, TPDOs, heartbeat); False once
        stopped."""
        try:
            if not self._powered:
                self._step_motor(dt, now)          # the load coasts, nothing is sent
                if now >= self._power_on_at:
                    self._power_on()
                return True
            self._step_faults(now)
            self._step_motor(dt, now)
            self._check_watchdogs(now)
            self._send_state_tpdos()
            self._send_cyclic(now)
        except (can.CanError, RuntimeError, OSError) as exc:
            if self._stop_event.is_set():
                return False
            log.warning('simulated drive: bus error: %s', exc)
        return True

    SERVO_STEP = 0.001      # s, the motor model's own step (a drive's servo loop never stalls)

    def _step_motor(self, dt: float, now: float | None = None) -> None:
        """The motor from its last instant to `now` (`dt` kept for callers: the model keeps
        its own time, so a thread that ran late, or frames handled late, change nothing)."""
        now = time.monotonic() if now is None else now
        with self._lock:
            fault = self._advance(now)
        if fault:
            log.warning('simulated drive %d: %s', self.node_id, self.last_following_fault)
            self.following_error_faults += 1
            self._fe_since = None
            self.inject_fault(EMCY_FOLLOWING_ERROR)

    def _advance(self, now: float) -> bool:
        """Integrate the motor in SERVO_STEP steps up to `now` (lock held); True when a CSP
        following error lasted beyond its time-out."""
        last = self._motor_time
        if last is None or now - last > 1.0:          # first step, or a paused simulation
            self._motor_time = now
            return False
        if now <= last:
            return False
        steps = max(1, math.ceil((now - last) / self.SERVO_STEP - 1e-9))
        h = (now - last) / steps
        fault = False
        for k in range(1, steps + 1):
            fault = self._motor_substep(h, last + k * h) or fault
        self._motor_time = now
        return fault

    def _motor_substep(self, dt: float, now: float) -> bool:
        to_counts = self.counts_per_motor_rev / (2.0 * math.pi)
        following_fault = False
        state = self._state
        v = self._velocity
        limit = self.max_acceleration * to_counts
        if state == OPERATION_ENABLED and self._mode == CYCLIC_SYNC_POSITION:
            # position loop on the interpolated set point, with its speed as feed-forward
            setpoint = self._csp_setpoint(now)
            period = self._sync_period or 0.01
            moving = now - self._csp_start < period * self._csp_reach()
            feed = (self._csp_to - self._csp_from) / period if moving else 0.0
            wanted = feed + (setpoint - self._position) / self.time_constant
            self._following_error = setpoint - self._position
            if abs(self._following_error) > self._fe_window:
                self._fe_since = now if self._fe_since is None else self._fe_since
                following_fault = now - self._fe_since >= self._fe_timeout
                if following_fault:
                    self.last_following_fault = (
                        f'following error {self._following_error:.0f} counts > window '
                        f'{self._fe_window:.0f} for {now - self._fe_since:.3f} s (set '
                        f'point {setpoint:.0f}, segment {self._csp_from:.0f} -> '
                        f'{self._csp_to:.0f} started {now - self._csp_start:.3f} s ago, '
                        f'speed {self._velocity:.0f} counts/s, dt {dt:.4f} s)')
            else:
                self._fe_since = None
        elif state == OPERATION_ENABLED and self._mode in (PROFILE_VELOCITY, objs.HOMING):
            target = self._motor_target() if self._mode == PROFILE_VELOCITY else (
                self._homing_velocity())
            ramp = (objs.PROFILE_ACCELERATION if abs(target) >= abs(v)
                    else objs.PROFILE_DECELERATION)
            accel = self._od_value(ramp.index)
            limit = min(limit, accel)
            wanted = v + (target - v) * (1.0 - math.exp(-dt / self.time_constant))
        elif state in (QUICK_STOP_ACTIVE, FAULT_REACTION_ACTIVE):
            limit = min(limit, self._od_value(objs.QUICK_STOP_DECELERATION.index))
            wanted = 0.0
        else:                                   # power stage off: the load coasts down
            wanted = v * math.exp(-dt / self.coast_time_constant)
        dv = max(-limit * dt, min(limit * dt, wanted - v))
        self._velocity = v + dv
        before = self._position
        self._position += 0.5 * (v + self._velocity) * dt
        if self._homing is not None and state == OPERATION_ENABLED:
            self._homing_step(before)
        if self.record_bottom:
            self._note_bottom(before, dt, now)
        stopped = abs(self._velocity) < 0.5
        if stopped and state == FAULT_REACTION_ACTIVE:
            self._state = FAULT
        elif (stopped and state == QUICK_STOP_ACTIVE
              and self._quick_stop_option in (1, 2, 3, 4)):
            self._state = SWITCH_ON_DISABLED
        return following_fault

    def _note_bottom(self, before: float, dt: float, now: float) -> None:
        """The mechanism's bottom passed forwards in the sub-step from `before` counts that
        ended at `now`: its instant, interpolated (lock held)."""
        a0 = self._mechanism_angle(before) / (2.0 * math.pi)
        a1 = self._mechanism_angle(self._position) / (2.0 * math.pi)
        if a1 > a0 and math.floor(a1) > math.floor(a0):
            share = (a1 - math.floor(a1)) / (a1 - a0)
            self.bottom_times.append(now - share * dt)

    # ---------------------------------------------------------------- homing (mode 6)
    def _start_homing(self) -> None:
        """Controlword bit 4 rising in homing mode (lock held): method 0x6098."""
        method = int(self._od_sub(objs.HOMING_METHOD))
        self._homing_attained = self._homing_error = False
        fast = self._od_sub(objs.HOMING_SPEED_SWITCH)
        slow = self._od_sub(objs.HOMING_SPEED_ZERO)
        if method not in HOMING_METHODS or (method < 35 and (fast <= 0 or slow <= 0)):
            self._homing_error = True
            self._homing = None
        elif method in (35, 37):                   # the current position is home
            self._set_home(self._position)
        elif method == 19:                         # home switch: its edge below the switch
            if self._switch_active(self._position):
                self._homing = ('leave', -1, slow)
            else:
                self._homing = ('search', 1, fast)
        else:                                      # 33 index pulse backwards, 34 forwards
            self._homing = ('index', 1 if method == 34 else -1, slow)

    def _homing_velocity(self) -> float:
        """The motor speed the homing phase asks for (counts/s)."""
        if self._homing is None:
            return 0.0
        _, direction, speed = self._homing
        return self._sign(0x40) * direction * speed

    def _homing_step(self, before: float) -> None:
        """After a motor sub-step from `before` counts: switch and index edges."""
        phase = self._homing[0]
        now = self._position
        if phase == 'search' and self._switch_active(now):
            self._homing = ('leave', -1, self._od_sub(objs.HOMING_SPEED_ZERO))
        elif phase == 'leave' and not self._switch_active(now):
            self._set_home(now)
        elif phase == 'index' and (math.floor(now / self.counts_per_motor_rev)
                                   != math.floor(before / self.counts_per_motor_rev)):
            index = self.counts_per_motor_rev * max(math.floor(now / self.counts_per_motor_rev),
                                                    math.floor(before / self.counts_per_motor_rev))
            self._set_home(index)
        elif phase == 'stop' and abs(self._velocity) < 0.5:
            self._homing = None

    def _set_home(self, counts: float) -> None:
        """The motor position `counts` becomes the home offset 0x607C; stop, attained."""
        offset = self._od_sub(objs.HOME_OFFSET)
        self._home_shift = offset - self._sign(0x80) * counts
        self._homing = ('stop', 1, 0.0) if abs(self._velocity) >= 0.5 else None
        self._homing_attained = True

    def _od_sub(self, obj: objs.Obj) -> float:
        raw = self.node.data_store.get(obj.index, {}).get(obj.subindex)
        if raw is None:
            return float(self._od_default(obj.index, obj.subindex))
        entry = self.node.object_dictionary[obj.index]
        if obj.subindex:
            entry = entry[obj.subindex]
        return float(entry.decode_raw(raw))

    def _od_value(self, index: int) -> float:
        raw = self.node.data_store.get(index, {}).get(0)
        if raw is None:
            return float(self._od_default(index))
        return float(self.node.object_dictionary[index].decode_raw(raw))

    def _check_watchdogs(self, now: float) -> None:
        with self._lock:
            if self._state != OPERATION_ENABLED:
                return
            rpdo_late = (self._rpdo_deadline > 0 and self._last_rpdo is not None
                         and now - self._last_rpdo > self._rpdo_deadline)
            hb = self._consumed_heartbeat
            hb_late = (self._consumer_timeout > 0 and hb is not None
                       and now - hb > self._consumer_timeout)
            if rpdo_late:
                self._last_rpdo = None              # re-armed by the next RPDO
            if hb_late:
                self._consumed_heartbeat = None     # re-armed by the next heartbeat
        if rpdo_late:
            self._comm_error('RPDO deadline (0x1400:5) expired', EMCY_RPDO_TIMEOUT)
        elif hb_late:
            self._comm_error('master heartbeat (0x1016) lost', EMCY_HEARTBEAT)

    def _send_cyclic(self, now: float) -> None:
        with self._lock:
            hb_due = (self._hb_enabled and self._heartbeat_period > 0
                      and now - self._last_hb_sent >= self._heartbeat_period)
        if hb_due:
            self._last_hb_sent = now
            self.network.send_message(objs.heartbeat_cob(self.node_id),
                                      bytes([_NMT_CODE.get(self.node.nmt.state, 0x7F)]))
        if not self._nmt_operational:
            return
        for number, pdo_map in self.node.tpdo.map.items():
            if (not pdo_map.enabled or not pdo_map.event_timer
                    or (pdo_map.trans_type or 255) <= 240):
                continue
            if now - self._tpdo_last_sent.get(number, -math.inf) >= pdo_map.event_timer / 1000.0:
                self._tpdo_last_sent[number] = now
                self._send_tpdo(pdo_map)


class SimulatedBus:
    """Several simulated drives as devices on one cable: one python-can bus and one canopen
    Network for all of them (one receiving bus in the process, not one per drive, so a frame
    sent to N drives is copied once, as on a real bus). `drives[i]` has node id `node_ids[i]`;
    keyword arguments go to every SimulatedDrive."""

    def __init__(self, channel: str | can.BusABC, node_ids: Iterable[int], *,
                 interface: str = 'virtual', tick: float = 0.002,
                 node_kwargs: dict | None = None, **drive_kwargs: Any) -> None:
        """`channel`: a channel name of `interface` (opened here), or an open python-can bus
        (e.g. one end of a socket pair to a master in another process; shut down on stop).
        `node_kwargs`: node id (int or its text) -> keyword arguments of that drive alone (its
        gear, wiring, mechanical offset), over the common ones."""
        self.bus = (channel if isinstance(channel, can.BusABC)
                    else can.Bus(interface=interface, channel=channel))
        self.network = canopen.Network(self.bus)
        self.tick = float(tick)
        own = {int(node): dict(kwargs) for node, kwargs in (node_kwargs or {}).items()}
        self.drives = [SimulatedDrive(self.bus, node_id=node_id, network=self.network,
                                      tick=tick, **{**drive_kwargs, **own.get(node_id, {})})
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
            for dt, now in _paced(self._stop_event, self.tick,
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


def simulated_mechanism(seed: int, node_id: int, power_up: int = 0) -> tuple[float, bool]:
    """(mechanical offset rad, motor reversed) of a simulated row: the wiring fixed by `seed`
    and the node id (the machine's), the offset between the encoder's zero and the bottom by
    the power-up too (an incremental encoder counts from wherever the motor was at power-up):
    commissioning runs power-up 0, a later start another, and the homing must find the same
    bottom."""
    import numpy as np
    wiring = np.random.default_rng([seed, node_id])
    offset = np.random.default_rng([seed, node_id, power_up])
    return float(offset.uniform(0.0, 2.0 * math.pi)), bool(wiring.random() < 0.5)


def wire_time(timestamp: float | None) -> float:
    """A received frame's time on the bus, on the monotonic clock: python-can stamps a frame
    with the wall clock (the virtual bus when it is sent, SocketCAN when the kernel receives
    it), so its age is subtracted from now; now for a frame without a stamp."""
    now = time.monotonic()
    if timestamp is None or not math.isfinite(timestamp) or timestamp <= 0.0:
        return now
    return now - max(time.time() - timestamp, 0.0)


def receive(bus: can.BusABC, network: canopen.Network) -> None:
    """Decode every frame waiting on `bus` (canopen's own listener does the same from a thread
    of its own): the simulated drives' thread calls this before each step, so a watchdog is
    never judged with frames still waiting in the queue."""
    while True:
        msg = bus.recv(timeout=0.0)
        if msg is None:
            return
        if msg.is_error_frame or msg.is_remote_frame:
            continue
        try:
            network.notify(msg.arbitration_id, msg.data, msg.timestamp)
        except Exception as exc:     # a callback's error must not stop the drive, as canopen
            log.error('simulated drive: %s', exc)


def _wrap_i32(value: int) -> int:
    return (value + 2**31) % 2**32 - 2**31


def _clip_i32(value: int) -> int:
    return max(-2**31, min(2**31 - 1, value))


def _wrap_angle(angle: float) -> float:
    """`angle` wrapped to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi
