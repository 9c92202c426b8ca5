"""Simulated CiA 402 drives, for tests, the demo and `planter drive check --simulated`: kept out
of `drive/`, which holds the real master. A strict CiA 301 / CiA 402 device on a python-can bus
that takes any EDS as its object dictionary (`node`), with its state machine (`control`), motor
and mechanism (`motor`, `csp`, `homing`, `mechanism`), PDO timing (`pdo`), watchdogs
(`watchdog`), injected faults (`faults`); several on one bus (`bus`), in a process of their own
(`process`); and `fault_bus`, a python-can bus with the faults a real bus has."""

__all__ = ['bus', 'clock', 'control', 'csp', 'drive', 'fault_bus', 'faults', 'homing', 'mechanism',
           'motor', 'node', 'pdo', 'process', 'spec', 'watchdog']
