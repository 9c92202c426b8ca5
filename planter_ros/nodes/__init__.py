"""ROS 2 nodes: thin shells that turn parameters, topics and CAN into calls of the core."""

# the submodules (imported by name, never here)
__all__ = ['design_node', 'graph', 'markers', 'monitor_node', 'parameters', 'sync_node']
