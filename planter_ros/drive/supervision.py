"""The master's judgement of one drive: faults latched until a reset is asked for, the one
fault reset per request, and a restart (a power cycle) noticed. It decides the controlword of
every frame the master sends (`controlword`), and shares the feedback's lock: it reads the
statusword the callbacks write.

A fault latches on the statusword's fault bit, any EMCY other than 00xxh, a heartbeat older
than `drive_heartbeat_timeout`, or the drive leaving OPERATION ENABLED unasked; every frame then
holds (no state change) until `request_reset()`: the next frames carry one fault-reset edge
(80h) and the steps back to OPERATION ENABLED, and give up after `reset_timeout`, never a
reset loop. Non-blocking throughout."""
from __future__ import annotations

from collections.abc import Callable
import logging
import time
from typing import TYPE_CHECKING

from .states import (EMCY_HEARTBEAT, FAULT, FAULT_REACTION_ACTIVE, NOT_READY, OPERATION_ENABLED,
                     QUICK_STOP_ACTIVE, READY_TO_SWITCH_ON, SWITCH_ON_DISABLED, SWITCHED_ON,
                     state_of)
from .words import (CW_DISABLE_VOLTAGE, CW_ENABLE_OPERATION, CW_FAULT_RESET, CW_QUICK_STOP,
                    CW_SHUTDOWN, CW_SWITCH_ON, SW_FAULT)

if TYPE_CHECKING:
    from canopen.emcy import EmcyError

    from .config import DriveConfig
    from .feedback import Feedback

__all__ = ['Supervisor', 'NMT_OPERATIONAL']

log = logging.getLogger(__name__)
NMT_OPERATIONAL = 0x05

# Fault reset / re-enable: the controlword that moves each state one step towards
# OPERATION ENABLED (the fault state handled separately: one reset edge per request).
_REENABLE_STEP = {
    SWITCH_ON_DISABLED: CW_SHUTDOWN,
    READY_TO_SWITCH_ON: CW_SWITCH_ON,
    SWITCHED_ON: CW_ENABLE_OPERATION,
    QUICK_STOP_ACTIVE: CW_DISABLE_VOLTAGE,      # via SWITCH ON DISABLED (always allowed)
    NOT_READY: CW_DISABLE_VOLTAGE,
    FAULT_REACTION_ACTIVE: CW_DISABLE_VOLTAGE,
}


class Supervisor:
    """Fault latch, fault reset and restart detection of one drive (module doc)."""

    def __init__(self, config: DriveConfig, feedback: Feedback,
                 heartbeat_age: Callable[[], float]) -> None:
        self.config = config
        self.feedback = feedback
        self.heartbeat_age = heartbeat_age
        self.lock = feedback.lock
        self.enabled = False              # the enable steps finished (cleared by shutdown)
        self.latched = ''                 # why the drive is held ('' : it is not)
        self.emcy_code = 0
        self.reset_requested = False
        self._reset_deadline = 0.0
        self._reset_edge_sent = False
        self.last_controlword = 0
        self.restarted = ''               # why it must be configured again
        feedback.on_statusword = self._on_statusword

    @property
    def node_id(self) -> int:
        return self.config.drive_node_id

    def _on_statusword(self, statusword: int) -> None:
        """A new statusword (lock held by the feedback)."""
        if (self.enabled and not self.reset_requested and not self.latched
                and state_of(statusword) != OPERATION_ENABLED):
            self.latched = f'drive left OPERATION ENABLED ({state_of(statusword)})'

    def on_emcy(self, entry: EmcyError) -> None:
        if entry.code & 0xFF00 == 0:                # "error reset / no error"
            return
        with self.lock:
            self.emcy_code = entry.code
            if not self.latched:
                desc = entry.get_desc() or 'drive error'
                self.latched = f'EMCY 0x{entry.code:04X} ({desc})'

    def on_nmt_state(self, state: int) -> None:
        """The drive's heartbeat or boot-up message (NMT state; 00h = boot-up). A drive we
        enabled that boots, or says it is not operational, has lost its configuration (a
        power cycle, a reset): latched, and `restarted` says why until it is configured
        again."""
        if state == NMT_OPERATIONAL:
            return
        with self.lock:
            if not self.enabled or self.restarted:
                return
            self.restarted = ('boot-up message' if state == 0
                              else f'its heartbeat says NMT state 0x{state:02X}')
            self.latched = f'drive restarted ({self.restarted})'

    def restart_seen(self, why: str) -> bool:
        """The drive lost its configuration (`why`); False when that was already known or
        it is not enabled."""
        with self.lock:
            if not self.enabled or self.restarted:
                return bool(self.restarted)
            self.restarted = why
            self.latched = f'drive restarted ({why})'
            return True

    def latch_heartbeat_loss(self) -> None:
        """Lock held."""
        if self.enabled and not self.latched and not self.reset_requested:
            if self.heartbeat_age() > self.config.drive_heartbeat_timeout:
                self.latched = 'drive heartbeat lost'
                self.emcy_code = self.emcy_code or EMCY_HEARTBEAT

    def controlword(self, now: float) -> tuple[int, bool]:
        """(controlword of the next frame, whether it may carry a command); lock held."""
        self.latch_heartbeat_loss()
        state = state_of(self.feedback.statusword)
        if self.reset_requested:
            return self._reset_step(state, now), False
        if self.latched or state != OPERATION_ENABLED:
            # refuse: hold, and a controlword that causes no transition towards enabled (0x0F
            # holds an enabled drive; quick stop elsewhere)
            return (CW_ENABLE_OPERATION if state == OPERATION_ENABLED else CW_QUICK_STOP), False
        return CW_ENABLE_OPERATION, True

    def _reset_step(self, state: str, now: float) -> int:
        if now > self._reset_deadline:
            self.reset_requested = False
            self.latched = self.latched or f'fault reset failed (state {state})'
            log.warning('drive node %d: fault reset abandoned in state %s', self.node_id, state)
            return CW_ENABLE_OPERATION if state == OPERATION_ENABLED else CW_QUICK_STOP
        if state == FAULT:
            if self._reset_edge_sent:
                return CW_FAULT_RESET                   # hold: one edge per request, no loop
            if self.last_controlword & CW_FAULT_RESET:
                return CW_DISABLE_VOLTAGE               # need a 0 first for the rising edge
            self._reset_edge_sent = True
            return CW_FAULT_RESET
        if state == OPERATION_ENABLED:
            self.reset_requested = False
            return CW_ENABLE_OPERATION
        return _REENABLE_STEP.get(state, CW_DISABLE_VOLTAGE)

    def request_reset(self) -> None:
        with self.lock:
            self.reset_requested = True
            self._reset_edge_sent = False
            self._reset_deadline = time.monotonic() + self.config.reset_timeout
            self.latched = ''
            self.emcy_code = 0

    def enabled_now(self) -> None:
        """The enable steps reached OPERATION ENABLED: nothing latched any more."""
        with self.lock:
            self.reset_requested = False
            self.latched = ''
            self.emcy_code = 0
            self.enabled = True

    def configuring(self) -> None:
        """Being configured again (a restart): not enabled until the enable steps finish."""
        with self.lock:
            self.enabled = False
            self.reset_requested = False
            self.latched = self.latched or 'drive being configured again'

    def reason(self) -> str:
        """Why the drive is held now ('' : it is not); lock held."""
        self.latch_heartbeat_loss()
        fault_bit = bool(self.feedback.statusword & SW_FAULT) and self.feedback.sw_received
        return self.latched or ('statusword fault bit' if fault_bit else '')
