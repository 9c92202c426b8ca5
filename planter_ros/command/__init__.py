"""The command process: the CAN bus, the CiA 402 masters, the heartbeats, the watchdogs and the
row loop in a process of their own, with no DDS participant and no rclpy (doc/command.md).

`engine` is the command path as one object (also run in-process by sync_node when handed a
bus); `process` the process's main loop; `client` the shell's handle (start, feed, supervise);
`channel` the local message channel between them; `socket_bus` a python-can bus over a socket
pair (the simulated drives in a process of their own); `realtime` SCHED_FIFO, mlockall and
dying with the parent; `settings` what the shell hands over at start."""

__all__ = ['channel', 'client', 'engine', 'process', 'realtime', 'settings', 'socket_bus']
