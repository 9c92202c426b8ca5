"""CiA 402 names and codes used by the master and the simulated drive, in one place.

State names, controlword commands and operation modes are canopen's (`State402`,
`OperationMode`); only what canopen does not define is written here.
"""

from canopen.profiles.p402 import OperationMode, State402

# state names exactly as canopen spells them (keys of State402.SW_MASK), declared canopen-free
from .state_names import (  # noqa: F401 (the master and the simulated drive import them here)
    FAULT, FAULT_REACTION_ACTIVE, NOT_READY, OPERATION_ENABLED, QUICK_STOP_ACTIVE,
    READY_TO_SWITCH_ON, STATES, SWITCH_ON_DISABLED, SWITCHED_ON)
assert set(STATES) == set(State402.SW_MASK), 'canopen renamed a CiA 402 state'

PROFILE_VELOCITY = OperationMode.PROFILED_VELOCITY            # 3
PROFILE_VELOCITY_SUPPORTED = OperationMode.SUPPORTED['PROFILED VELOCITY']   # 0x6502 bit 2
CYCLIC_SYNC_POSITION = OperationMode.CYCLIC_SYNCHRONOUS_POSITION              # 8
CSP_SUPPORTED = OperationMode.SUPPORTED['CYCLIC SYNCHRONOUS POSITION']        # 0x6502 bit 7
MODE_SUPPORTED = {PROFILE_VELOCITY: PROFILE_VELOCITY_SUPPORTED,
                  CYCLIC_SYNC_POSITION: CSP_SUPPORTED}

# the controlword commands and the statusword bits are named once, canopen-free, in
# drive.words; canopen agrees on the commands
from .words import (  # noqa: F401,E402 (re-exported for the master and the simulated drive)
    CW_DISABLE_VOLTAGE, CW_ENABLE_OPERATION, CW_FAULT_RESET, CW_QUICK_STOP, CW_SHUTDOWN,
    CW_SWITCH_ON)
assert (CW_DISABLE_VOLTAGE, CW_QUICK_STOP, CW_SHUTDOWN, CW_SWITCH_ON, CW_ENABLE_OPERATION) == (
    State402.CW_DISABLE_VOLTAGE, State402.CW_QUICK_STOP, State402.CW_SHUTDOWN,
    State402.CW_SWITCH_ON, State402.CW_OPERATION_ENABLED), 'canopen recoded a controlword'

ABORT_OPTION_QUICK_STOP = 3                           # 0x6007: abort connection -> quick stop

# CiA 301 emergency codes the watchdogs raise
EMCY_RPDO_TIMEOUT = 0x8250                            # RPDO deadline missed
EMCY_HEARTBEAT = 0x8130                               # life guard or heartbeat error
EMCY_FOLLOWING_ERROR = 0x8611                         # CiA 402: following error
EMCY_SYNC = 0x8700                                    # CiA 301: SYNC data length / missing


def state_of(statusword: int) -> str:
    """CiA 402 state name of a statusword ('UNKNOWN' if no state matches)."""
    for name, (mask, bits) in State402.SW_MASK.items():
        if statusword & mask == bits:
            return name
    return 'UNKNOWN'
