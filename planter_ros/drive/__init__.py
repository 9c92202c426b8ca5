"""CAN drive: the CiA 402 master (cia402) and a simulated drive (simulated_drive). No ROS here."""
