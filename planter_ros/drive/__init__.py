"""CAN drive, no ROS: the one CiA 402 master (`cia402`), its settings (`config`), the CANopen
objects and PDO layouts (`objects`), its exception family (`errors`), the CiA 402 names and
codes (`states`) and a simulated drive (`simulated_drive`) for tests and the demo."""

__all__ = ['bus_load', 'cia402', 'config', 'drive_set', 'eds', 'errors', 'objects',
           'simulated_drive', 'state_names', 'states']
