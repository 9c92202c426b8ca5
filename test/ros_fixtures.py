"""rclpy fixtures for plain pytest: a fresh Context per test and an executor spun in the test."""
import itertools
import os
import time

import pytest

_channels = itertools.count()


def unique_channel(prefix='t'):
    """A python-can virtual channel no other test uses (channels are process-wide)."""
    return f'{prefix}{os.getpid()}_{next(_channels)}'


class Ros:
    """One rclpy context with its executor; nodes added here are destroyed at teardown."""

    def __init__(self):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        self.context = Context()
        rclpy.init(context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.nodes = []

    def add(self, node):
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def node(self, name):
        from rclpy.node import Node
        return self.add(Node(name, context=self.context))

    def spin_until(self, predicate, timeout=3.0):
        """Spin until predicate() is true; returns its final value (False on timeout)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.01)
        return bool(predicate())

    def spin_for(self, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.01)

    def close(self):
        for node in reversed(self.nodes):
            self.executor.remove_node(node)
            node.destroy_node()
        self.executor.shutdown()
        self.context.try_shutdown()


@pytest.fixture
def ros():
    r = Ros()
    try:
        yield r
    finally:
        r.close()
