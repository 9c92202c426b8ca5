"""CiA 402 servo drive master over CANopen, on a python-can bus: the one CAN protocol class of
planter_ros, made of parts that each own their state:

* `bus.CanopenBus`: the python-can bus, its canopen Network, the master heartbeat and SYNC
  (the loop's, and the start-up producer's while a drive starts);
* `feedback.Feedback`: what the drive reports (TPDOs, EMCYs), written by bus callbacks;
* `supervision.Supervisor`: faults latched, one fault reset per request, restarts noticed;
  it decides each frame's controlword;
* `rpdo.Commander`: the command frames (RPDOs as the plan mapped them);
* `startup.StartUp`: the start-up plan (drive.plan, from the drive's EDS) carried out, the
  enable steps, homing;
* `sdo.Sdo`: SDO access, every failure one line in the right family.

`Cia402Drive` joins them. ``connect_and_enable()``, ``shutdown()`` and the commissioning calls
block (SDO, waits with timeouts): call them at start-up / shutdown or from a worker thread,
never from a ROS or CAN callback. ``send_velocity()``, ``send_position()``, ``send_hold()``,
``send_heartbeat()``, ``status()`` and ``request_fault_reset()`` never block: one frame per RPDO
at most, or a snapshot of what the bus callbacks collected. canopen's BaseNode402 blocking
helpers are not used (its ``state`` setter busy-waits, ``reset_from_fault()`` always waits its
full timeout, the ``op_mode`` setter logs instead of raising).

Drive-side watchdog (the motor stops if this process dies or hangs), where the drive's EDS has
them: RPDO deadline monitoring (1400h:5 = ``command_timeout``, EMCY 8250h) and the heartbeat
consumer (1016h, ``master_heartbeat_timeout``, EMCY 8130h), both reacting with 6007h = 3 (quick
stop). Both arm on the first frame they see: a control loop must start sending within
``command_timeout`` after ``connect_and_enable()`` returns. No ``send_periodic`` anywhere.

Units: mechanism rad and rad/s at the API; on the bus 60FFh / 606Ch are encoder increments per
second and 6064h increments (``counts_per_motor_rev`` per motor revolution, ``motor_gear_ratio``
motor revolutions per mechanism revolution).
"""
from __future__ import annotations

from collections.abc import Callable
import logging
import math
import time

import can
from canopen import ObjectDictionary
from canopen.profiles.p402 import BaseNode402

from planter_ros.drive import objects as od
from planter_ros.drive.bus import CanopenBus
from planter_ros.drive.config import BusConfig, DeviceConfig, DriveConfig
from planter_ros.drive.dictionary import read_dictionary
from planter_ros.drive.eds import default_eds_path
from planter_ros.drive.errors import DriveError, NotConnectedError
from planter_ros.drive.feedback import EMCY_KEPT, DriveStatus, Feedback
from planter_ros.drive.plan import DrivePlan
from planter_ros.drive.rpdo import Commander
from planter_ros.drive.sdo import Sdo
from planter_ros.drive.setup import DriveSetup
from planter_ros.drive.startup import DriveLink, StartUp
from planter_ros.drive.supervision import Supervisor
from planter_ros.drive.states import (CYCLIC_SYNC_POSITION, FAULT, OPERATION_ENABLED,
                                      PROFILE_VELOCITY, READY_TO_SWITCH_ON, SWITCH_ON_DISABLED,
                                      state_of)
from planter_ros.drive.words import CW_ENABLE_OPERATION, CW_QUICK_STOP, CW_SHUTDOWN

__all__ = ['BusConfig', 'CanopenBus', 'Cia402Drive', 'DeviceConfig', 'DriveConfig', 'DriveError',
           'DriveStatus']

log = logging.getLogger(__name__)


