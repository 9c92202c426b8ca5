"""The command process: the CAN bus, the CiA 402 masters, the heartbeats, the watchdogs and the
row loop in a process of their own, with no DDS participant and no rclpy (doc/command.md).

`engine` is the command path as one object (also run in-process by sync_node when handed a
bus), split by the state each part owns: `state` (what they share, per row `RowUnit`),
`lifecycle`, `design_change`, `control_step`, `watch` (with `recovery`'s per-row counts) and
`status`; `reports` the typed messages it sends; `process` the process's main loop; `client`
the shell's handle (start, feed, supervise), with `inbox` (what the process said) and `orders`
(the design and sections it is told again after a restart); `channel` the local message
channel between them; `settings` what the shell hands over at start (SCHED_FIFO, mlockall
and dying with the parent: `planter_ros.host.realtime`). The CAN bus to simulated drives in a
process of their own is `planter_ros.drive.socket_bus`."""

__all__ = ['channel', 'client', 'control_step', 'design_change', 'engine', 'inbox', 'lifecycle',
           'orders', 'process', 'recovery', 'reports', 'settings', 'state', 'status',
           'watch']
