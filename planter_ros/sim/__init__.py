"""Simulation: the machine without a field. `closed_loop` runs the sync law against a drive
model; `field` holds ground-speed profiles; `runs` turns them into measured streams; `bags`
writes those as recordings; `lockstep` feeds them to real nodes on a simulated clock;
`ros_field` is the demo's ground-speed sensor and observer nodes. Never imports
planter_ros.nodes: callers hand in the nodes to feed."""

# the submodules (imported by name, never here)
__all__ = ['bags', 'closed_loop', 'field', 'gnss', 'lockstep', 'options', 'ros_field', 'runs',
           'season', 'spacing']
