"""ground_speed_node: the tractor's sensors -> `ground_speed` (TwistStamped), a thin shell over
sensing.ground_speed_sources.

Sources, in the order of preference of its `sources` parameter: the tractor's ISOBUS speed
messages on a second CAN channel (`isobus_channel`, read by a python-can Notifier thread),
the GNSS velocity (`gnss/vel`) and a wheel or radar pulse counter (`wheel_pulses`). The first
source heard from within `source_timeout` is published; when it goes quiet the next one takes
over at its next sample, and the switch is logged and shown in /diagnostics (status
`ground_speed_node: ground speed source`: the source in use, the last switches). The yaw rate
(twist.angular.z) comes from the GNSS course or an IMU (`imu/data`), or is 0. A reading below
`standstill_speed` is published as 0 until it reaches twice that (standstill is standstill:
sensing.ground_speed_sources.Standstill).
"""

import functools
import math
import sys
import threading
import time

from geometry_msgs.msg import TwistStamped
from rclpy.node import Node
from std_msgs.msg import UInt32

from planter_ros import diagnostics, interfaces
from planter_ros.nodes.parameters import ParameterGroup, refuse_undeclared
from planter_ros.nodes.run import run_node
from planter_ros.sensing.ground_speed_sources import (
    CourseYawRate, GroundSpeedSourceConfig, IsobusSpeedDecoder, PulseSpeed, SourceSelector,
    Standstill, gnss_speed, imu_yaw_rate)

NAME = 'ground_speed_node'
TASK = 'ground speed source'
DIAGNOSTICS_PERIOD = 1.0


class GroundSpeedNode(Node):
    """Publishes the preferred live ground-speed source; see the module doc."""

    def __init__(self, arguments=None, bus=None, **kwargs):
        """`bus`: an open python-can bus for ISOBUS (tests); else `isobus_channel` is opened."""
        super().__init__(NAME, **kwargs)
        self.config = ParameterGroup(self, GroundSpeedSourceConfig).value
        refuse_undeclared(self, arguments)
        cfg = self.config
        self._lock = threading.Lock()
        self.selector = SourceSelector(cfg.sources, cfg.source_timeout)
        self.standstill = Standstill(cfg.standstill_speed)
        self.course = CourseYawRate(cfg.min_course_speed)
        self.yaw_rate = 0.0
        self.published = 0
        self._reported_events = 0
        self._publisher = interfaces.GROUND_SPEED.publisher(self)
        self._diagnostics = interfaces.DIAGNOSTICS.publisher(self)
        interfaces.GNSS_VELOCITY.subscribe(self, self._on_gnss)
        if cfg.yaw_rate_source == 'imu':
            interfaces.IMU.subscribe(self, self._on_imu)
        self.pulses = None
        if 'pulses' in cfg.sources:
            self.pulses = pulses = PulseSpeed(cfg.pulses_per_metre)
            interfaces.WHEEL_PULSES.subscribe(self, functools.partial(self._on_pulses, pulses))
        self._bus, self._own_bus, self._notifier = bus, False, None
        if any(s.startswith('isobus') for s in cfg.sources) and (bus or cfg.isobus_channel):
            self._open_isobus()
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)

    # ------------------------------------------------------------------ sources
    def _open_isobus(self):
        import can  # lazy: python-can (0.15 s) only for an ISOBUS speed source
        self.decoder = IsobusSpeedDecoder()
        if self._bus is None:
            self._bus = can.Bus(interface=self.config.isobus_interface,
                                channel=self.config.isobus_channel)
            self._own_bus = True
        self._notifier = can.Notifier(self._bus, [self._on_frame], timeout=0.1)

    def _now(self):
        return time.monotonic()

    def _on_frame(self, frame):
        """python-can's Notifier thread: one ISOBUS frame (never raises: it would kill it)."""
        try:
            sample = self.decoder.decode(self._now(), frame.arbitration_id, frame.data,
                                         frame.is_extended_id)
            if sample is not None:
                self._offer(sample)
        except Exception as exc:              # a malformed frame must not stop the reader
            self.get_logger().warning(f'ISOBUS frame not decoded: {exc}')

    def _on_gnss(self, msg):
        twist = msg.twist.twist if hasattr(msg.twist, 'twist') else msg.twist
        now = self._now()
        east, north = twist.linear.x, twist.linear.y
        if self.config.yaw_rate_source == 'gnss':
            rate = self.course.update(now, east, north)
            with self._lock:
                self.yaw_rate = 0.0 if rate is None else rate
        sample = gnss_speed(now, east, north)
        if sample is not None:
            self._offer(sample)

    def _on_imu(self, msg):
        rate = imu_yaw_rate(msg.angular_velocity.z, msg.angular_velocity_covariance[0])
        with self._lock:
            self.yaw_rate = 0.0 if math.isnan(rate) else rate

    def _on_pulses(self, pulses: PulseSpeed, msg: UInt32) -> None:
        sample = pulses.update(self._now(), msg.data)
        if sample is not None:
            self._offer(sample)

    def _offer(self, sample):
        with self._lock:
            chosen = self.selector.offer(self.standstill.apply(sample))
            events = self.selector.events[self._reported_events:]
            self._reported_events = len(self.selector.events)
            yaw = self.yaw_rate
        for _, text in events:
            self.get_logger().warning(f'ground speed: {text}')
        if chosen is None:
            return
        msg = TwistStamped()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = chosen.source
        msg.twist.linear.x = float(chosen.speed)
        msg.twist.angular.z = float(yaw)
        self._publisher.publish(msg)
        self.published += 1

    # -------------------------------------------------------------- diagnostics
    def report(self):
        with self._lock:
            active = self.selector.choose(self._now())
            events = list(self.selector.events[-3:])
            heard = dict(self.selector.last_heard)
        now = self._now()
        preferred = self.selector.preference[0]
        if active is None:
            level, message = diagnostics.ERROR, 'no ground-speed source'
        elif active != preferred:
            level, message = diagnostics.WARN, f'{active} (fallback: {preferred} silent)'
        else:
            level, message = diagnostics.OK, active
        values = [('source', active or 'none'),
                  ('preference', ', '.join(self.selector.preference)),
                  ('published', self.published)]
        values += [(f'{s} age', f'{now - t:.2f} s') for s, t in heard.items()]
        values += [(f'switch {i + 1}', text) for i, (_, text) in enumerate(events)]
        return diagnostics.Report(TASK, level, message, tuple(values))

    def _publish_diagnostics(self):
        hardware = self.config.isobus_channel or 'gnss'
        self._diagnostics.publish(diagnostics.array([(self.report(), hardware)], NAME,
                                                    self.get_clock().now().to_msg()))

    def destroy_node(self):
        if self._notifier is not None:
            self._notifier.stop()
        if self._own_bus and self._bus is not None:
            self._bus.shutdown()
        return super().destroy_node()


def main(args=None):
    return run_node(NAME, lambda arguments: GroundSpeedNode(
        namespace=interfaces.NAMESPACE, arguments=arguments), args, errors=(OSError,))


if __name__ == '__main__':
    sys.exit(main())
