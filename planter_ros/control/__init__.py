"""Pure control laws (no ROS, no CAN): the sync node translates topics and drive feedback into
calls of these, so they are tested and simulated without either."""
