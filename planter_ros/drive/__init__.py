"""CAN drive, no ROS: the one CiA 402 master (`cia402`, made of `bus`, `feedback`,
`supervision`, `rpdo`, `startup` and `sdo`), the start-up plan made from a drive's EDS (`plan`,
`dictionary`), its settings (`config`), the CANopen objects and PDO layouts (`objects`), its
exception family (`errors`), the CiA 402 names, codes and bits (`states`, `state_names`,
`words`), a machine's drives on one bus (`drive_set`), the bus load (`bus_load`) and a CAN bus
over a socket pair (`socket_bus`). The simulated drives live in `planter_ros.simdrive`."""

__all__ = ['bus', 'bus_load', 'cia402', 'config', 'dictionary', 'drive_set', 'eds', 'errors',
           'feedback', 'objects', 'plan', 'rpdo', 'sdo', 'setup', 'socket_bus', 'startup',
           'state_names', 'states', 'supervision', 'words']
