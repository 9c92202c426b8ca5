"""The CiA 402 state names, exactly as canopen spells them (the keys of its `State402.SW_MASK`),
without importing canopen: the sync node's health policy (control.sync_status) compares a drive
status's state with them, and replay and season analysis, which load that policy's module
chain, never touch a bus. drive.states checks them against canopen's.
"""

__all__ = ['NOT_READY', 'SWITCH_ON_DISABLED', 'READY_TO_SWITCH_ON', 'SWITCHED_ON',
           'OPERATION_ENABLED', 'QUICK_STOP_ACTIVE', 'FAULT_REACTION_ACTIVE', 'FAULT', 'STATES']

NOT_READY = 'NOT READY TO SWITCH ON'
SWITCH_ON_DISABLED = 'SWITCH ON DISABLED'
READY_TO_SWITCH_ON = 'READY TO SWITCH ON'
SWITCHED_ON = 'SWITCHED ON'
OPERATION_ENABLED = 'OPERATION ENABLED'
QUICK_STOP_ACTIVE = 'QUICK STOP ACTIVE'
FAULT_REACTION_ACTIVE = 'FAULT REACTION ACTIVE'
FAULT = 'FAULT'
STATES = (NOT_READY, SWITCH_ON_DISABLED, READY_TO_SWITCH_ON, SWITCHED_ON, OPERATION_ENABLED,
          QUICK_STOP_ACTIVE, FAULT_REACTION_ACTIVE, FAULT)
