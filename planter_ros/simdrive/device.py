"""The simulated drive's device side: what a servo drive does with the values it is given, apart
from how they reach it. It owns the CiA 402 state machine (`control`), the motor (`motor`),
the CSP set point (`csp`), homing (`homing`), the target velocity and the polarity; it takes
the dictionary's writes (`write`), gives its live values (`read`, the statusword among them)
and moves the motor up to an instant (`advance`). The drive's lock is held by every caller."""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

from planter_ros.drive import objects as objs
from planter_ros.drive.states import (CYCLIC_SYNC_POSITION, FAULT, FAULT_REACTION_ACTIVE,
                                      MODE_SUPPORTED, OPERATION_ENABLED, PROFILE_VELOCITY,
                                      QUICK_STOP_ACTIVE)
from planter_ros.drive.words import (ERROR_REGISTER_COMMUNICATION, ERROR_REGISTER_GENERIC,
                                     STATE_BITS, SW_FOLLOWING_ERROR, SW_FOLLOWS,
                                     SW_HOMING_ATTAINED, SW_HOMING_ERROR, SW_REMOTE,
                                     SW_SPEED_ZERO, SW_TARGET_REACHED, error_register)

from .control import DeviceControl, Transition
from .csp import CspSetpoint, wrap_i32
from .homing import Homing, HomingOrder
from .motor import Motor

if TYPE_CHECKING:
    from .mechanism import Mechanism
    from .node import StrictNode
    from .spec import SimSpec

__all__ = ['SimulatedDevice']

HOMING_SUPPORTED = 0x20            # 6502h bit 5


def _clip_i32(value: int) -> int:
    return max(-2**31, min(2**31 - 1, value))


