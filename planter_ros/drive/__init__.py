"""CAN drive, no ROS: the one CiA 402 master (`cia402`), its settings (`config`), the CANopen
objects and PDO layouts (`objects`), its exception family (`errors`), the CiA 402 names and
codes (`states`), a simulated drive (`simulated_drive`) for tests and the demo, and the
drives' own process (`sim_process`) on a CAN bus over a socket pair (`socket_bus`)."""

__all__ = ['bus_load', 'cia402', 'config', 'drive_set', 'eds', 'errors', 'objects',
           'sim_process', 'simulated_drive', 'socket_bus', 'state_names', 'states']
