"""The simulated drive's CiA 402 device control: its state, the controlword it obeys (all eight
states, 605Ah's quick stop options, one fault-reset edge needed, a state that can be held as an
STO would), its fault and its mode of operation (6061h keeps its value for a mode the drive does
not offer, as many drives do). Plain state: the drive's lock is held by the caller."""
from __future__ import annotations

from dataclasses import dataclass

from planter_ros.drive.objects import HOMING
from planter_ros.drive.states import (FAULT, FAULT_REACTION_ACTIVE, NOT_READY, OPERATION_ENABLED,
                                      QUICK_STOP_ACTIVE, READY_TO_SWITCH_ON, SWITCH_ON_DISABLED,
                                      SWITCHED_ON)
from planter_ros.drive.words import (CW_ENABLE_OPERATION_BIT, CW_ENABLE_VOLTAGE_BIT,
                                     CW_FAULT_RESET, CW_HOMING_START, CW_QUICK_STOP_BIT,
                                     CW_SWITCH_ON_BIT)

__all__ = ['DeviceControl', 'Transition', 'next_state']


def next_state(state: str, controlword: int, quick_stop_option: int) -> str:
    """One CiA 402 device-control transition for a controlword (bit 7 handled by the caller)."""
    if not controlword & CW_ENABLE_VOLTAGE_BIT:                         # disable voltage
        if state in (READY_TO_SWITCH_ON, SWITCHED_ON, OPERATION_ENABLED, QUICK_STOP_ACTIVE):
            return SWITCH_ON_DISABLED
        return state
    if not controlword & CW_QUICK_STOP_BIT:                             # quick stop
        return {READY_TO_SWITCH_ON: SWITCH_ON_DISABLED, SWITCHED_ON: SWITCH_ON_DISABLED,
                OPERATION_ENABLED: QUICK_STOP_ACTIVE}.get(state, state)
    if not controlword & CW_SWITCH_ON_BIT:                              # shutdown
        if state in (SWITCH_ON_DISABLED, SWITCHED_ON, OPERATION_ENABLED):
            return READY_TO_SWITCH_ON
        return state
    if controlword & CW_ENABLE_OPERATION_BIT:                # (switch on +) enable operation
        if state == QUICK_STOP_ACTIVE:                       # transition 16: options 5..8 only
            return OPERATION_ENABLED if 5 <= quick_stop_option <= 8 else state
        return {READY_TO_SWITCH_ON: SWITCHED_ON, SWITCHED_ON: OPERATION_ENABLED}.get(state, state)
    return {READY_TO_SWITCH_ON: SWITCHED_ON, OPERATION_ENABLED: SWITCHED_ON}.get(state, state)


@dataclass
class Transition:
    """What one controlword did."""

    reset_done: bool = False          # a fault reset cleared the fault
    enabled: bool = False             # the drive entered OPERATION ENABLED
    quick_stop: bool = False          # it entered QUICK STOP ACTIVE
    homing_start: bool = False        # bit 4 rose in homing mode, enabled
    homing_stop: bool = False         # bit 4 cleared in homing mode


@dataclass
class DeviceControl:
    """State, controlword, fault and mode of one simulated drive (module doc)."""

    supported: tuple[int, ...] = ()   # modes 6060h accepts (homing always)
    state: str = NOT_READY
    controlword: int = 0
    mode: int = 0
    quick_stop_option: int = 2        # 605Ah
    fault_code: int = 0
    fault_persistent: bool = False
    error_code: int = 0               # 603Fh
    quick_stopped: bool = False       # a quick stop since the drive was last enabled
    held: str | None = None           # a state no transition leaves (STO)

    def apply(self, controlword: int) -> Transition:
        """The drive receives `controlword` (its transitions, at most three steps)."""
        out = Transition()
        rising_reset = bool(controlword & CW_FAULT_RESET) and not self.controlword & CW_FAULT_RESET
        if self.mode == HOMING and self.state == OPERATION_ENABLED:
            rising = bool(controlword & CW_HOMING_START) and not self.controlword & CW_HOMING_START
            out.homing_start = rising
            out.homing_stop = not controlword & CW_HOMING_START
        self.controlword = controlword
        state = self.state
        if state == FAULT:
            if rising_reset and not self.fault_persistent:
                self.fault_code = self.error_code = 0
                self.state = SWITCH_ON_DISABLED
                out.reset_done = True
            return out
        if state in (NOT_READY, FAULT_REACTION_ACTIVE):
            return out
        for _ in range(3):
            new = next_state(state, controlword, self.quick_stop_option)
            if new == state or state == self.held:
                break
            state = new
            if state == OPERATION_ENABLED:
                out.enabled = True
                self.quick_stopped = False
            elif state == QUICK_STOP_ACTIVE:
                out.quick_stop = self.quick_stopped = True
        self.state = state
        return out

    def fault(self, code: int, persistent: bool = False) -> None:
        """A fault now: fault reaction (ramp) from a powered state, else FAULT at once."""
        self.fault_code = self.error_code = int(code)
        self.fault_persistent = persistent
        powered = self.state in (OPERATION_ENABLED, QUICK_STOP_ACTIVE)
        self.state = FAULT_REACTION_ACTIVE if powered else FAULT

    def communication_error(self, code: int, abort_option: int) -> None:
        """Abort connection option 6007h: 0 none, 1 fault, 2 disable voltage, 3 quick stop."""
        self.error_code = code
        if abort_option == 1:
            self.fault_code = code
            self.state = FAULT_REACTION_ACTIVE
        elif abort_option == 2:
            self.state = SWITCH_ON_DISABLED
        elif abort_option == 3:
            self.state = QUICK_STOP_ACTIVE
            self.quick_stopped = True

    def set_mode(self, mode: int) -> bool:
        """6060h written: True when the mode changed (an unsupported one is ignored)."""
        if mode not in self.supported and mode != HOMING:
            return False
        changed = mode != self.mode
        self.mode = mode
        return changed

    def stopped(self) -> None:
        """The motor came to rest: a fault reaction ends in FAULT, a quick stop with options
        1..4 in SWITCH ON DISABLED."""
        if self.state == FAULT_REACTION_ACTIVE:
            self.state = FAULT
        elif self.state == QUICK_STOP_ACTIVE and self.quick_stop_option in (1, 2, 3, 4):
            self.state = SWITCH_ON_DISABLED