class SimulatedDevice:
    """State machine, motor, CSP, homing, target and polarity of one drive (module doc)."""

    def __init__(self, spec: SimSpec, node: StrictNode, mechanism: Mechanism,
                 kept: tuple | None = None) -> None:
        self.spec, self.node, self.mechanism = spec, node, mechanism
        if spec.supported_modes is not None:
            self.supported_modes = tuple(spec.supported_modes)
        else:
            bits = node.value(objs.SUPPORTED_MODES.index, 0, 0)
            self.supported_modes = tuple(m for m, bit in MODE_SUPPORTED.items() if bits & bit)
        self.control = DeviceControl(self.supported_modes,
                                     quick_stop_option=node.value(0x605A, 0, 2))
        self.motor = Motor(spec)
        self.csp = CspSetpoint()
        self.homing = Homing(spec.counts_per_motor_rev, mechanism.switch_active)
        self.target = 0                     # counts/s, 60FFh
        self.polarity = 0                   # 607Eh
        if kept is not None:                # a power cycle keeps these (non-volatile)
            (self.motor.position, self.motor.velocity, self.motor.time, self.polarity,
             self.homing.shift) = kept
        self.syncs_seen = 0
        self.target_at_enable: int | None = None
        self.interpolation()

    def kept(self) -> tuple:
        """What a power cycle keeps: the absolute encoder, the polarity, the home."""
        return (self.motor.position, self.motor.velocity, self.motor.time, self.polarity,
                self.homing.shift)

    def sign(self, bit: int) -> float:
        """-1 where 607Eh inverts (bit 7 position, bit 6 velocity), else 1."""
        return -1.0 if self.polarity & bit else 1.0

    def interpolation(self, written: tuple[int, int, int] | None = None) -> None:
        """The CSP interpolation period: 60C2h:1 × 10^60C2h:2 s (1006h without 60C2h);
        `written`: (index, sub-index, value) being written now (not stored yet)."""
        def value(index: int, subindex: int, default: int | None = None) -> int | None:
            if written is not None and written[:2] == (index, subindex):
                return written[2]
            return self.node.value(index, subindex, default)
        periods = value(0x60C2, 1)
        if periods is not None:
            index = value(0x60C2, 2, -3)
            self.csp.period = periods * 10.0 ** (index if index is not None else -3)
        else:
            self.csp.period = (value(0x1006, 0, 0) or 0) / 1e6

    # ---------------------------------------------------------------- the dictionary
    def statusword(self) -> int:
        control = self.control
        sw = STATE_BITS[control.state] | SW_REMOTE
        if control.state != OPERATION_ENABLED:
            return sw
        if control.mode == CYCLIC_SYNC_POSITION:
            sw |= SW_FOLLOWS
            if abs(self.csp.error) > self.csp.window:
                sw |= SW_FOLLOWING_ERROR
        elif control.mode == objs.HOMING:
            sw |= (SW_HOMING_ATTAINED if self.homing.attained else 0) | (
                SW_HOMING_ERROR if self.homing.error else 0) | (
                SW_TARGET_REACHED if self.homing.phase is None else 0)
        elif control.mode == PROFILE_VELOCITY:
            target = self.sign(0x40) * self.target
            v = self.motor.velocity
            if abs(v - target) <= max(1.0, 0.01 * abs(target)):
                sw |= SW_TARGET_REACHED
            if abs(v) < 1.0:
                sw |= SW_SPEED_ZERO
        return sw

    def error_register(self) -> int:
        """1001h: bit 0 with any error bit (communication: bit 4)."""
        if self.control.state not in (FAULT, FAULT_REACTION_ACTIVE):
            return 0
        code = self.control.error_code
        communication = code & 0xFF00 == 0x8100 or code == 0x8250
        return error_register(ERROR_REGISTER_COMMUNICATION if communication
                              else ERROR_REGISTER_GENERIC)

    def read(self, index: int, subindex: int) -> int | None:
        """A live value (None: the dictionary's own)."""
        motor = self.motor
        if index == objs.STATUSWORD.index:
            return self.statusword()
        if index == objs.CONTROLWORD.index:
            return self.control.controlword
        if index == objs.MODES_DISPLAY.index:
            return self.control.mode
        if index == objs.POSITION_ACTUAL.index:
            return wrap_i32(round(self.sign(0x80) * motor.position + self.homing.shift))
        if index == objs.VELOCITY_ACTUAL.index:
            return _clip_i32(round(self.sign(0x40) * motor.velocity))
        if index == objs.TARGET_VELOCITY.index:
            return self.target
        if index == objs.TARGET_POSITION.index:
            return wrap_i32(round(self.sign(0x80) * self.csp.to + self.homing.shift))
        if index == objs.SUPPORTED_MODES.index:
            homing = HOMING_SUPPORTED if self.node.has(objs.HOMING_METHOD.index) else 0
            return sum(MODE_SUPPORTED.get(m, 0) for m in self.supported_modes) | homing
        if index == objs.POLARITY.index:
            return self.polarity
        if index == objs.DIGITAL_INPUTS.index:
            return objs.DI_HOME_SWITCH if self.mechanism.switch_active(motor.position) else 0
        if index == objs.VENDOR_ID.index and 1 <= subindex <= 4 and self.spec.identity:
            return self.spec.identity[subindex - 1]
        if index == objs.ERROR_CODE.index:
            return self.control.error_code
        if index == objs.ERROR_REGISTER.index:
            return self.error_register()
        return None

    def write(self, index: int, subindex: int, value: int) -> Transition | None:
        """A value written by SDO or an RPDO acted on; the controlword's Transition."""
        if index == objs.CONTROLWORD.index:
            return self.apply_controlword(value)
        if index == objs.TARGET_VELOCITY.index:
            self.target = value
        elif index == objs.TARGET_POSITION.index:
            counts = value
            if self.polarity & 0x80 or self.homing.shift:        # to the motor's counts
                counts = wrap_i32(round(self.sign(0x80) * (value - self.homing.shift)))
            if self.control.state != OPERATION_ENABLED or self.syncs_seen == 0:
                self.csp.hold(self.csp.unwrap(counts))          # no SYNC yet: a set point
            self.csp.pending = counts
        elif index in (0x60C2, objs.COMM_CYCLE_PERIOD.index):
            self.interpolation((index, subindex, value))
        elif index == objs.FOLLOWING_ERROR_WINDOW.index:
            self.csp.window = float(value)
        elif index == objs.FOLLOWING_ERROR_TIMEOUT.index:
            self.csp.timeout = value / 1000.0
        elif index == objs.MODES_OF_OPERATION.index:
            if self.control.set_mode(value):
                self.homing.reset()
                if value == CYCLIC_SYNC_POSITION:       # the target re-synced to the shaft
                    self.csp.hold(self.motor.position)
        elif index == objs.POLARITY.index:
            self.polarity = value
        elif index == objs.QUICK_STOP_OPTION.index:
            self.control.quick_stop_option = value
        return None

    def apply_controlword(self, controlword: int) -> Transition:
        done = self.control.apply(controlword)
        if done.homing_start:
            node = self.node
            order = HomingOrder(int(node.value(0x6098, 0, 0)), node.value(0x6099, 1, 0),
                                node.value(0x6099, 2, 0), node.value(0x607C, 0, 0))
            self.homing.start(order, self.motor.position, self.sign(0x80), self.motor.velocity)
        elif done.homing_stop:
            self.homing.stop()
        if done.enabled:
            self.target_at_enable = self.target
            if self.control.mode == CYCLIC_SYNC_POSITION:
                self.csp.hold(self.motor.position)
        return done

    def sync(self, now: float) -> None:
        """A SYNC's share in CSP: the segment to the target taken."""
        self.syncs_seen += 1
        if self.control.mode == CYCLIC_SYNC_POSITION and self.control.state == OPERATION_ENABLED:
            self.csp.next_segment(now)

    # ---------------------------------------------------------------- the servo
    def advance(self, now: float) -> bool:
        """The motor up to `now`; True when a CSP following error outlasted its time-out."""
        fault = [False]
        control, csp, motor = self.control, self.csp, self.motor

        def law(dt: float, t: float, v: float) -> tuple[float, float]:
            state, mode = control.state, control.mode
            if state == OPERATION_ENABLED and mode == CYCLIC_SYNC_POSITION:
                # position loop on the interpolated set point, its speed as feed-forward
                setpoint, feed_forward = csp.guide(t)
                if csp.follow(t, motor.position, v, dt, setpoint):
                    fault[0] = True
                return (feed_forward + (setpoint - motor.position)
                        / motor.time_constant, math.inf)
            if state == OPERATION_ENABLED and mode in (PROFILE_VELOCITY, objs.HOMING):
                target = (self.sign(0x40) * self.target if mode == PROFILE_VELOCITY
                          else self.homing.velocity(self.sign(0x40)))
                ramp = objs.PROFILE_ACCELERATION if abs(target) >= abs(v) else \
                    objs.PROFILE_DECELERATION
                return motor.lag(target, dt), self.node.value(ramp.index, 0, math.inf)
            if state in (QUICK_STOP_ACTIVE, FAULT_REACTION_ACTIVE):
                return 0.0, self.node.value(objs.QUICK_STOP_DECELERATION.index, 0, math.inf)
            return motor.coast(dt), math.inf          # power stage off: the load coasts

        def after(before: float, dt: float, t: float) -> None:
            self.mechanism.note_motion(motor.position, t)
            if self.homing.phase is not None and control.state == OPERATION_ENABLED:
                self.homing.step(before, motor.position, motor.velocity)
            self.mechanism.note_bottom(before, motor.position, dt, t)
            if abs(motor.velocity) < 0.5:
                control.stopped()

        motor.advance(now, law, after)
        return fault[0]
