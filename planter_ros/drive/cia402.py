"""CiA 402 servo drive master over CANopen (profile velocity mode), on a python-can bus.

The one CAN protocol module of planter_ros. It uses the `canopen` library (Network on a
python-can bus, BaseNode402 with the drive's EDS) for SDO, NMT, PDO encoding, EMCY and the
statusword decoding, and keeps every blocking call out of the real-time path.

`CanopenBus` owns the python-can bus and its canopen Network and sends the master's heartbeat
(once per bus); `Cia402Drive` is the master of one drive (one node id) on such a bus. Several
drives share one `CanopenBus` (a machine with a drive per row); a drive given none opens its own.

* ``connect_and_enable()`` and ``shutdown()`` block (SDO, waits with timeouts): call them at
  node start-up / shutdown or from a worker thread, never from a ROS or CAN callback.
* ``send_velocity()``, ``send_heartbeat()``, ``status()`` and ``request_fault_reset()`` never
  block: one CAN frame at most, or a snapshot of what the bus callbacks collected.

canopen's BaseNode402 blocking helpers are not used for the same reason: its ``state`` setter
busy-waits, ``reset_from_fault()`` always waits its full timeout, and the ``op_mode`` setter
logs instead of raising (we write 0x6060 and read 0x6061 back ourselves).

Drive-side watchdog (the motor stops if this process dies or hangs), both reacting with the
abort connection option 0x6007 = 3 (quick stop):
* RPDO deadline monitoring: the RPDO's event timer 0x1400:5 = ``command_timeout``; the drive
  expects a command frame at least that often (CiA 301 deadline monitoring, EMCY 0x8250).
* heartbeat consumer 0x1016:1 watches our heartbeat (node ``master_node_id``) with
  ``master_heartbeat_timeout`` (EMCY 0x8130).
Both are armed by the first frame they see, so a control loop must start sending within
``command_timeout`` after ``connect_and_enable()`` returns. No ``send_periodic`` anywhere:
on SocketCAN it is a kernel job that keeps sending while the process hangs.

Units: mechanism rad and rad/s at the API; on the bus 0x60FF / 0x606C are encoder increments
per second and 0x6064 increments (``counts_per_motor_rev`` per motor revolution,
``motor_gear_ratio`` motor revolutions per mechanism revolution).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
import logging
import math
from pathlib import Path
import threading
import time
from typing import TYPE_CHECKING

import can
import canopen
from canopen.pdo.base import PDO_NOT_VALID
from canopen.profiles.p402 import BaseNode402
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from planter_ros.drive import objects as od
from planter_ros.drive.config import BusConfig, DeviceConfig, DriveConfig
from planter_ros.drive.eds import default_eds_path
from planter_ros.drive.setup import (HOMING_SEARCH_SPEED, HOMING_ZERO_SPEED, DriveSetup,
                                     eds_mismatch, homing_timeout, identity_mismatch,
                                     missing_modes, pdo_mismatch)
from planter_ros.drive.errors import (BusError, DriveConfigError, DriveError,
                                      DriveRefusedError, DriveTimeoutError, NotConnectedError)
from planter_ros.drive.states import (
    ABORT_OPTION_QUICK_STOP, CYCLIC_SYNC_POSITION, MODE_SUPPORTED, CW_DISABLE_VOLTAGE,
    CW_ENABLE_OPERATION, CW_FAULT_RESET,
    CW_QUICK_STOP, CW_SHUTDOWN, CW_SWITCH_ON, EMCY_HEARTBEAT, FAULT, FAULT_REACTION_ACTIVE,
    NOT_READY, OPERATION_ENABLED, PROFILE_VELOCITY, PROFILE_VELOCITY_SUPPORTED,
    QUICK_STOP_ACTIVE, READY_TO_SWITCH_ON, SWITCH_ON_DISABLED, SWITCHED_ON, state_of)

if TYPE_CHECKING:
    from collections.abc import Callable

    from canopen.emcy import EmcyError
    from canopen.pdo.base import PdoMap

__all__ = ['BusConfig', 'CanopenBus', 'Cia402Drive', 'DeviceConfig', 'DriveConfig', 'DriveError',
           'DriveStatus']

log = logging.getLogger(__name__)

_INT32 = (-2**31, 2**31 - 1)
SDO_ATTEMPTS = 2            # each SDO request is sent at most this often (sdo_timeout each)
_NMT_OPERATIONAL = 0x05
NMT_REPEAT = 0.1          # s between two NMT start commands while the drive has not answered
_MODE_NAMES = {PROFILE_VELOCITY: 'profile velocity', CYCLIC_SYNC_POSITION: 'cyclic synchronous '
               'position'}


def _wrap_i32(value: int) -> int:
    return (value + 2**31) % 2**32 - 2**31

# Fault-reset / re-enable: the controlword that moves each state one step towards
# OPERATION ENABLED (fault state handled separately: one reset edge per request).
_REENABLE_STEP = {
    SWITCH_ON_DISABLED: CW_SHUTDOWN,
    READY_TO_SWITCH_ON: CW_SWITCH_ON,
    SWITCHED_ON: CW_ENABLE_OPERATION,
    QUICK_STOP_ACTIVE: CW_DISABLE_VOLTAGE,      # via SWITCH ON DISABLED (always allowed)
    NOT_READY: CW_DISABLE_VOLTAGE,
    FAULT_REACTION_ACTIVE: CW_DISABLE_VOLTAGE,
}


@dataclass(frozen=True)
class DriveStatus:                             # snapshot, built without blocking
    state: str                                 # CiA 402 state name (drive.states) or 'UNKNOWN'
    statusword: int
    fault: bool                                # statusword bit 3 or an EMCY since the last reset
    error_code: int                            # 0x603F / last EMCY code, 0 if none
    position: float                            # mechanism angle (rad, unwrapped, from 0x6064)
    velocity: float                            # mechanism speed (rad/s, from 0x606C)
    heartbeat_age: float                       # s since the drive's last heartbeat (inf if never)
    stamp: float                               # time.monotonic() of the last feedback TPDO
    fault_reason: str = ''                     # why `fault` is set ('' when not), for diagnostics
    heartbeat_lost: bool = False               # heartbeat_age > drive_heartbeat_timeout
    resetting: bool = False                    # a requested fault reset is in progress
    enabled: bool = False                      # connected, OPERATION ENABLED, taking commands
    commanded_velocity: float = 0.0            # mechanism rad/s in the last RPDO sent
    mode: int = 0                              # 3 profile velocity, 8 CSP (0 before enable)
    commanded_position: float = math.nan       # CSP: mechanism rad in the last RPDO sent
    restarted: str = ''                        # why the drive must be configured again (it
                                               # booted, or its heartbeat says it is not
                                               # operational): '' when it need not


class _ReceiveErrors(can.Listener):
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
    """One python-can bus with its canopen Network (a notifier thread runs the callbacks of
    every node on it) and the master's heartbeat. Uses the bus fields of `config`
    (can_interface, can_channel, can_bitrate, master_node_id); `bus` = an open python-can bus
    to use (left open on close)."""

    def __init__(self, config: BusConfig, bus: can.BusABC | None = None) -> None:
        self.config = config
        self._given_bus = bus
        self._bus: can.BusABC | None = None
        self.network: canopen.Network | None = None
        self._lock = threading.Lock()
        #: receive errors survived by the notifier thread (bus-off, interface down)
        self.receive_errors = _ReceiveErrors()

    @property
    def where(self) -> str:
        return f'{self.config.can_interface}:{self.config.can_channel}'

    def open(self) -> canopen.Network:
        """Open the bus and start the Network (idempotent). Raises BusError."""
        with self._lock:
            if self.network is not None:
                return self.network
            cfg = self.config
            try:
                self._bus = self._given_bus or can.Bus(
                    interface=cfg.can_interface, channel=cfg.can_channel, bitrate=cfg.can_bitrate)
            except Exception as exc:
                raise BusError(f'open bus: {self.where}: {type(exc).__name__}: {exc}') from None
            network = canopen.Network(self._bus)
            network.NOTIFIER_CYCLE = 0.05                 # close() waits at most this long
            network.connect()
            network.notifier.add_listener(self.receive_errors)
            self.receive_errors.notifier = network.notifier
            self.network = network
            return network

    def send_heartbeat(self) -> None:
        """Our heartbeat frame (NMT state operational), for every drive's consumer.
        NON-BLOCKING. Raises NotConnectedError before open(), BusError on a send error."""
        network = self.network
        if network is None:
            raise NotConnectedError(f'CAN bus {self.where}: not open (no heartbeat sent)')
        try:
            network.send_message(od.heartbeat_cob(self.config.master_node_id), b'\x05')
        except Exception as exc:            # python-can raises CanError, OSError, ValueError...
            raise BusError(f'CAN send of heartbeat failed on {self.where}: '
                           f'{type(exc).__name__}: {exc}') from None

    def send_sync(self) -> None:
        """One SYNC frame (COB-ID 80h, no data): the drives in CSP apply the position targets
        received since the last one. NON-BLOCKING; raises NotConnectedError / BusError."""
        network = self.network
        if network is None:
            raise NotConnectedError(f'CAN bus {self.where}: not open (no SYNC sent)')
        try:
            network.send_message(od.SYNC_COB, b'')
        except Exception as exc:            # python-can raises CanError, OSError, ValueError...
            raise BusError(f'CAN send of SYNC failed on {self.where}: '
                           f'{type(exc).__name__}: {exc}') from None

    def close(self) -> None:
        """Stop the Network's notifier; shut the bus down if this object opened it."""
        with self._lock:
            network, self.network = self.network, None
            if network is not None and network.notifier is not None:
                network.notifier.stop(1.0)
            if self._given_bus is None and self._bus is not None:
                self._bus.shutdown()
            self._bus = None


