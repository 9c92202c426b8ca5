"""What the machine measures and which measurements to believe; below both the control law and
the plant prediction model, which must judge a sample the same way. Pure Python, no ROS."""
