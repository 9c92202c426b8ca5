"""Bringing one drive up: the start-up sequence the master runs at every start and after a
power cycle, and homing. BLOCKING (SDO and state waits), never from a callback or the loop.

1. NMT pre-operational, with SYNC flowing from here on (the bus's start-up producer: a strict
   CiA 301 drive acts on a synchronous RPDO and sends a synchronous TPDO only on SYNC);
2. identify: 1000h a CiA 402 device, 6502h the modes, 608Fh the encoder resolution; the
   machine file's identity (1018h) and modes;
3. the start-up plan (drive.plan) from the drive's EDS, for the mode chosen: refused here,
   before anything moves, when the mode needs what the drive lacks;
4. the plan's PDOs written (CiA 301's order) and read back, then its writes (heartbeats,
   watchdogs, polarity, SYNC and interpolation period, following error), CSP's target set to
   the actual position, 6060h written and confirmed by 6061h;
5. the drive's heartbeat, NMT operational (repeated until its first statusword TPDO), the
   enable steps 06h, 07h, 0Fh (each within `step_timeout`), homing with the machine file's
   method.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
import logging
import time
from typing import TYPE_CHECKING

from . import objects as od
from .dictionary import pdo_maps
from .errors import (DriveConfigError, DriveError, DriveRefusedError, DriveTimeoutError,
                     can_calls)
from .plan import MODE_NAMES, DrivePlan, Write, choose_mode, homing_writes, plan_drive
from .setup import (HOMING_SEARCH_SPEED, HOMING_ZERO_SPEED, homing_timeout, identity_mismatch,
                    missing_modes, pdo_mismatch)
from .states import (CYCLIC_SYNC_POSITION, FAULT, FAULT_REACTION_ACTIVE, OPERATION_ENABLED,
                     READY_TO_SWITCH_ON, SWITCH_ON_DISABLED, SWITCHED_ON, state_of)
from .words import (CW_DISABLE_VOLTAGE, CW_ENABLE_OPERATION, CW_FAULT_RESET, CW_HOMING_START,
                    CW_SHUTDOWN, CW_SWITCH_ON, SW_HOMED, SW_HOMING_ERROR)

if TYPE_CHECKING:
    from canopen import ObjectDictionary
    from canopen.profiles.p402 import BaseNode402

    from .bus import CanopenBus
    from .config import DriveConfig
    from .feedback import Feedback
    from .rpdo import Commander
    from .sdo import Sdo
    from .setup import DriveSetup
    from .supervision import Supervisor

__all__ = ['DriveLink', 'StartUp', 'NMT_REPEAT']

log = logging.getLogger(__name__)
NMT_REPEAT = 0.1          # s between two NMT start commands while the drive has not answered


@dataclass(frozen=True)
class DriveLink:
    """One drive's node on its bus, as `Cia402Drive.open()` made it: the bus, the canopen node
    with the dictionary read from the drive's EDS, and SDO access to it."""

    canbus: CanopenBus
    node: BaseNode402
    dictionary: ObjectDictionary
    sdo: Sdo


