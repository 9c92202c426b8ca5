"""Pure control laws (no ROS, no CAN): the sync node and the command process translate topics and
drive feedback into calls of these, so they are tested and simulated without either.
`row_loop.RowLoop.step` is the whole machine's step: every row's command and status."""

__all__ = ['cam_law', 'loop_timing', 'machine_law', 'odometer', 'phase_lock', 'row_loop',
           'sync_status']
