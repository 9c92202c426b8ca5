"""Recording (MCAP in rosbag2's layout) and offline replay of recordings."""

# the submodules (imported by name, never here: replay needs no recorder, the recorder no numpy)
__all__ = ['bag_reader', 'cdr', 'errors', 'export', 'indexed', 'monitor_topics',
           'recorder', 'recovery', 'replay',
           'replay_text']
