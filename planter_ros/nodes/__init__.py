"""ROS 2 nodes: thin shells that turn parameters, topics and CAN into calls of the core."""
