"""ROS 2 nodes: thin shells that translate parameters, topics and CAN into calls of the core."""
