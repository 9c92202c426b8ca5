"""CAN drive, no ROS: the one CiA 402 master (`cia402`), its settings (`config`), its exception
family (`errors`), the CiA 402 names and codes (`states`) and a simulated drive
(`simulated_drive`) for tests and the demo."""

# the submodules (imported by name, never here)
__all__ = ['bus_load', 'cia402', 'config', 'drive_set', 'eds', 'errors', 'simulated_drive',
           'state_names', 'states']
