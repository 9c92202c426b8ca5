"""The bits of the CiA 402 statusword (6041h) and controlword (6040h), named once: the master
reads and writes them by these names, the simulated drive sets and decodes them by the same.

canopen-free (the sync node's health policy and the simulator's state machine load it without
a bus). Bit meanings as CiA 402 (IEC 61800-7-201) states them; bits 12 and 13 of the statusword
and 4 to 6 of the controlword mean what the operation mode says (named per mode below).
"""
from __future__ import annotations

from .state_names import (FAULT, FAULT_REACTION_ACTIVE, NOT_READY, OPERATION_ENABLED,
                          QUICK_STOP_ACTIVE, READY_TO_SWITCH_ON, SWITCH_ON_DISABLED, SWITCHED_ON)

__all__ = [
    'SW_READY_TO_SWITCH_ON', 'SW_SWITCHED_ON', 'SW_OPERATION_ENABLED', 'SW_FAULT',
    'SW_VOLTAGE_ENABLED', 'SW_QUICK_STOP', 'SW_SWITCH_ON_DISABLED', 'SW_WARNING', 'SW_REMOTE',
    'SW_TARGET_REACHED', 'SW_INTERNAL_LIMIT', 'SW_SPEED_ZERO', 'SW_FOLLOWS',
    'SW_FOLLOWING_ERROR', 'SW_HOMING_ATTAINED', 'SW_HOMING_ERROR', 'SW_HOMED',
    'CW_SWITCH_ON_BIT', 'CW_ENABLE_VOLTAGE_BIT', 'CW_QUICK_STOP_BIT', 'CW_ENABLE_OPERATION_BIT',
    'CW_HOMING_START', 'CW_FAULT_RESET', 'CW_HALT', 'CW_DISABLE_VOLTAGE', 'CW_QUICK_STOP',
    'CW_SHUTDOWN', 'CW_SWITCH_ON', 'CW_ENABLE_OPERATION', 'STATE_BITS', 'ERROR_REGISTER_GENERIC',
    'ERROR_REGISTER_COMMUNICATION', 'error_register',
]

# statusword 6041h
SW_READY_TO_SWITCH_ON = 1 << 0
SW_SWITCHED_ON = 1 << 1
SW_OPERATION_ENABLED = 1 << 2
SW_FAULT = 1 << 3
SW_VOLTAGE_ENABLED = 1 << 4
SW_QUICK_STOP = 1 << 5                 # 0: a quick stop is active
SW_SWITCH_ON_DISABLED = 1 << 6
SW_WARNING = 1 << 7
SW_REMOTE = 1 << 9                     # the controlword is obeyed
SW_TARGET_REACHED = 1 << 10
SW_INTERNAL_LIMIT = 1 << 11
SW_SPEED_ZERO = 1 << 12                # profile velocity: speed = 0
SW_FOLLOWS = 1 << 12                   # CSP: the drive follows the target
SW_FOLLOWING_ERROR = 1 << 13           # CSP: following error beyond the window
SW_HOMING_ATTAINED = 1 << 12           # homing: homing attained
SW_HOMING_ERROR = 1 << 13              # homing: homing error
SW_HOMED = SW_HOMING_ATTAINED | SW_TARGET_REACHED     # homing finished: both set

# controlword 6040h: the bits
CW_SWITCH_ON_BIT = 1 << 0
CW_ENABLE_VOLTAGE_BIT = 1 << 1
CW_QUICK_STOP_BIT = 1 << 2             # 0: quick stop
CW_ENABLE_OPERATION_BIT = 1 << 3
CW_HOMING_START = 1 << 4               # homing: start on the rising edge, stop when cleared
CW_FAULT_RESET = 1 << 7                # acts on its rising edge
CW_HALT = 1 << 8

# controlword 6040h: the device-control commands (CiA 402 table "command coding")
CW_DISABLE_VOLTAGE = 0x00
CW_QUICK_STOP = CW_ENABLE_VOLTAGE_BIT                                          # 0x02
CW_SHUTDOWN = CW_ENABLE_VOLTAGE_BIT | CW_QUICK_STOP_BIT                        # 0x06
CW_SWITCH_ON = CW_SHUTDOWN | CW_SWITCH_ON_BIT                                  # 0x07
CW_ENABLE_OPERATION = CW_SWITCH_ON | CW_ENABLE_OPERATION_BIT                   # 0x0F

# the statusword's state bits in each state (the simulated drive reports them; the master
# decodes a statusword with canopen's State402 masks, which agree: test_drive_objects)
STATE_BITS = {
    NOT_READY: 0,
    SWITCH_ON_DISABLED: SW_SWITCH_ON_DISABLED,
    READY_TO_SWITCH_ON: SW_READY_TO_SWITCH_ON | SW_VOLTAGE_ENABLED | SW_QUICK_STOP,
    SWITCHED_ON: SW_READY_TO_SWITCH_ON | SW_SWITCHED_ON | SW_VOLTAGE_ENABLED | SW_QUICK_STOP,
    OPERATION_ENABLED: (SW_READY_TO_SWITCH_ON | SW_SWITCHED_ON | SW_OPERATION_ENABLED
                        | SW_VOLTAGE_ENABLED | SW_QUICK_STOP),
    QUICK_STOP_ACTIVE: (SW_READY_TO_SWITCH_ON | SW_SWITCHED_ON | SW_OPERATION_ENABLED
                        | SW_VOLTAGE_ENABLED),
    FAULT_REACTION_ACTIVE: (SW_READY_TO_SWITCH_ON | SW_SWITCHED_ON | SW_OPERATION_ENABLED
                            | SW_FAULT | SW_VOLTAGE_ENABLED),
    FAULT: SW_FAULT,
}

# error register 1001h (CiA 301): bit 0 is set whenever any other error bit is
ERROR_REGISTER_GENERIC = 1 << 0
ERROR_REGISTER_COMMUNICATION = 1 << 4


def error_register(*bits: int) -> int:
    """The error register 1001h with `bits` set: the generic bit 0 with any of them."""
    value = 0
    for bit in bits:
        value |= bit
    return value | ERROR_REGISTER_GENERIC if value else 0