class StartUp:
    """The start-up of one drive and what it made: the plan, the mode, whether PDOs flow."""

    def __init__(self, config: DriveConfig, setup: DriveSetup | None, link: DriveLink,
                 feedback: Feedback, supervisor: Supervisor, commander: Commander) -> None:
        self.config, self.setup, self.link, self.feedback = config, setup, link, feedback
        self.canbus, self.node, self.dictionary, self.sdo = (link.canbus, link.node,
                                                              link.dictionary, link.sdo)
        self.supervisor, self.commander = supervisor, commander
        self.plan: DrivePlan | None = None
        self.connected = False            # PDOs configured, the drive operational
        self.enable_duration = float('nan')

    def fail(self, step: str, detail: str, kind: type[DriveError]) -> DriveError:
        return self.sdo.fail(step, detail, kind)

    def run(self) -> None:
        """The whole sequence (module doc). Raises DriveError."""
        t_start = time.monotonic()
        with self.canbus.start_up_sync():
            self._send_nmt('PRE-OPERATIONAL')
            supported = self._identify()
            self._check_setup()
            who = f'drive node {self.config.drive_node_id}'
            mode = choose_mode(self.config.operation_mode, supported, self.setup,
                               f'{who}: choose the operation mode', DriveRefusedError)
            self.plan = plan = plan_drive(self.dictionary, self.config, self.setup, mode, who)
            self._configure_pdos(plan)
            self._verify_pdos(plan)
            heartbeat_written = time.time()
            for write in plan.writes:
                self.sdo.write(write.step, write.obj, write.value)
            if mode == CYCLIC_SYNC_POSITION:
                self.hold_here('target position = actual position (0x607A from 0x6064)')
            self.change_mode(f'mode of operation (0x6060 = {mode}, confirmed by 0x6061)', mode)
            self._wait_drive_heartbeat(since=heartbeat_written)
            self._go_operational()
            self._enable_state_machine()
            if self.setup is not None and self.setup.homing_method:
                self.home(self.setup.homing_method, HOMING_SEARCH_SPEED, HOMING_ZERO_SPEED,
                          timeout=homing_timeout(), writes=plan.homing)
        self.enable_duration = time.monotonic() - t_start
        log.info('drive node %d enabled in %.1f ms (%s)', self.config.drive_node_id,
                 1000 * self.enable_duration, MODE_NAMES[mode])

    def _send_nmt(self, state: str) -> None:
        node = self.config.drive_node_id
        with can_calls(f'drive node {node}: CAN send of NMT {state.lower()} failed on '
                       f'{self.canbus.where}', node):
            self.node.nmt.state = state

    def _identify(self) -> int | None:
        """Refuse a node that is not a CiA 402 drive; its 6502h (None: it does not say)."""
        cfg = self.config
        step = 'identify (SDO 0x1000 device type)'
        device_type = self.sdo.read(step, od.DEVICE_TYPE)
        if device_type & 0xFFFF != 402:
            raise self.fail(step, f'device type 0x{device_type:08X} is not a CiA 402 drive',
                            DriveRefusedError)
        supported = self.sdo.read('choose the operation mode (0x6502 supported drive modes)',
                                  od.SUPPORTED_MODES, optional=True)
        step = 'check encoder resolution (0x608F)'
        increments = self.sdo.read(step, od.ENCODER_INCREMENTS, optional=True)
        revolutions = self.sdo.read(step, od.ENCODER_MOTOR_REVOLUTIONS, optional=True)
        if increments and revolutions and increments / revolutions != cfg.counts_per_motor_rev:
            raise self.fail(step, f'drive counts {increments}/{revolutions} increments per '
                                  f'motor rev but counts_per_motor_rev={cfg.counts_per_motor_rev}',
                            DriveRefusedError)
        return supported

    def _check_setup(self) -> None:
        """Refuse a drive that is not the one the machine file describes: its identity (0x1018
        as the file states it) and the modes the row needs (0x6502)."""
        setup = self.setup
        if setup is None:
            return
        step = 'check against the machine file'
        identity = {name: self.sdo.read(step, obj, optional=True) for name, obj in (
            ('vendor_id', od.VENDOR_ID), ('product_code', od.PRODUCT_CODE),
            ('revision', od.REVISION_NUMBER))}
        mismatch = identity_mismatch(setup, identity)
        if not mismatch:
            modes = self.sdo.read(step, od.SUPPORTED_MODES, optional=True)
            missing = missing_modes(modes, setup)
            if missing:
                shown = 'nothing' if modes is None else f'0x{modes:08X}'
                mismatch = (f'0x6502 supported drive modes: expected {", ".join(missing)}, '
                            f'found {shown}')
        if mismatch:
            raise self.fail(step, mismatch, DriveRefusedError)

    def _configure_pdos(self, plan: DrivePlan) -> None:
        """The plan's PDO writes, then canopen's maps set to match for receiving the TPDOs
        (no canopen `save()`: it writes sub-indices a drive may not have)."""
        for write in plan.comm:
            self.sdo.write(write.step, write.obj, write.value)
        node = self.node
        used = {pdo.number for pdo in plan.tpdos}
        for number, tpdo in pdo_maps(node.tpdo).items():
            if number not in used:
                tpdo.enabled = False
                if tpdo.cob_id:
                    node.network.unsubscribe(tpdo.cob_id, tpdo.on_message)
        for pdo in plan.tpdos:
            tpdo = node.tpdo[pdo.number]
            tpdo.clear()
            for obj in pdo.entries:
                tpdo.add_variable(obj.index, obj.subindex)
            tpdo.cob_id = pdo.cob_id(self.config.drive_node_id)
            tpdo.trans_type = pdo.trans_type
            tpdo.enabled = True
            tpdo.subscribe()
            if self.feedback.on_tpdo not in tpdo.callbacks:
                tpdo.add_callback(self.feedback.on_tpdo)
        self.commander.configure(node.network, plan.mode, plan.rpdos)

    def _verify_pdos(self, plan: DrivePlan) -> None:
        """Read the PDO mapping back (SDO): a drive that took the writes but maps otherwise
        (a read-only or fixed mapping) is refused, naming the entry."""
        step = 'PDO mapping read back (0x1400/0x1600, 0x1800/0x1A00)'
        obj8, obj32 = od.UNSIGNED8, od.UNSIGNED32

        def read(index: int, sub: int) -> int:
            dtype = obj8 if sub == 0 and index & 0x200 else obj32
            return self.sdo.read(step, od.Obj(index, sub, dtype, f'{index:04X}h:{sub}', ''))
        for pdo in (*plan.rpdos, *plan.tpdos):
            mismatch = pdo_mismatch(pdo.layout, self.config.drive_node_id, read)
            if mismatch:
                raise self.fail(step, mismatch, DriveRefusedError)

    def hold_here(self, step: str) -> None:
        """CSP: the position target (0x607A and our frames') = the actual position."""
        actual = self.sdo.read(step, od.POSITION_ACTUAL)
        self.sdo.write(step, od.TARGET_POSITION, actual)
        with self.feedback.lock:
            self.commander.target_counts = actual

    def change_mode(self, step: str, mode: int) -> None:
        """0x6060 = `mode`, confirmed by reading 0x6061 (drives switch modes with a delay)."""
        self.sdo.write(step, od.MODES_OF_OPERATION, mode)
        deadline = time.monotonic() + self.config.step_timeout
        while (shown := self.sdo.read(step, od.MODES_DISPLAY)) != mode:
            if time.monotonic() > deadline:
                raise self.fail(step, f'0x6061 reads {shown} after writing {mode} for '
                                      f'{self.config.step_timeout:.2f} s', DriveTimeoutError)
            time.sleep(0.005)

    def _wait_drive_heartbeat(self, since: float) -> None:
        """The drive's first heartbeat after 0x1017 was written (wall-clock `since`)."""
        cfg = self.config
        wait = max(cfg.step_timeout, 2.5 * cfg.drive_heartbeat_period)
        deadline = time.monotonic() + wait
        while (self.node.nmt.timestamp or 0.0) < since:
            if time.monotonic() > deadline:
                period_ms = round(cfg.drive_heartbeat_period * 1000)
                raise self.fail('drive heartbeat', f'no heartbeat within {wait:.2f} s after '
                                f'setting 0x1017 = {period_ms} ms', DriveTimeoutError)
            time.sleep(0.002)

    def _go_operational(self) -> None:
        """NMT operational: PDOs flow; wait for the first statusword TPDO (after a SYNC in
        CSP). The NMT command is unconfirmed (a lost frame is never re-sent by the bus):
        repeated every NMT_REPEAT s until the drive answers."""
        self.feedback.forget_statusword()
        self.connected = True
        self.wait_state('NMT operational (first statusword TPDO)',
                        lambda state: self.feedback.sw_received, 'no statusword TPDO'
                        + (' (SYNC sent: none answered)' if self.canbus.producing_sync
                           else ''),
                        resend=lambda: self._send_nmt('OPERATIONAL'), resend_period=NMT_REPEAT)

    def _enable_state_machine(self) -> None:
        """From whatever state the drive is in to OPERATION ENABLED, one step at a time."""
        with self.feedback.lock:
            state = state_of(self.feedback.statusword)
            resetting = self.supervisor.reset_requested
        if state in (FAULT, FAULT_REACTION_ACTIVE):
            if not resetting:
                raise self.fail('enable', f'drive is in FAULT (error code '
                                          f'0x{self.feedback.error_code:04X}); call '
                                          'request_fault_reset() and connect again',
                                DriveRefusedError)
            self.commander.transmit(CW_DISABLE_VOLTAGE)
            self.wait_step('fault reset (0x80)', CW_FAULT_RESET, SWITCH_ON_DISABLED)
        elif state not in (SWITCH_ON_DISABLED, READY_TO_SWITCH_ON):
            # left enabled (or quick-stopped) by an earlier session: start from the bottom
            self.wait_step('disable voltage (0x00)', CW_DISABLE_VOLTAGE, SWITCH_ON_DISABLED)
        self.wait_step('shutdown (0x06)', CW_SHUTDOWN, READY_TO_SWITCH_ON)
        self.wait_step('switch on (0x07)', CW_SWITCH_ON, SWITCHED_ON)
        self.wait_step('enable operation (0x0F)', CW_ENABLE_OPERATION, OPERATION_ENABLED)
        self.supervisor.enabled_now()

    def wait_state(self, step: str, done: Callable[[str], bool], what: str,
                   resend: Callable[[], object] | None = None,
                   resend_period: float = 0.02) -> None:
        fb = self.feedback
        deadline = time.monotonic() + self.config.step_timeout
        next_send = 0.0
        while True:
            with fb.lock:
                state = state_of(fb.statusword)
                if done(state):
                    return
                if deadline - time.monotonic() <= 0:
                    sw = fb.statusword
                    break
            now = time.monotonic()
            if resend is not None and now >= next_send:   # keeps the RPDO deadline fed
                resend()
                next_send = now + resend_period
            with fb.lock:
                fb.lock.wait(min(max(deadline - time.monotonic(), 0.0), 0.005))
        seen = f'state stays {state} (statusword 0x{sw:04X})' if fb.sw_received else what
        raise self.fail(f'enable step {step!r}',
                        f'timed out after {self.config.step_timeout:.2f} s: {seen}',
                        DriveTimeoutError)

    def wait_step(self, step: str, controlword: int, target_state: str) -> None:
        self.wait_state(step, lambda state: state == target_state, 'no statusword',
                        resend=lambda: self.commander.transmit(controlword))

    def home(self, method: int, switch_speed: float, zero_speed: float,
             timeout: float = 60.0, writes: Sequence[Write] = ()) -> None:
        """Home the enabled drive: homing mode 6 with `method` (0x6098), speeds in mechanism
        rad/s (0x6099:1 search for the switch, :2 for zero), home offset 0 where it can;
        started with controlword bit 4, finished by statusword bits 12 (attained) and 10
        (target reached), refused on bit 13 (homing error) or after `timeout` s. Our frames
        (RPDO, heartbeat, SYNC) keep flowing meanwhile; then back to the mode chosen at
        enable, CSP's target first re-synced to where homing left the shaft."""
        mode = self.commander.mode
        step = f'homing method {method} (0x6098, 0x6099, 0x607C, 0x6060 = 6)'
        if not writes:
            writes = homing_writes(self.dictionary, method, self.config, switch_speed,
                                   zero_speed)
        with self.canbus.start_up_sync():
            for write in writes:
                self.sdo.write(write.step, write.obj, write.value)
            self.commander.transmit(CW_ENABLE_OPERATION)
            self.change_mode(step, od.HOMING)
            deadline = time.monotonic() + timeout
            try:
                while True:
                    self.commander.transmit(CW_ENABLE_OPERATION | CW_HOMING_START)
                    self.canbus.send_heartbeat()
                    sw = self.sdo.read(step, od.STATUSWORD)
                    if sw & SW_HOMING_ERROR:
                        raise self.fail(step, f'the drive reports a homing error (statusword '
                                              f'0x{sw:04X})', DriveRefusedError)
                    if sw & SW_HOMED == SW_HOMED:
                        break
                    if state_of(sw) != OPERATION_ENABLED:
                        raise self.fail(step, f'the drive left operation enabled (statusword '
                                              f'0x{sw:04X})', DriveRefusedError)
                    if time.monotonic() > deadline:
                        raise self.fail(step, f'not homed within {timeout:g} s (statusword '
                                              f'0x{sw:04X})', DriveTimeoutError)
                    time.sleep(0.01)
            finally:
                if mode == CYCLIC_SYNC_POSITION:
                    self.hold_here('back to CSP after homing (0x607A from 0x6064)')
                self.commander.transmit(CW_ENABLE_OPERATION)
                self.change_mode('back to the running mode after homing', mode)
            # the homed position in the TPDOs (after a SYNC in CSP)
            time.sleep(2.5 * max(self.config.feedback_period, self.config.sync_period))

    def check_mode(self, step: str, mode: int) -> None:
        if self.commander.mode != mode:
            raise self.fail(step, f'needs {MODE_NAMES[mode]} (operation_mode)',
                            DriveConfigError)