class Cia402Drive:
    """Master of one CiA 402 drive (module doc). `bus`: an open python-can bus to use;
    `canbus`: a `CanopenBus` shared with other drives (then this drive neither opens nor closes
    the bus, and the heartbeat and SYNC are the CanopenBus's); `setup`: what the machine file
    says of it (checked and applied at every start)."""

    EMCY_KEPT = EMCY_KEPT

    def __init__(self, config: DriveConfig, bus: can.BusABC | None = None,
                 canbus: CanopenBus | None = None, setup: DriveSetup | None = None) -> None:
        self.config = config
        self.setup = setup
        self._owns_canbus = canbus is None
        self.canbus = canbus if canbus is not None else CanopenBus(config, bus)
        self._link: DriveLink | None = None          # while open
        self.feedback = Feedback(2.0 * math.pi / (config.counts_per_motor_rev
                                                  * config.motor_gear_ratio))
        self.supervisor = Supervisor(config, self.feedback, self._heartbeat_age)
        self.commander = Commander(config, self.feedback, self.supervisor)
        self.startup: StartUp | None = None          # made by open(), kept after shutdown

    # ---------------------------------------------------------------- what it is
    @property
    def node(self) -> BaseNode402 | None:
        """The canopen node while open (diagnostics and benchmarks; its SDO calls block)."""
        return self._link.node if self._link is not None else None

    @property
    def dictionary(self) -> ObjectDictionary:
        """The object dictionary read from the drive's EDS (after open(); NotConnectedError
        before)."""
        return self._opened().dictionary

    @property
    def mode(self) -> int:
        """3 profile velocity, 8 CSP (0 before the first enable)."""
        return self.commander.mode

    @property
    def plan(self) -> DrivePlan | None:
        """The start-up plan of the last start (None before it was made)."""
        return self.startup.plan if self.startup is not None else None

    @property
    def enable_duration(self) -> float:
        return self.startup.enable_duration if self.startup is not None else math.nan

    @property
    def emcy_count(self) -> int:
        return self.feedback.emcy_count

    @property
    def last_emcy_code(self) -> int:
        return self.feedback.last_emcy_code

    @property
    def _connected(self) -> bool:
        return self.startup is not None and self.startup.connected and self.commander.ready

    def _heartbeat_age(self) -> float:
        stamp = self._link.node.nmt.timestamp if self._link is not None else None
        if stamp is None:
            return math.inf
        return max(0.0, time.time() - stamp)   # frame timestamps are wall-clock (python-can)

    # ---------------------------------------------------------------- the bus
    def open(self) -> None:
        """Open (or join) the bus and add this drive's node, its dictionary read from its EDS
        (no frame sent). Drives sharing a CanopenBus are opened one after the other, then
        enabled at once. DictionaryError for an EDS that cannot be read."""
        self._open()

    def _open(self) -> StartUp:
        """open(); the start-up of the drive, made with its node."""
        if self._link is not None and self.startup is not None:
            return self.startup
        cfg = self.config
        eds = (self.setup.eds if self.setup is not None and self.setup.eds else cfg.eds_path)
        dictionary = read_dictionary(eds or default_eds_path(), cfg.drive_node_id)
        try:
            network = self.canbus.open()
        except DriveError as exc:
            raise type(exc)(f'drive node {cfg.drive_node_id}: {exc}') from None
        node = BaseNode402(cfg.drive_node_id, dictionary)
        network.add_node(node)
        node.emcy.add_callback(self.supervisor.on_emcy)
        node.nmt.add_heartbeat_callback(self.supervisor.on_nmt_state)
        node.emcy.add_callback(lambda entry: self.feedback.count_emcy(entry, node.emcy))
        self._link = link = DriveLink(self.canbus, node, dictionary, Sdo(node, cfg))
        self.startup = startup = StartUp(cfg, self.setup, link, self.feedback, self.supervisor,
                                         self.commander)
        return startup

    def _opened(self) -> DriveLink:
        """The drive's node on the bus; NotConnectedError before open() or after shutdown()."""
        if self._link is None:
            raise NotConnectedError(f'drive node {self.config.drive_node_id}: not open '
                                    '(call open or connect_and_enable first)')
        return self._link

    def _check_connected(self) -> StartUp:
        """The start-up of the connected drive; NotConnectedError when it is not."""
        startup = self.startup
        if startup is None or not self._connected:
            raise NotConnectedError(f'drive node {self.config.drive_node_id}: not connected '
                                    '(call connect_and_enable first)')
        return startup

    # ---------------------------------------------------------------- blocking: start
    def connect_and_enable(self) -> None:
        """Open the bus, bring the drive up by its plan and enable it (BLOCKING; DriveError):
        see drive.startup. A drive found in FAULT is only reset if request_fault_reset() was
        called first. After this returns the control loop must send a command at least every
        command_timeout and the heartbeat every heartbeat_period."""
        if self.supervisor.enabled:
            return
        self._open().run()

    def reconfigure(self) -> None:
        """BLOCKING: configure and enable again a drive that restarted (`status().restarted`)
        through the one start-up path. Until it returns the drive is not enabled: send it
        nothing meanwhile. Raises DriveError (then call again)."""
        self.supervisor.configuring()
        if self.startup is not None:
            self.startup.connected = False
        self.connect_and_enable()
        with self.feedback.lock:
            self.supervisor.restarted = ''

    def probe_restart(self, timeout: float = 0.2) -> bool:
        """BLOCKING (one SDO read, at most `timeout` s): whether a drive whose heartbeat is
        lost restarted with its boot-up message lost on the bus: its heartbeat producer 0x1017
        no longer reads what we wrote. Raises DriveError when it does not answer."""
        link = self._opened()
        sdo = link.node.sdo
        kept = sdo.RESPONSE_TIMEOUT, sdo.MAX_RETRIES
        sdo.RESPONSE_TIMEOUT, sdo.MAX_RETRIES = timeout, 1
        try:
            period = link.sdo.read('is the drive restarted? (0x1017 heartbeat producer)',
                                   od.HEARTBEAT_PRODUCER)
        finally:
            sdo.RESPONSE_TIMEOUT, sdo.MAX_RETRIES = kept
        if period == round(self.config.drive_heartbeat_period * 1000):
            return False
        return self.supervisor.restart_seen(f'its heartbeat producer 0x1017 reads {period} ms: '
                                            'it lost its configuration')

    # ---------------------------------------------------------------- non-blocking
    def send_velocity(self, speed: float) -> None:
        """Profile velocity: one command (mechanism rad/s); a held drive gets 0 and no state
        change, after request_fault_reset() the reset steps. DriveError for a non-finite
        speed, before connect, or on a CAN send error."""
        self._check_connected()
        self.commander.send_velocity(speed)

    def send_position(self, angle: float) -> None:
        """CSP: the position (mechanism rad, unwrapped) for the next SYNC (as send_velocity;
        a held drive is held where it is)."""
        self._check_connected()
        self.commander.send_position(angle)

    def send_hold(self) -> None:
        """Keep the drive fed without moving it: velocity 0, or in CSP the last target."""
        self._check_connected()
        self.commander.send_hold()

    def send_sync(self) -> None:
        """The SYNC frame (once per bus: `canbus.send_sync()` on a shared CanopenBus)."""
        self._check_connected()
        self.canbus.send_sync()

    def send_heartbeat(self) -> None:
        """Our heartbeat frame, for the drive's consumer (once per bus on a shared one)."""
        if self._link is None:
            raise NotConnectedError(f'drive node {self.config.drive_node_id}: not connected '
                                    '(call connect_and_enable first)')
        try:
            self.canbus.send_heartbeat()
        except DriveError as exc:
            raise type(exc)(f'drive node {self.config.drive_node_id}: {exc}') from None

    def status(self) -> DriveStatus:
        """Snapshot of the drive as the bus callbacks last saw it. NON-BLOCKING."""
        age = self._heartbeat_age()
        fb, sup, cmd = self.feedback, self.supervisor, self.commander
        with fb.lock:
            reason = sup.reason()
            state = state_of(fb.statusword) if fb.sw_received else 'UNKNOWN'
            return DriveStatus(
                state=state, statusword=fb.statusword, fault=bool(reason),
                error_code=fb.error_code or sup.emcy_code, position=fb.position,
                velocity=fb.velocity, heartbeat_age=age, stamp=fb.motion_stamp,
                fault_reason=reason, heartbeat_lost=age > self.config.drive_heartbeat_timeout,
                resetting=sup.reset_requested,
                enabled=(sup.enabled and self._connected and not reason
                         and not sup.reset_requested and state == OPERATION_ENABLED),
                commanded_velocity=cmd.commanded, mode=cmd.mode,
                commanded_position=cmd.commanded_position, restarted=sup.restarted)

    def request_fault_reset(self) -> None:
        """Ask for one fault reset (never done automatically). NON-BLOCKING."""
        self.supervisor.request_reset()

    # ---------------------------------------------------------------- blocking: stop
    def shutdown(self) -> None:
        """Target 0 (wait for standstill), disable (06h), stop consuming our heartbeat, NMT
        pre-operational, close. BLOCKING (about 2 x step_timeout at most), idempotent, never
        raises: a failing step is logged and the next one still runs."""
        link = self._link
        if link is None:
            return
        cfg = self.config
        with self.canbus.start_up_sync():
            if self._connected:
                try:
                    state = self.status().state
                    with self.feedback.lock:
                        self.supervisor.enabled = False
                        self.commander.commanded = 0.0
                    hold = CW_ENABLE_OPERATION if state == OPERATION_ENABLED else CW_QUICK_STOP
                    self._shutdown_wait(hold, lambda st: st.state != OPERATION_ENABLED
                                        or abs(st.velocity) < 0.01, 'still turning')
                    self._shutdown_wait(CW_SHUTDOWN, lambda st: st.state in (
                        READY_TO_SWITCH_ON, SWITCH_ON_DISABLED, FAULT), 'not disabled')
                except DriveError as exc:
                    log.warning('%s', exc)
            try:
                link.node.nmt.state = 'PRE-OPERATIONAL'
                plan = self.plan
                if self._heartbeat_age() < cfg.drive_heartbeat_timeout and (
                        plan is None or plan.heartbeat_consumer):
                    link.sdo.write('shutdown', od.HEARTBEAT_CONSUMER, 0)
            except Exception as exc:                    # best effort: the bus may be gone
                log.warning('drive node %d: shutdown: %s', cfg.drive_node_id, exc)
        with self.feedback.lock:
            self.supervisor.enabled = False
        if self.startup is not None:
            self.startup.connected = False
        self._close()

    def _shutdown_wait(self, controlword: int, done: Callable[[DriveStatus], bool],
                       complaint: str) -> None:
        deadline = time.monotonic() + self.config.step_timeout
        next_heartbeat = 0.0
        failed = None
        while True:
            now = time.monotonic()
            try:
                # (in CSP the SYNC producer started with the NMT start runs on: feedback comes)
                self.commander.transmit(controlword)
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
            with self.feedback.lock:
                self.feedback.lock.wait(0.01)

    def _close(self) -> None:
        link, self._link = self._link, None
        network = self.canbus.network
        node_id = link.node.id if link is not None else None
        if network is not None and node_id is not None and node_id in network:
            del network[node_id]
        self.commander.close()
        if self._owns_canbus:
            self.canbus.close()

    # ---------------------------------------------------------------- blocking: commissioning
    def read_identity(self) -> dict[str, int | None]:
        """The drive's identity (0x1000, 0x1018:1..4) and supported modes (0x6502) by SDO
        (BLOCKING; after open()). A missing entry reads None."""
        sdo = self._opened().sdo
        step = 'identify (0x1000, 0x1018, 0x6502)'
        return {name: sdo.read(step, obj, optional=True) for name, obj in (
            ('device_type', od.DEVICE_TYPE), ('vendor_id', od.VENDOR_ID),
            ('product_code', od.PRODUCT_CODE), ('revision', od.REVISION_NUMBER),
            ('serial', od.SERIAL_NUMBER), ('supported_modes', od.SUPPORTED_MODES))}

    def set_polarity(self, reversed_: bool) -> None:
        """0x607E: bits 7 and 6 (position and velocity inverted) or none (BLOCKING)."""
        self._opened().sdo.write('polarity (0x607E)', od.POLARITY,
                                 od.POLARITY_REVERSED if reversed_ else 0)

    def read_inputs(self) -> int:
        """The drive's digital inputs 0x60FD (bit 2 home switch) by SDO (BLOCKING)."""
        return self._opened().sdo.read('digital inputs (0x60FD)', od.DIGITAL_INPUTS)

    def home(self, method: int, switch_speed: float, zero_speed: float,
             timeout: float = 60.0) -> None:
        """Home the enabled drive with `method` (drive.startup.StartUp.home), BLOCKING."""
        self._check_connected().home(method, switch_speed, zero_speed, timeout)

    def jog(self, speed: float, until: Callable[[], bool] | None = None,
            timeout: float = 60.0) -> bool:
        """Turn at `speed` (mechanism rad/s, slow) in profile velocity until `until()` is true
        (called between frames; None: for `timeout` s), then stop (BLOCKING). Returns whether
        `until` was met. Our frames and SYNC keep the drive's watchdogs fed."""
        self._check_connected().check_mode('jog', PROFILE_VELOCITY)
        deadline = time.monotonic() + timeout
        met = False
        with self.canbus.start_up_sync():
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
        with self.canbus.start_up_sync():
            while time.monotonic() < deadline:
                self.send_velocity(0.0)
                self.send_heartbeat()
                if abs(self.feedback.velocity) <= 1e-3:
                    break
                time.sleep(0.01)
            for _ in range(3):                       # one more feedback period at rest
                self.send_velocity(0.0)
                self.send_heartbeat()
                time.sleep(max(self.config.feedback_period, self.config.sync_period))

    def move_by(self, angle: float, speed: float = 0.2, timeout: float = 30.0) -> float:
        """CSP: move `angle` rad (mechanism) from where the drive is at `speed` rad/s, one
        target per SYNC (the start-up producer's), and hold (BLOCKING). The angle the drive
        reports it moved."""
        self._check_connected().check_mode('move_by', CYCLIC_SYNC_POSITION)
        period = self.config.sync_period
        start = self.status().position
        steps = max(1, math.ceil(abs(angle) / (speed * period)))
        deadline = time.monotonic() + timeout
        with self.canbus.start_up_sync():
            for k in range(1, steps + 1):
                self.send_position(start + angle * k / steps)
                self.send_heartbeat()
                time.sleep(period)
                if time.monotonic() > deadline:
                    break
            end = time.monotonic() + 0.5
            while time.monotonic() < end:
                self.send_position(start + angle)
                self.send_heartbeat()
                time.sleep(period)
        return self.status().position - start

    def __enter__(self) -> 'Cia402Drive':
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()
