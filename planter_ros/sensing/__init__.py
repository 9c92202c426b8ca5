"""What the machine measures and which measurements to believe; below both the control law and
the plant prediction model, which must judge a sample the same way. Pure Python, no ROS."""

# the submodules (imported by name, never here)
__all__ = ['ground_speed_filter', 'plant_map', 'row_speed']
