"""The simulated field of the demo: a ground-speed sensor and an observer of the mechanism.

GroundSpeedSource publishes TwistStamped along a field profile (t -> true speed, m/s) with
Gaussian noise and, at given times, the glitches real wheel/radar sensors produce (a spike, a
NaN) that the sync node must reject. The profile's exact travelled distance is the reference
for the demo's spacing figures; Observer collects the measured mechanism angle to compare.
"""


import math

import numpy as np
from rclpy.node import Node
from rclpy.time import Time
from geometry_msgs.msg import TwistStamped

from planter_ros import interfaces

from .spacing import plant_positions


class GroundSpeedSource(Node):
    """Publishes `ground_speed` at `rate` Hz from `profile(t)` (t in s since start)."""

    def __init__(self, profile, rate=20.0, noise=0.005, glitches=(), seed=0, **kwargs):
        super().__init__('ground_speed_source', **kwargs)
        self.profile = profile
        self.noise = noise
        self.glitches = sorted(glitches)      # (t, value) published instead of the reading
        self._rng = np.random.default_rng(seed)
        self._pub = interfaces.GROUND_SPEED.publisher(self)
        self.start = self.get_clock().now()
        self.samples = 0
        self.create_timer(1.0 / rate, self._tick)

    def elapsed(self, now=None):
        return ((now or self.get_clock().now()) - self.start).nanoseconds * 1e-9

    def _tick(self):
        now = self.get_clock().now()
        t = self.elapsed(now)
        v = self.profile(t)
        reading = v + self._rng.normal(0.0, self.noise) if v > 0.0 else 0.0
        if self.glitches and t >= self.glitches[0][0]:
            reading = self.glitches.pop(0)[1]
        msg = TwistStamped()
        msg.header.stamp = now.to_msg()
        msg.header.frame_id = 'base_link'
        msg.twist.linear.x = float(reading)
        self._pub.publish(msg)
        self.samples += 1


class Observer(Node):
    """Collects joint_states (measured) and speed_command for the demo's summary."""

    def __init__(self, **kwargs):
        super().__init__('demo_observer', **kwargs)
        self.start = None            # rclpy Time the field run started
        self.joint = []              # (t since start, angle rad, velocity rad/s)
        self.command = []            # (t since start, rad/s)
        interfaces.JOINT_STATES.subscribe(self, self._on_joint)
        interfaces.SPEED_COMMAND.subscribe(self, self._on_command)

    def _since_start(self, time):
        return (time - self.start).nanoseconds * 1e-9

    def _on_joint(self, msg):
        if self.start is not None and msg.position:
            self.joint.append((self._since_start(Time.from_msg(msg.header.stamp)),
                               msg.position[0], msg.velocity[0] if msg.velocity else math.nan))

    def _on_command(self, msg):
        if self.start is not None:
            self.command.append((self._since_start(self.get_clock().now()), msg.data))

    def window(self, what, a, b):
        """Commanded ('command') or measured ('velocity') speeds between a and b s."""
        rows, col = (self.command, 1) if what == 'command' else (self.joint, 2)
        return np.array([r[col] for r in list(rows) if a <= r[0] <= b])

    def plant_positions(self, profile, design):
        """True travelled distance (m) at each plant release seen in the measured angle."""
        rows = [r for r in list(self.joint) if r[0] >= 0.0]
        if len(rows) < 2:
            return np.empty(0)
        t, angle, _ = (np.array(c) for c in zip(*rows))
        pitch = 2 * math.pi / design['plants_per_revolution']
        # the arm starts at the top and releases half a pitch later (five-bar: the bottom)
        return plant_positions(angle, profile.distance(t), pitch, release=angle[0] + 0.5 * pitch)
