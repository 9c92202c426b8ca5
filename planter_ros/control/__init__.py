"""Pure control laws (no ROS, no CAN): the sync node translates topics and drive feedback into
calls of these, so they are tested and simulated without either."""

# the submodules (imported by name, never here)
__all__ = ['loop_timing', 'machine', 'phase_lock', 'sync_status']