class Cia402Drive:
    """Master for one CiA 402 drive in profile velocity mode (see the module docstring).

    `bus`: an open python-can bus to use; `canbus`: a `CanopenBus` shared with other drives
    (then this drive neither opens nor closes the bus, and the master heartbeat is the
    CanopenBus's to send)."""

    def __init__(self, config: DriveConfig, bus: can.BusABC | None = None,
                 canbus: CanopenBus | None = None, setup: DriveSetup | None = None) -> None:
        self.config = config
        #: what the machine file says of this drive: checked and applied at every configure
        self.setup = setup
        self._owns_canbus = canbus is None
        self.canbus = canbus if canbus is not None else CanopenBus(config, bus)
        self._network: canopen.Network | None = None
        self._node: BaseNode402 | None = None
        self._rpdo = None
        self._rpdo_packed = False     # RPDO1 has the layout self._layout packs
        self.mode = 0                 # chosen at enable: PROFILE_VELOCITY or CYCLIC_SYNC_POSITION
        self._layout = od.RPDO_VELOCITY
        self._target_counts: int | None = None    # CSP: last target position sent (raw)
        self._connected = False       # bus open, PDOs configured, drive operational
        self._enabled = False         # enable sequence finished (cleared by shutdown)
        self._lock = threading.Lock()             # feedback and fault fields
        self._tx_lock = threading.Lock()          # the RPDO buffer and its frame
        self._feedback = threading.Condition(self._lock)
        self._rad_per_count = 2.0 * math.pi / (config.counts_per_motor_rev
                                              * config.motor_gear_ratio)
        # feedback (written by bus callbacks)
        self._statusword = 0
        self._sw_received = False
        self._status_stamp = 0.0
        self._error_code = 0
        self._raw_position: int | None = None
        self._position_counts = 0
        self._velocity_counts = 0
        self._motion_stamp = 0.0
        # latched faults (cleared only by request_fault_reset)
        self._emcy_code = 0
        self._latched_reason = ''
        # reset sequence
        self._reset_requested = False
        self._reset_deadline = 0.0
        self._reset_edge_sent = False
        self._last_controlword = 0
        self._commanded = 0.0
        self._commanded_position = math.nan
        #: measured at the last connect_and_enable (s)
        self.enable_duration = math.nan
        # restarts (a power cycle) and EMCYs counted (callbacks)
        self._restarted = ''
        #: EMCY frames received (every one, warnings and error resets too) and the last code
        self.emcy_count = 0
        self.last_emcy_code = 0

    @property
    def node(self) -> BaseNode402 | None:
        """The canopen node (diagnostics and benchmarks; its SDO calls block: never from a
        callback or the control loop)."""
        return self._node

    # ------------------------------------------------------------------ helpers
    def _counts_per_s(self, speed: float) -> int:
        counts = round(speed / self._rad_per_count)
        if not _INT32[0] <= counts <= _INT32[1]:
            limit = _INT32[1] * self._rad_per_count
            raise DriveError(f'speed {speed!r} rad/s is out of range (allowed: |speed| <= '
                             f'{limit:.6g} rad/s)')
        return counts

    def _fail(self, step: str, detail: str, kind: type = DriveError) -> DriveError:
        return kind(f'drive node {self.config.drive_node_id}: {step}: {detail}')

    def _sdo_write(self, step: str, index: int, subindex: int | None, value: int) -> None:
        try:
            var = self._node.sdo[index] if subindex is None else self._node.sdo[index][subindex]
            var.raw = value
        except SdoCommunicationError as exc:
            raise self._fail(step, f'no SDO answer writing 0x{index:04X}'
                                   f'{self._sdo_wait_text()} ({exc})',
                             DriveTimeoutError) from None
        except (SdoAbortedError, KeyError) as exc:
            raise self._fail(step, f'drive refused 0x{index:04X}={value} ({exc})',
                             DriveRefusedError) from None
        except Exception as exc:             # python-can: CanError, OSError, ValueError...
            raise self._fail(step, f'CAN send failed: {type(exc).__name__}: {exc}',
                             BusError) from None

    def _sdo_read(self, step: str, index: int, subindex: int | None = None,
                  optional: bool = False):
        try:
            var = self._node.sdo[index] if subindex is None else self._node.sdo[index][subindex]
            return var.raw
        except SdoCommunicationError as exc:
            raise self._fail(step, f'no SDO answer reading 0x{index:04X}'
                                   f'{self._sdo_wait_text()} '
                                   f'(is the drive on {self.config.can_interface}:'
                                   f'{self.config.can_channel} as node '
                                   f'{self.config.drive_node_id}? {exc})',
                             DriveTimeoutError) from None
        except (SdoAbortedError, KeyError) as exc:
            if optional:
                return None
            raise self._fail(step, f'drive refused reading 0x{index:04X} ({exc})',
                             DriveRefusedError) from None
        except Exception as exc:             # python-can: CanError, OSError, ValueError...
            raise self._fail(step, f'CAN send failed: {type(exc).__name__}: {exc}',
                             BusError) from None

    def _write(self, step: str, obj: od.Obj, value: int) -> None:
        self._sdo_write(step, obj.index, obj.subindex or None, value)

    def _read(self, step: str, obj: od.Obj, optional: bool = False) -> int | None:
        return self._sdo_read(step, obj.index, obj.subindex or None, optional)

    def _send(self, what: str, send: Callable[[], object]) -> None:
        """Run one frame-sending call; any CAN/bus failure becomes a one-line BusError."""
        try:
            send()
        except DriveError:
            raise
        except Exception as exc:            # python-can raises CanError, OSError, ValueError...
            raise BusError(f'drive node {self.config.drive_node_id}: CAN send of {what} failed '
                           f'on {self.config.can_interface}:{self.config.can_channel}: '
                           f'{type(exc).__name__}: {exc}') from None

    # ------------------------------------------------------------------ bus callbacks
    def _on_status_tpdo(self, pdo_map: PdoMap) -> None:
        now = time.monotonic()
        values = {var.index: var.raw for var in pdo_map}
        with self._feedback:
            if od.STATUSWORD.index in values:
                self._statusword = values[od.STATUSWORD.index]
                self._sw_received = True
                self._status_stamp = now
                if (self._enabled and not self._reset_requested and not self._latched_reason
                        and state_of(self._statusword) != OPERATION_ENABLED):
                    self._latched_reason = ('drive left OPERATION ENABLED '
                                            f'({state_of(self._statusword)})')
            if od.ERROR_CODE.index in values:
                self._error_code = values[od.ERROR_CODE.index]
            if od.POSITION_ACTUAL.index in values:
                raw = values[od.POSITION_ACTUAL.index]
                if self._raw_position is None:
                    self._position_counts = raw
                else:                               # unwrap the 32-bit counter
                    self._position_counts += (raw - self._raw_position + 2**31) % 2**32 - 2**31
                self._raw_position = raw
                self._motion_stamp = now
            if od.VELOCITY_ACTUAL.index in values:
                self._velocity_counts = values[od.VELOCITY_ACTUAL.index]
                self._motion_stamp = now
            self._feedback.notify_all()

    def _on_emcy(self, entry: EmcyError) -> None:
        if entry.code & 0xFF00 == 0:                # "error reset / no error"
            return
        with self._lock:
            self._emcy_code = entry.code
            if not self._latched_reason:
                desc = entry.get_desc() or 'drive error'
                self._latched_reason = f'EMCY 0x{entry.code:04X} ({desc})'

    EMCY_KEPT = 100     # canopen's EMCY log and active list are trimmed to this many

    def _count_emcy(self, entry: EmcyError) -> None:
        """Count every EMCY; keep canopen's lists of them bounded (a drive in an EMCY storm
        sends hundreds a second: its log would grow without end)."""
        self.emcy_count += 1
        self.last_emcy_code = entry.code
        emcy = self._node.emcy if self._node is not None else None
        if emcy is not None and len(emcy.log) > 2 * self.EMCY_KEPT:
            with emcy.emcy_received:
                del emcy.log[:-self.EMCY_KEPT]
                del emcy.active[:-self.EMCY_KEPT]

    def _on_nmt_state(self, state: int) -> None:
        """The drive's heartbeat or boot-up message (NMT state; 00h = boot-up). A drive we
        enabled that boots, or says it is not operational, has lost its configuration (a
        power cycle, a reset): latched, and `status().restarted` says why until
        `reconfigure()` has brought it back."""
        if state == _NMT_OPERATIONAL:
            return
        with self._lock:
            if not self._enabled or self._restarted:
                return
            self._restarted = ('boot-up message' if state == 0
                               else f'its heartbeat says NMT state 0x{state:02X}')
            self._latched_reason = f'drive restarted ({self._restarted})'

    def reconfigure(self) -> None:
        """BLOCKING: configure and enable again a drive that restarted (`status().restarted`)
        through the one start-up path, `connect_and_enable` (PDO mapping, mode, SYNC,
        heartbeats, watchdogs, the enable steps). Until it returns the drive is not enabled:
        send it nothing meanwhile (its enable steps send their own frames). Raises DriveError
        (then call again: the drive is still to be configured)."""
        with self._lock:
            self._enabled = False
            self._connected = False
            self._reset_requested = False
            self._latched_reason = self._latched_reason or 'drive being configured again'
        self.connect_and_enable()
        with self._lock:
            self._restarted = ''

    def probe_restart(self, timeout: float = 0.2) -> bool:
        """BLOCKING (one SDO read, at most `timeout` s): whether a drive whose heartbeat is
        lost restarted with its boot-up message lost on the bus: its heartbeat producer 0x1017
        no longer reads what we wrote. Then `status().restarted` says so. Raises DriveError
        when it does not answer (still off). Not while another SDO transfer to this drive
        runs (the caller's to ensure: its SDO timeout is borrowed meanwhile)."""
        self._check_open()
        sdo = self._node.sdo
        kept = sdo.RESPONSE_TIMEOUT, sdo.MAX_RETRIES
        sdo.RESPONSE_TIMEOUT, sdo.MAX_RETRIES = timeout, 1
        try:
            period = self._read('is the drive restarted? (0x1017 heartbeat producer)',
                                od.HEARTBEAT_PRODUCER)
        finally:
            sdo.RESPONSE_TIMEOUT, sdo.MAX_RETRIES = kept
        if period == round(self.config.drive_heartbeat_period * 1000):
            return False
        with self._lock:
            if not self._enabled or self._restarted:
                return bool(self._restarted)
            self._restarted = f'its heartbeat producer 0x1017 reads {period} ms: it lost its ' \
                              'configuration'
            self._latched_reason = f'drive restarted ({self._restarted})'
        return True

    def _sdo_wait_text(self) -> str:
        return (f' within {SDO_ATTEMPTS} x {self.config.sdo_timeout:g} s (sdo_timeout, asked '
                f'{SDO_ATTEMPTS} times)')

    def _heartbeat_age(self) -> float:
        stamp = self._node.nmt.timestamp if self._node is not None else None
        if stamp is None:
            return math.inf
        return max(0.0, time.time() - stamp)   # frame timestamps are wall-clock (python-can)

    # ------------------------------------------------------------------ blocking: enable
    def connect_and_enable(self) -> None:
        """Open the bus, configure the drive and enable it (BLOCKING; raises DriveError).

        NMT pre-operational; SDO: identify (0x1000, 0x6502, 0x608F), the machine file's checks
        (`setup`: 0x1018, 0x6502, the drive's EDS), PDO mapping written and read back, heartbeat
        both ways, watchdog (0x1400:5 deadline, 0x6007 = quick stop), 0x60FF = 0, the
        machine file's polarity (0x607E), mode 3 confirmed via 0x6061; NMT operational; then
        0x06 -> 0x07 -> 0x0F, each step waiting at most step_timeout for the statusword; then
        homing with the machine file's method. A drive found in FAULT is only reset if
        request_fault_reset() was called first. After this returns, the control loop must call
        send_velocity() at least every command_timeout and send_heartbeat() every
        heartbeat_period, or the drive's watchdog quick-stops the motor.
        """
        if self._enabled:
            return
        t_start = time.monotonic()
        self._open()
        self._send('NMT pre-operational',
                   lambda: setattr(self._node.nmt, 'state', 'PRE-OPERATIONAL'))
        self._identify()
        self._check_setup()
        self._configure_pdos()
        self._verify_pdos()
        heartbeat_written = time.time()
        self._configure_watchdogs()
        self._apply_polarity()
        if self.mode == CYCLIC_SYNC_POSITION:
            self._configure_csp()
        self._select_mode()
        self._wait_drive_heartbeat(since=heartbeat_written)
        self._go_operational()
        self._enable_state_machine()
        self._home_at_start()
        self.enable_duration = time.monotonic() - t_start
        log.info('drive node %d enabled in %.1f ms (%s)', self.config.drive_node_id,
                 1000 * self.enable_duration, _MODE_NAMES[self.mode])

    def _identify(self) -> None:
        """Refuse a node that is not the drive the configuration describes."""
        cfg = self.config
        step = 'identify (SDO 0x1000 device type)'
        device_type = self._read(step, od.DEVICE_TYPE)
        if device_type & 0xFFFF != 402:
            raise self._fail(step, f'device type 0x{device_type:08X} is not a CiA 402 drive',
                             DriveRefusedError)
        step = 'choose the operation mode (0x6502 supported drive modes)'
        modes = self._read(step, od.SUPPORTED_MODES, optional=True)
        wanted = cfg.operation_mode
        if modes is None:                     # not said: profile velocity, as before
            modes = PROFILE_VELOCITY_SUPPORTED
        csp = bool(modes & MODE_SUPPORTED[CYCLIC_SYNC_POSITION])
        if wanted == 'csp' and not csp:
            raise self._fail(step, f'supported drive modes 0x{modes:08X} lack cyclic '
                                   'synchronous position (bit 7); set operation_mode to '
                                   'velocity or auto', DriveRefusedError)
        if wanted == 'csp' or (wanted == 'auto' and csp):
            self.mode = CYCLIC_SYNC_POSITION
        elif not modes & PROFILE_VELOCITY_SUPPORTED:
            raise self._fail(step, f'supported drive modes 0x{modes:08X} lack profile velocity '
                                   '(bit 2)', DriveRefusedError)
        else:
            self.mode = PROFILE_VELOCITY
        self._layout = od.rpdo_for_mode(self.mode)
        step = 'check encoder resolution (0x608F)'
        increments = self._read(step, od.ENCODER_INCREMENTS, optional=True)
        revolutions = self._read(step, od.ENCODER_MOTOR_REVOLUTIONS, optional=True)
        if increments and revolutions and increments / revolutions != cfg.counts_per_motor_rev:
            raise self._fail(step, f'drive counts {increments}/{revolutions} increments per motor '
                                   f'rev but counts_per_motor_rev={cfg.counts_per_motor_rev}',
                             DriveRefusedError)

    def _check_setup(self) -> None:
        """Refuse a drive that is not the one the machine file describes: its identity
        (0x1018 as the file states it), the modes the row needs (0x6502) and, with the drive's
        own EDS/DCF given, that file's objects (every one the master uses, with its type)."""
        setup = self.setup
        if setup is None:
            return
        step = 'check against the machine file'
        mismatch = identity_mismatch(setup, self.read_identity())
        if not mismatch:
            modes = self._read(step, od.SUPPORTED_MODES, optional=True)
            missing = missing_modes(modes, setup)
            if missing:
                shown = 'nothing' if modes is None else f'0x{modes:08X}'
                mismatch = (f'0x6502 supported drive modes: expected {", ".join(missing)}, '
                            f'found {shown}')
        if not mismatch and setup.eds:
            mismatch = eds_mismatch(setup.eds, setup)
        if mismatch:
            raise self._fail(step, mismatch, DriveRefusedError)

    def _verify_pdos(self) -> None:
        """Read the PDO mapping back (SDO): a drive that took the writes but maps otherwise
        (a read-only or fixed mapping) is refused, naming the entry."""
        step = 'PDO mapping read back (0x1400/0x1600, 0x1800/0x1A00)'
        for layout in (self._layout, *od.TPDOS):
            mismatch = pdo_mismatch(layout, self.config.drive_node_id,
                                    lambda index, sub: self._sdo_read(step, index, sub))
            if mismatch:
                raise self._fail(step, mismatch, DriveRefusedError)

    def _apply_polarity(self) -> None:
        """0x607E as the machine file's polarity (written at every start: a drive reset or
        replaced drive forgets it)."""
        if self.setup is not None:
            self.set_polarity(self.setup.polarity == 'reversed')

    def _home_at_start(self) -> None:
        """Home with the machine file's method (mode 6, the commissioning's speeds), so the
        phase offset found at commissioning means the same angle after a drive reset."""
        if self.setup is not None and self.setup.homing_method:
            self.home(self.setup.homing_method, HOMING_SEARCH_SPEED, HOMING_ZERO_SPEED,
                      timeout=homing_timeout())

    def _configure_watchdogs(self) -> None:
        """Heartbeat both ways, quick stop when our frames stop, and a zero target."""
        cfg = self.config
        step = 'heartbeat (0x1017 producer, 0x1016 consumer)'
        self._write(step, od.HEARTBEAT_PRODUCER, round(cfg.drive_heartbeat_period * 1000))
        self._write(step, od.HEARTBEAT_CONSUMER, (cfg.master_node_id << 16)
                        | round(cfg.master_heartbeat_timeout * 1000))
        step = 'watchdog (0x6007 abort connection option = quick stop)'
        self._write(step, od.ABORT_CONNECTION, ABORT_OPTION_QUICK_STOP)
        step = 'target velocity 0 (0x60FF)'
        self._write(step, od.TARGET_VELOCITY, 0)

    def _configure_csp(self) -> None:
        """CSP: SYNC consumer and its period, the interpolation period, the following-error
        window, and the target position = where the drive is (no jump when enabled)."""
        cfg = self.config
        step = 'SYNC (0x1005 consumer, 0x1006 period, 0x60C2 interpolation period)'
        self._write(step, od.SYNC_COB_ID, od.SYNC_COB)
        self._write(step, od.COMM_CYCLE_PERIOD, round(cfg.sync_period * 1e6))
        self._write(step, od.INTERPOLATION_PERIOD_VALUE, round(cfg.sync_period * 1e3))
        self._write(step, od.INTERPOLATION_PERIOD_INDEX, -3)
        step = 'following error (0x6065 window, 0x6066 time out)'
        self._write(step, od.FOLLOWING_ERROR_WINDOW,
                    max(1, round(cfg.following_error_window / self._rad_per_count)))
        self._write(step, od.FOLLOWING_ERROR_TIMEOUT, round(cfg.following_error_timeout * 1e3))
        self._hold_here('target position = actual position (0x607A from 0x6064)')

    def _hold_here(self, step: str) -> None:
        """CSP: the position target (0x607A and our frames') = the actual position."""
        actual = self._read(step, od.POSITION_ACTUAL)
        self._write(step, od.TARGET_POSITION, actual)
        with self._lock:
            self._target_counts = actual

    def _select_mode(self) -> None:
        """0x6060 = the chosen mode, confirmed by reading 0x6061 back (drives switch modes with
        a delay)."""
        cfg = self.config
        mode, name = self.mode, _MODE_NAMES[self.mode]
        step = f'mode of operation (0x6060 = {mode}, confirmed by 0x6061)'
        self._write(step, od.MODES_OF_OPERATION, mode)
        deadline = time.monotonic() + cfg.step_timeout
        while (shown := self._read(step, od.MODES_DISPLAY)) != mode:
            if time.monotonic() > deadline:
                raise self._fail(step, f'0x6061 reads {shown} after writing {mode} ({name}) '
                                       f'for {cfg.step_timeout:.2f} s', DriveTimeoutError)
            time.sleep(0.005)

    def _wait_drive_heartbeat(self, since: float) -> None:
        """The drive's first heartbeat after 0x1017 was written (wall-clock `since`)."""
        cfg = self.config
        wait = max(cfg.step_timeout, 2.5 * cfg.drive_heartbeat_period)
        deadline = time.monotonic() + wait
        while (self._node.nmt.timestamp or 0.0) < since:
            if time.monotonic() > deadline:
                period_ms = round(cfg.drive_heartbeat_period * 1000)
                raise self._fail('drive heartbeat', f'no heartbeat within {wait:.2f} s after '
                                 f'setting 0x1017 = {period_ms} ms', DriveTimeoutError)
            time.sleep(0.002)

    def _go_operational(self) -> None:
        """NMT operational: PDOs flow; wait for the first statusword TPDO. The NMT command is
        unconfirmed (a lost frame is never re-sent by the bus): repeated every
        NMT_REPEAT s until the drive answers (a drive already operational ignores it)."""
        with self._lock:
            self._sw_received = False
        self._connected = True
        self._wait_state('NMT operational (first statusword TPDO)',
                         lambda state: self._sw_received, 'no statusword TPDO',
                         resend=lambda: self._send(
                             'NMT operational',
                             lambda: setattr(self._node.nmt, 'state', 'OPERATIONAL')),
                         resend_period=NMT_REPEAT)

    def _enable_state_machine(self) -> None:
        """From whatever state the drive is in to OPERATION ENABLED, one step at a time."""
        state = self.status().state
        if state in (FAULT, FAULT_REACTION_ACTIVE):
            if not self._reset_requested:
                raise self._fail('enable', f'drive is in FAULT (error code '
                                           f'0x{self._error_code:04X}); call '
                                           'request_fault_reset() and connect again',
                                 DriveRefusedError)
            self._transmit(CW_DISABLE_VOLTAGE, None)
            self._wait_step('fault reset (0x80)', CW_FAULT_RESET, SWITCH_ON_DISABLED)
        elif state not in (SWITCH_ON_DISABLED, READY_TO_SWITCH_ON):
            # left enabled (or quick-stopped) by an earlier session: start from the bottom
            self._wait_step('disable voltage (0x00)', CW_DISABLE_VOLTAGE, SWITCH_ON_DISABLED)
        self._wait_step('shutdown (0x06)', CW_SHUTDOWN, READY_TO_SWITCH_ON)
        self._wait_step('switch on (0x07)', CW_SWITCH_ON, SWITCHED_ON)
        self._wait_step('enable operation (0x0F)', CW_ENABLE_OPERATION, OPERATION_ENABLED)
        with self._lock:
            self._reset_requested = False
            self._latched_reason = ''
            self._emcy_code = 0
            self._enabled = True

    def open(self) -> None:
        """Open (or join) the bus and add this drive's node to it (no frame sent). Drives
        sharing a CanopenBus are opened one after the other, then enabled at once."""
        if self._network is not None:
            return
        cfg = self.config
        eds = cfg.eds_path or str(default_eds_path())
        if not Path(eds).is_file():
            raise self._fail('load EDS', f'{eds} is not a file', DriveConfigError)
        try:
            network = self.canbus.open()
        except BusError as exc:
            raise BusError(f'drive node {cfg.drive_node_id}: {exc}') from None
        node = BaseNode402(cfg.drive_node_id, eds)
        node.sdo.RESPONSE_TIMEOUT = cfg.sdo_timeout
        node.sdo.MAX_RETRIES = SDO_ATTEMPTS             # a request or answer lost: asked again
        network.add_node(node)
        node.emcy.add_callback(self._on_emcy)
        node.nmt.add_heartbeat_callback(self._on_nmt_state)
        node.emcy.add_callback(self._count_emcy)
        self._network, self._node = network, node

    _open = open

    def _configure_pdos(self) -> None:
        """RPDO1 = controlword + target velocity (profile velocity, asynchronous) or target
        position (CSP, synchronous: applied at the next SYNC); TPDO1 = statusword + error code,
        TPDO2 = position + velocity actual (every feedback period, or every SYNC in CSP);
        every other PDO disabled (drive.objects declares the layouts)."""
        cfg, node = self.config, self._node
        step = 'configure PDOs (0x1400/0x1600, 0x1800/0x1A00)'
        feedback_ms = max(1, round(cfg.feedback_period * 1000))
        try:
            csp = self.mode == CYCLIC_SYNC_POSITION
            layout = self._layout
            rpdo = node.rpdo[1]
            rpdo.clear()
            for obj in layout.entries:
                rpdo.add_variable(obj.index, obj.subindex)
            rpdo.cob_id = layout.cob_id(cfg.drive_node_id)
            rpdo.trans_type = 1 if csp else 255
            rpdo.event_timer = round(cfg.command_timeout * 1000)    # deadline monitoring
            rpdo.enabled = True
            rpdo.save()
            for layout in od.TPDOS:
                tpdo = node.tpdo[layout.number]
                tpdo.clear()
                for obj in layout.entries:
                    tpdo.add_variable(obj.index, obj.subindex)
                tpdo.cob_id = layout.cob_id(cfg.drive_node_id)
                tpdo.trans_type = 1 if csp else 255
                tpdo.inhibit_time = 0
                tpdo.event_timer = 0 if csp else feedback_ms
                tpdo.enabled = True
                tpdo.save()
            for maps, first_free, base in ((node.rpdo.map, 2, 0x200),
                                           (node.tpdo.map, len(od.TPDOS) + 1, 0x180)):
                for number in range(first_free, len(maps) + 1):
                    cob_id = base + 0x100 * (number - 1) + cfg.drive_node_id if number <= 4 else 0
                    maps[number].com_record[1].raw = PDO_NOT_VALID | cob_id
                    maps[number].enabled = False
        except SdoCommunicationError as exc:
            raise self._fail(step, f'no SDO answer{self._sdo_wait_text()} ({exc})',
                             DriveTimeoutError) from None
        except SdoAbortedError as exc:
            raise self._fail(step, f'drive refused the mapping ({exc})',
                             DriveRefusedError) from None
        except Exception as exc:             # python-can: CanError, OSError, ValueError...
            raise self._fail(step, f'CAN send failed: {type(exc).__name__}: {exc}',
                             BusError) from None
        # our callback after BaseNode402's (which keeps node.tpdo_values); once per node,
        # a second enable attempt in the same session must not add them again
        if self._on_status_tpdo not in node.tpdo[1].callbacks:
            node.setup_pdos(upload=False)
            for layout in od.TPDOS:
                node.tpdo[layout.number].add_callback(self._on_status_tpdo)
        self._rpdo = rpdo
        mapped = tuple((var.index, var.offset, var.length) for var in rpdo)
        # (the RPDO's layout: `layout` is the last TPDO's after the loop above, which left the
        # packed hot path off on every drive)
        self._rpdo_packed = (mapped == self._layout.bit_layout
                             and rpdo.cob_id == self._layout.cob_id(cfg.drive_node_id))

    def _hold_counts(self) -> int:
        """The target that holds the drive: velocity 0, or in CSP the last target sent (the
        position where it was told to be; the actual one at enable)."""
        if self.mode != CYCLIC_SYNC_POSITION:
            return 0
        with self._lock:
            if (not self._enabled and self._raw_position is not None
                    and time.monotonic() - self._motion_stamp < 3 * self.config.sync_period):
                # enabling, with fresh feedback: where the shaft is now (after a restart it
                # may still coast; the target written when configuring is behind it)
                return _wrap_i32(self._position_counts)
            if self._target_counts is not None:
                return self._target_counts
            return _wrap_i32(self._position_counts)

    def _transmit(self, controlword: int, counts: int | None) -> None:
        """One RPDO frame: controlword + target velocity (counts/s) or target position
        (counts, CSP); None = the holding target (`_hold_counts`)."""
        if counts is None:
            counts = self._hold_counts()
        target = self._layout.entries[1]

        def send():
            with self._tx_lock:
                if self._rpdo_packed:
                    self._network.send_message(self._rpdo.cob_id,
                                               self._layout.frame.pack(controlword, counts))
                else:
                    self._rpdo[od.CONTROLWORD.index].raw = controlword
                    self._rpdo[target.index].raw = counts
                    self._rpdo.transmit()
                self._last_controlword = controlword
        self._send(f'RPDO (controlword 0x{controlword:04X}, {target.address} {counts})', send)

    def _wait_state(self, step: str, done: Callable[[str], bool], what: str,
                    resend: Callable[[], object] | None = None,
                    resend_period: float = 0.02) -> None:
        deadline = time.monotonic() + self.config.step_timeout
        next_send = 0.0
        while True:
            with self._feedback:
                state = state_of(self._statusword)
                if done(state):
                    return
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    sw = self._statusword
                    break
                if resend is None:
                    self._feedback.wait(min(remaining, 0.02))
            if resend is not None:
                now = time.monotonic()
                if now >= next_send:            # repeat the command: keeps the RPDO deadline fed
                    resend()
                    next_send = now + resend_period
                with self._feedback:
                    self._feedback.wait(min(max(deadline - time.monotonic(), 0.0), 0.005))
        seen = f'state stays {state} (statusword 0x{sw:04X})' if self._sw_received else what
        raise self._fail(f'enable step {step!r}',
                         f'timed out after {self.config.step_timeout:.2f} s: {seen}',
                         DriveTimeoutError)

    def _wait_step(self, step: str, controlword: int, target_state: str) -> None:
        self._wait_state(step, lambda state: state == target_state, 'no statusword',
                         resend=lambda: self._transmit(controlword, None))

    # ------------------------------------------------------------------ non-blocking
    def send_velocity(self, speed: float) -> None:
        """Send one RPDO: controlword + 0x60FF for `speed` (mechanism rad/s). NON-BLOCKING.

        While the drive is faulted (statusword bit 3, EMCY, lost heartbeat, unexpected state)
        the frame carries 0 and no state change; after request_fault_reset() the frames carry
        the reset edge and the re-enable steps, one per call, then speeds again.
        Raises DriveError for a non-finite speed, before connect, or on a CAN send error.
        """
        self._check_connected()
        if self.mode == CYCLIC_SYNC_POSITION:
            raise DriveError(f'drive node {self.config.drive_node_id}: runs cyclic synchronous '
                             'position: send_position(), not send_velocity()')
        if not math.isfinite(speed):
            raise DriveError(f'speed {speed!r} rad/s is not finite (allowed: a finite number)')
        counts = self._counts_per_s(speed)
        with self._lock:
            controlword, commanding = self._controlword_locked(time.monotonic())
            counts = counts if commanding else 0
            self._commanded = counts * self._rad_per_count
        self._transmit(controlword, counts)

    def send_position(self, angle: float) -> None:
        """CSP: send one RPDO: controlword + 0x607A for mechanism angle `angle` (rad, on the
        unwrapped scale of `status().position`), applied by the drive at the next SYNC.
        NON-BLOCKING. While faulted (as send_velocity) the frame holds where the drive is;
        after request_fault_reset() it carries the reset steps. Raises DriveError for a
        non-finite angle, before connect, in profile velocity mode, or on a CAN send error."""
        self._check_connected()
        if self.mode != CYCLIC_SYNC_POSITION:
            raise DriveError(f'drive node {self.config.drive_node_id}: runs profile velocity: '
                             'send_velocity(), not send_position()')
        if not math.isfinite(angle):
            raise DriveError(f'angle {angle!r} rad is not finite (allowed: a finite number)')
        with self._lock:
            controlword, commanding = self._controlword_locked(time.monotonic())
            if commanding:
                counts = _wrap_i32(round(angle / self._rad_per_count))
                self._commanded_position = angle
            else:                                  # hold where the drive is
                counts = _wrap_i32(self._position_counts)
                self._commanded_position = self._position_counts * self._rad_per_count
            self._commanded = 0.0
            self._target_counts = counts
        self._transmit(controlword, counts)

    def send_hold(self) -> None:
        """Keep the drive fed without moving it: velocity 0, or in CSP the last target
        (NON-BLOCKING)."""
        if self.mode == CYCLIC_SYNC_POSITION:
            self._check_connected()
            with self._lock:
                controlword, _ = self._controlword_locked(time.monotonic())
            self._transmit(controlword, None)
        else:
            self.send_velocity(0.0)

    def send_sync(self) -> None:
        """The SYNC frame (once per bus: `canbus.send_sync()` on a shared CanopenBus)."""
        self._check_connected()
        self.canbus.send_sync()

    def _check_connected(self) -> None:
        if not self._connected or self._rpdo is None:
            raise NotConnectedError(f'drive node {self.config.drive_node_id}: not connected '
                                    '(call connect_and_enable first)')

    def _controlword_locked(self, now: float) -> tuple[int, bool]:
        """(controlword of the next frame, whether it may carry a command); lock held."""
        self._latch_heartbeat_loss()
        state = state_of(self._statusword)
        if self._reset_requested:
            return self._reset_step(state, now), False
        if self._latched_reason or state != OPERATION_ENABLED:
            # refuse: hold, and a controlword that causes no transition towards enabled (0x0F
            # holds an enabled drive; quick stop elsewhere)
            return (CW_ENABLE_OPERATION if state == OPERATION_ENABLED else CW_QUICK_STOP), False
        return CW_ENABLE_OPERATION, True

    def _reset_step(self, state: str, now: float) -> int:
        """Controlword for the next frame of an explicit fault reset (lock held)."""
        if now > self._reset_deadline:
            self._reset_requested = False
            self._latched_reason = self._latched_reason or f'fault reset failed (state {state})'
            log.warning('drive node %d: fault reset abandoned in state %s',
                        self.config.drive_node_id, state)
            return CW_ENABLE_OPERATION if state == OPERATION_ENABLED else CW_QUICK_STOP
        if state == FAULT:
            if self._reset_edge_sent:
                return CW_FAULT_RESET                   # hold: one edge per request, no loop
            if self._last_controlword & CW_FAULT_RESET:
                return CW_DISABLE_VOLTAGE               # need a 0 first for the rising edge
            self._reset_edge_sent = True
            return CW_FAULT_RESET
        if state == OPERATION_ENABLED:
            self._reset_requested = False
            return CW_ENABLE_OPERATION
        return _REENABLE_STEP.get(state, CW_DISABLE_VOLTAGE)

    def _latch_heartbeat_loss(self) -> None:
        if self._enabled and not self._latched_reason and not self._reset_requested:
            if self._heartbeat_age() > self.config.drive_heartbeat_timeout:
                self._latched_reason = 'drive heartbeat lost'
                self._emcy_code = self._emcy_code or EMCY_HEARTBEAT

    def send_heartbeat(self) -> None:
        """Our heartbeat frame (NMT state operational), for the drive's consumer. NON-BLOCKING.
        On a shared CanopenBus send it once per bus instead (`canbus.send_heartbeat()`)."""
        if self._network is None:
            raise NotConnectedError(f'drive node {self.config.drive_node_id}: not connected '
                             '(call connect_and_enable first)')
        try:
            self.canbus.send_heartbeat()
        except DriveError as exc:
            raise BusError(f'drive node {self.config.drive_node_id}: {exc}') from None

    def status(self) -> DriveStatus:
        """Snapshot of the drive as the bus callbacks last saw it. NON-BLOCKING."""
        age = self._heartbeat_age()
        with self._lock:
            self._latch_heartbeat_loss()
            sw = self._statusword
            state = state_of(sw) if self._sw_received else 'UNKNOWN'
            fault_bit = bool(sw & 0x08) and self._sw_received
            reason = self._latched_reason or ('statusword fault bit' if fault_bit else '')
            error_code = self._error_code or self._emcy_code
            return DriveStatus(
                state=state, statusword=sw, fault=bool(reason), error_code=error_code,
                position=self._position_counts * self._rad_per_count,
                velocity=self._velocity_counts * self._rad_per_count,
                heartbeat_age=age, stamp=self._motion_stamp,
                fault_reason=reason,
                heartbeat_lost=age > self.config.drive_heartbeat_timeout,
                resetting=self._reset_requested,
                enabled=(self._enabled and self._connected and not reason
                         and not self._reset_requested and state == OPERATION_ENABLED),
                commanded_velocity=self._commanded, mode=self.mode,
                commanded_position=self._commanded_position, restarted=self._restarted)

    def request_fault_reset(self) -> None:
        """Ask for one fault reset: the next send_velocity frames carry the reset edge (0x80)
        and the steps back to OPERATION ENABLED. NON-BLOCKING; never done automatically."""
        with self._lock:
            self._reset_requested = True
            self._reset_edge_sent = False
            self._reset_deadline = time.monotonic() + self.config.reset_timeout
            self._latched_reason = ''
            self._emcy_code = 0

    # ------------------------------------------------------------------ blocking: shutdown
    def shutdown(self) -> None:
        """0x60FF = 0 (wait for standstill), disable (0x06), NMT pre-operational, close.

        BLOCKING (at most about 2 x step_timeout), idempotent, never raises: a failing step is
        logged and the next one still runs."""
        if self._network is None:
            return
        cfg = self.config
        if self._connected and self._rpdo is not None:
            try:
                state = self.status().state
                with self._lock:
                    self._enabled = False
                    self._commanded = 0.0
                hold = CW_ENABLE_OPERATION if state == OPERATION_ENABLED else CW_QUICK_STOP
                # 0x60FF = 0 and wait for standstill (frames and our heartbeat keep the
                # drive's watchdog fed meanwhile), then disable and wait for the state
                self._shutdown_wait(hold, lambda st: st.state != OPERATION_ENABLED
                                    or abs(st.velocity) < 0.01, 'still turning')
                self._shutdown_wait(CW_SHUTDOWN, lambda st: st.state in (
                    READY_TO_SWITCH_ON, SWITCH_ON_DISABLED, FAULT), 'not disabled')
            except DriveError as exc:
                log.warning('%s', exc)
        try:
            self._node.nmt.state = 'PRE-OPERATIONAL'
            if self._heartbeat_age() < cfg.drive_heartbeat_timeout:
                self._node.sdo[od.HEARTBEAT_CONSUMER.index][od.HEARTBEAT_CONSUMER.subindex].raw = 0
        except Exception as exc:                    # best effort: the bus may be gone
            log.warning('drive node %d: shutdown: %s: %s', cfg.drive_node_id,
                        type(exc).__name__, exc)
        self._connected = False
        self._enabled = False
        self._close()

    def _shutdown_wait(self, controlword: int, done: Callable[[DriveStatus], bool],
                       complaint: str) -> None:
        deadline = time.monotonic() + self.config.step_timeout
        next_heartbeat = 0.0
        failed = None
        while True:
            now = time.monotonic()
            try:
                self._transmit(controlword, None)
                if self.mode == CYCLIC_SYNC_POSITION:
                    self.canbus.send_sync()      # CSP feedback comes with the SYNC
                if now >= next_heartbeat:
                    self.send_heartbeat()
                    next_heartbeat = now + self.config.heartbeat_period
            except DriveError as exc:
                # a send that failed (a full transmit queue) is sent again until the deadline:
                # one lost frame must not leave the drive enabled
                failed = exc
            status = self.status()
            if done(status):
                return
            if status.heartbeat_lost:
                log.warning('drive node %d: shutdown: drive heartbeat lost, not waiting for it',
                            self.config.drive_node_id)
                return
            if now > deadline:
                log.warning('drive node %d: shutdown: %s (%s, %.3f rad/s)%s',
                            self.config.drive_node_id, complaint, status.state, status.velocity,
                            f'; last send error: {failed}' if failed is not None else '')
                return
            with self._feedback:
                self._feedback.wait(0.01)

    def _close(self) -> None:
        network, self._network = self._network, None
        if network is not None and self._node is not None and self._node.id in network:
            del network[self._node.id]
        if self._owns_canbus:
            self.canbus.close()
        self._rpdo = None

    # ------------------------------------------------------------------ blocking: commissioning
    def read_identity(self) -> dict[str, int | None]:
        """The drive's identity (0x1000, 0x1018:1..4) and supported modes (0x6502) by SDO
        (BLOCKING; after open(), before or after enabling). A missing entry reads None."""
        self._check_open()
        step = 'identify (0x1000, 0x1018, 0x6502)'
        return {name: self._read(step, obj, optional=True) for name, obj in (
            ('device_type', od.DEVICE_TYPE), ('vendor_id', od.VENDOR_ID),
            ('product_code', od.PRODUCT_CODE), ('revision', od.REVISION_NUMBER),
            ('serial', od.SERIAL_NUMBER), ('supported_modes', od.SUPPORTED_MODES))}

    def set_polarity(self, reversed_: bool) -> None:
        """0x607E: bits 7 and 6 (position and velocity inverted) or none (BLOCKING)."""
        self._check_open()
        self._write('polarity (0x607E)', od.POLARITY, od.POLARITY_REVERSED if reversed_ else 0)

    def read_inputs(self) -> int:
        """The drive's digital inputs 0x60FD (bit 2 home switch) by SDO (BLOCKING)."""
        self._check_open()
        return self._read('digital inputs (0x60FD)', od.DIGITAL_INPUTS)

    def home(self, method: int, switch_speed: float, zero_speed: float,
             timeout: float = 60.0) -> None:
        """Home the enabled drive (BLOCKING): homing mode 6 with `method` (0x6098), speeds in
        mechanism rad/s (0x6099:1 search for the switch, :2 for zero), home offset 0; started
        with controlword bit 4, finished by statusword bits 12 (attained) and 10 (target
        reached), refused on bit 13 (homing error) or after `timeout` s. Our frames (RPDO and
        heartbeat) keep flowing meanwhile; then back to the mode chosen at enable."""
        self._check_connected()
        step = f'homing method {method} (0x6098, 0x6099, 0x607C, 0x6060 = 6)'
        self._write(step, od.HOMING_METHOD, method)
        self._write(step, od.HOMING_SPEED_SWITCH, abs(self._counts_per_s(switch_speed)))
        self._write(step, od.HOMING_SPEED_ZERO, abs(self._counts_per_s(zero_speed)))
        self._write(step, od.HOME_OFFSET, 0)
        self._transmit(CW_ENABLE_OPERATION, None)
        self._change_mode(step, od.HOMING)
        deadline = time.monotonic() + timeout
        try:
            while True:
                self._transmit(CW_ENABLE_OPERATION | 0x10, None)
                self.send_heartbeat()
                sw = self._read(step, od.STATUSWORD)
                if sw & 0x2000:
                    raise self._fail(step, f'the drive reports a homing error (statusword '
                                           f'0x{sw:04X})', DriveRefusedError)
                if sw & 0x1400 == 0x1400:
                    break
                if state_of(sw) != OPERATION_ENABLED:
                    raise self._fail(step, f'the drive left operation enabled (statusword '
                                           f'0x{sw:04X})', DriveRefusedError)
                if time.monotonic() > deadline:
                    raise self._fail(step, f'not homed within {timeout:g} s (statusword '
                                           f'0x{sw:04X})', DriveTimeoutError)
                time.sleep(0.01)
        finally:
            if self.mode == CYCLIC_SYNC_POSITION:
                # the position target = where homing left it, before CSP takes it again
                self._hold_here('back to CSP after homing (0x607A from 0x6064)')
            self._transmit(CW_ENABLE_OPERATION, None)
            self._change_mode('back to the running mode after homing', self.mode)
        time.sleep(2.5 * self.config.feedback_period)     # the homed position in the TPDO

    def jog(self, speed: float, until: Callable[[], bool] | None = None,
            timeout: float = 60.0) -> bool:
        """Turn at `speed` (mechanism rad/s, slow) in profile velocity mode until `until()`
        returns true (called between frames; None: for `timeout` s), then stop (BLOCKING).
        Returns whether `until` was met. Our frames keep the drive's watchdogs fed."""
        self._check_connected()
        if self.mode != PROFILE_VELOCITY:
            raise self._fail('jog', 'needs profile velocity mode (operation_mode velocity)',
                             DriveConfigError)
        deadline = time.monotonic() + timeout
        met = False
        try:
            while time.monotonic() < deadline:
                self.send_velocity(speed)
                self.send_heartbeat()
                if until is not None and until():
                    met = True
                    break
                time.sleep(0.005)
        finally:
            self.stop_and_wait()
        return met

    def stop_and_wait(self, timeout: float = 5.0) -> None:
        """Velocity 0 and wait until the drive reports (almost) no speed (BLOCKING)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.send_velocity(0.0)
            self.send_heartbeat()
            with self._lock:
                moving = abs(self._velocity_counts * self._rad_per_count) > 1e-3
            if not moving:
                break
            time.sleep(0.01)
        for _ in range(3):                       # one more feedback period at rest
            self.send_velocity(0.0)
            self.send_heartbeat()
            time.sleep(self.config.feedback_period)

    def _change_mode(self, step: str, mode: int) -> None:
        """0x6060 = `mode`, confirmed by 0x6061."""
        self._write(step, od.MODES_OF_OPERATION, mode)
        deadline = time.monotonic() + self.config.step_timeout
        while (shown := self._read(step, od.MODES_DISPLAY)) != mode:
            if time.monotonic() > deadline:
                raise self._fail(step, f'0x6061 reads {shown} after writing {mode}',
                                 DriveTimeoutError)
            time.sleep(0.005)

    def _check_open(self) -> None:
        if self._node is None:
            raise NotConnectedError(f'drive node {self.config.drive_node_id}: not open '
                                    '(call open or connect_and_enable first)')

    def __enter__(self) -> 'Cia402Drive':
        return self

    def __exit__(self, *exc: object) -> None:

        self.shutdown()
