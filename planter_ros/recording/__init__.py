"""Recording (MCAP in rosbag2's layout) and offline replay of recordings."""
