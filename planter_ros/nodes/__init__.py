"""ROS 2 nodes: thin shells that turn parameters and topics into calls of the core."""
