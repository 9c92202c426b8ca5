"""Feed a simulated run to real nodes on a simulated clock, in lock-step.

The feeder publishes /clock and the run's messages (interfaces topics) one at a time and spins
the executor until the receiving node has taken each one, so nothing is dropped and the nodes'
receive times are the simulated ones (use_sim_time). A 30 s run goes through in a few seconds.
The nodes fed are the caller's (this package never imports planter_ros.nodes): `taken()` counts
the samples the receiver has taken, `has_design()` tells it has the design.
"""

from __future__ import annotations

from collections.abc import Callable
import time
from typing import TYPE_CHECKING

from builtin_interfaces.msg import Time
import rclpy
from rosgraph_msgs.msg import Clock as ClockMessage

from planter_ros import interfaces

if TYPE_CHECKING:
    from rclpy.clock import Clock
    from rclpy.context import Context
    from rclpy.executors import Executor

    from .runs import Run

# reliable, deep: lock-step feeding must never lose a sample (a best-effort subscriber of the
# contract's QoS still matches a reliable publisher)
FEED_QOS = interfaces.Qos('reliable', 'volatile', interfaces.RECORDING_DEPTH)


class LockStepFeeder:
    """Publishes a Run into `executor`'s graph; see the module doc."""

    def __init__(self, context: Context, executor: Executor, taken: Callable[[], int],
                 has_design: Callable[[], bool], timeout: float = 60.0) -> None:
        self.executor = executor
        self.taken = taken
        self.has_design = has_design
        self.deadline = time.monotonic() + timeout
        self.node = rclpy.create_node('sample_feeder', namespace=interfaces.NAMESPACE,
                                      context=context)
        executor.add_node(self.node)
        self._clock = interfaces.CLOCK.publisher(self.node)
        self._pubs = {topic: topic.publisher(self.node, qos=topic.qos if topic is
                                             interfaces.DESIGN else FEED_QOS)
                      for topic in (interfaces.DESIGN, interfaces.GROUND_SPEED,
                                    interfaces.JOINT_STATES, interfaces.SPEED_COMMAND)}
        self._now: int | None = None           # the simulated time last published (ns)

    def spin_until(self, condition: Callable[[], bool]) -> None:
        while not condition():
            if time.monotonic() > self.deadline:
                raise TimeoutError('the nodes did not take the sample stream in time')
            self.executor.spin_once(timeout_sec=0.01)

    def set_clock(self, stamp: int, clock_of: Callable[[], Clock]) -> None:
        """Publish simulated time `stamp` (ns) and wait until `clock_of()` reads it."""
        sec, nsec = divmod(stamp, 1_000_000_000)
        self._clock.publish(ClockMessage(clock=Time(sec=sec, nanosec=nsec)))
        self.spin_until(lambda: clock_of().now().nanoseconds == stamp)

    def feed(self, run: Run, clock_of: Callable[[], Clock]) -> None:
        """Publish every message of `run` (sim.runs.Run) in lock-step; `clock_of()` is the
        receiving node's clock."""
        pubs = list(self._pubs.values()) + [self._clock]
        self.spin_until(lambda: all(p.get_subscription_count() > 0 for p in pubs))
        for stamp, topic, msg in run.messages():
            if stamp != self._now:
                self.set_clock(stamp, clock_of)
                self._now = stamp
            before = self.taken()
            self._pubs[topic].publish(msg)
            if topic is interfaces.DESIGN:
                self.spin_until(self.has_design)
            else:
                self.spin_until(self._taken_beyond(before))

    def _taken_beyond(self, count: int) -> Callable[[], bool]:
        """Has the receiver taken more than `count` samples?"""
        return lambda: self.taken() > count

    def destroy(self) -> None:
        self.executor.remove_node(self.node)
        self.node.destroy_node()
