"""sync_node: ground speed -> phase-locked mechanism speed -> CiA 402 drive over CAN.

The control law is the pure `PhaseLock`; this node only moves data: ground-speed samples and
drive feedback in, one velocity RPDO out. The frame is sent inside the ground-speed callback
(the latency that matters is sample -> frame); a control timer sends the master heartbeat,
keeps commanding while samples are missing (stale -> ramp to 0 -> halt) and publishes
joint_states. The blocking enable runs once at start-up, never in a callback. A drive fault
(statusword bit 3 or EMCY) commands 0 and waits for an explicit `reset_fault` call.
"""

from dataclasses import dataclass
import json
import logging
import math
import sys
import threading
import time

import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from planter_ros import interfaces
from planter_ros.config import ConfigError, check, setting
from planter_ros.control import sync_status
from planter_ros.control.phase_lock import PhaseLock, PhaseLockConfig
from planter_ros.drive.cia402 import Cia402Drive
from planter_ros.drive.config import DriveConfig
from planter_ros.drive.errors import DriveError
from planter_ros.drive.states import FAULT
from planter_ros.nodes.parameters import ParameterGroup
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits


@dataclass(frozen=True)
class SyncLoopConfig:
    """The node's own timing (fixed at start-up)."""

    control_period: float = setting(0.02, 'control loop period: heartbeat, stale handling, '
                                    'joint_states', unit='s', range=(0.002, 0.1), read_only=True)
    diagnostics_period: float = setting(1.0, '/diagnostics period', unit='s', range=(0.1, 10.0),
                                        read_only=True)

    def __post_init__(self):
        check(self)


class SyncNode(Node):
    """Keeps the planting mechanism in step with the ground through a CiA 402 drive."""

    def __init__(self, bus=None, **kwargs):
        super().__init__('sync_node', **kwargs)
        self.drive_config = ParameterGroup(self, DriveConfig).value
        loop = ParameterGroup(self, SyncLoopConfig).value
        law = ParameterGroup(self, (PhaseLockConfig, GroundSpeedLimits),
                             on_change=self._on_law_parameters)
        cfg = self.drive_config
        self.hardware_id = f'{cfg.can_interface}:{cfg.can_channel} node {cfg.drive_node_id}'
        self.law = PhaseLock(*law.value)
        self.drive = Cia402Drive(cfg, bus=bus)
        self._lock = threading.Lock()
        self._enabled = False
        self._shut_down = False
        self._joint = None
        self._status = None
        self._halt = sync_status.NEVER_ENABLED
        self.command_value = 0.0
        self.send_errors = 0
        self._last_send_error = None        # (monotonic time, message)
        self._last_heartbeat = -math.inf

        group = MutuallyExclusiveCallbackGroup()    # one control thread of execution
        self._joint_pub = interfaces.JOINT_STATES.publisher(self)
        self._cmd_pub = interfaces.SPEED_COMMAND.publisher(self)
        self._diag_pub = interfaces.DIAGNOSTICS.publisher(self)
        interfaces.GROUND_SPEED.subscribe(self, self._on_ground_speed, callback_group=group)
        interfaces.DESIGN.subscribe(self, self._on_design, callback_group=group)
        self.create_service(interfaces.RESET_FAULT.srv_class(), interfaces.RESET_FAULT.name,
                            self._on_reset_fault, callback_group=group)
        self.create_timer(loop.control_period, self._on_control, callback_group=group)
        self.create_timer(loop.diagnostics_period, self._on_diagnostics, callback_group=group)

    # ---------------------------------------------------------------- life cycle
    def enable_drive(self):
        """BLOCKING: configure and enable the drive (start-up only, never from a callback)."""
        self.drive.connect_and_enable()
        with self._lock:
            self._enabled = True
            self._halt = None
        self.get_logger().info(f'drive {self.hardware_id} enabled (profile velocity)')

    def shutdown_drive(self):
        """BLOCKING, idempotent: 0x60FF = 0, disable, NMT pre-operational."""
        with self._lock:
            if self._shut_down:
                return
            self._shut_down = True
            was_enabled, self._enabled = self._enabled, False
        try:
            self.drive.shutdown()
            if was_enabled:
                self.get_logger().info('drive shut down (target 0, disabled, pre-operational)')
        except DriveError as exc:
            self.get_logger().error(f'drive shutdown: {exc}')

    def destroy_node(self):
        self.shutdown_drive()
        return super().destroy_node()

    # ---------------------------------------------------------------- callbacks
    def _on_ground_speed(self, msg):
        now = time.monotonic()
        with self._lock:
            self.law.ground_speed(msg.twist.linear.x, now)
            self._step(now)

    def _on_control(self):
        now = time.monotonic()
        with self._lock:
            self._step(now)
            status, joint = self._status, self._joint
        if status is not None and joint is not None and sync_status.has_feedback(status):
            # stamped when the drive measured it, not when we got round to publishing
            age = min(max(time.monotonic() - status.stamp, 0.0), 1.0)
            msg = JointState(name=[joint], position=[status.position],
                             velocity=[status.velocity])
            msg.header.stamp = (self.get_clock().now() - Duration(seconds=age)).to_msg()
            self._joint_pub.publish(msg)

    def _on_design(self, msg):
        try:
            design = json.loads(msg.data)
            spacing = float(design['plant_spacing'])
            n = int(design['plants_per_revolution'])
            joint = interfaces.MECHANISM_JOINT[design['mechanism']]
            with self._lock:
                if (spacing, n) != (self.law.spacing, self.law.plants_per_revolution):
                    self.law.set_design(spacing, n, time.monotonic())
                self._joint = joint
        except (ValueError, KeyError, TypeError, ConfigError) as exc:
            self.get_logger().error(f'design ignored, keeping the last one: {exc}')
            return
        self.get_logger().info(f"design: {design['mechanism']}, d = {spacing} m, "
                               f'{n} plant(s) per revolution')

    def _on_reset_fault(self, _request, response):
        with self._lock:
            status = self.drive.status()
            if not status.fault and status.state != FAULT:
                response.success = False
                response.message = f'no drive fault to reset (state {status.state})'
                return response
            self.drive.request_fault_reset()
            response.success = True
            response.message = (f'fault reset requested (error 0x{status.error_code:04X}); the '
                                'drive re-enables if the cause is gone')
        self.get_logger().warning(response.message)
        return response

    def _on_law_parameters(self, value):
        with self._lock:
            self.law.configure(*value)

    # ---------------------------------------------------------------- the control step
    def _step(self, now):
        """One command: feedback in, law (or 0 when halted), one RPDO out. Caller holds lock."""
        if not self._enabled:
            return
        if now - self._last_heartbeat >= self.drive_config.heartbeat_period:
            self._last_heartbeat = now          # due: from whichever path runs first
            try:
                self.drive.send_heartbeat()
            except DriveError as exc:
                self._send_failed(now, exc)
        status = self.drive.status()
        self._status = status
        if sync_status.has_feedback(status):
            self.law.feedback(status.position, status.velocity, status.stamp)
        halt = sync_status.halt_reason(status, self.drive_config.drive_heartbeat_timeout)
        if halt != self._halt:
            self._report_halt(halt, status)
            self._halt = halt
        if halt is None:
            command = self.law.command(now)
        else:
            command = 0.0
            self.law.halt(now)
        try:
            self.drive.send_velocity(command)
        except DriveError as exc:
            self._send_failed(now, exc)
        self.command_value = command
        self._cmd_pub.publish(Float64(data=command))

    def _report_halt(self, halt, status):
        log = self.get_logger()
        if halt is None:
            log.info('drive back in operation: resuming')
        elif halt.kind == sync_status.FAULTED:
            log.error(f'{halt.text} (state {status.state}): commanding 0; call the reset_fault '
                      'service once the cause is cleared')
        else:
            log.warning(f'{halt.text}: commanding 0')

    def _send_failed(self, now, exc):
        self.send_errors += 1
        first = self._last_send_error is None or \
            now - self._last_send_error[0] > sync_status.SEND_ERROR_HOLD
        self._last_send_error = (now, str(exc))
        if first:
            self.get_logger().error(f'CAN send failed: {exc}')

    # ---------------------------------------------------------------- diagnostics
    def _on_diagnostics(self):
        msg = DiagnosticArray(status=self.diagnostics())
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(msg)

    def diagnostics(self):
        """The DiagnosticStatus list the next /diagnostics message carries."""
        now = time.monotonic()
        with self._lock:
            reports = [
                sync_status.drive_report(self._status, self._enabled, self._shut_down,
                                         self._halt, self.send_errors, self._last_send_error,
                                         self.command_value, now),
                sync_status.ground_report(self.law, now),
                sync_status.phase_report(self.law, now, self.command_value)]
        return [DiagnosticStatus(level=bytes((r.level,)), name=f'{self.get_name()}: {r.task}',
                                 message=r.message, hardware_id=self.hardware_id,
                                 values=[KeyValue(key=k, value=str(v)) for k, v in r.values])
                for r in reports]


class LibraryLog(logging.Handler):
    """python-can and canopen (and our drive master) log through `logging`; with no handler
    Python prints their warnings raw on stderr, e.g. canopen's SDO abort just before our own
    error. Until the drive is enabled their records are held (a failed start is said in our
    one line, which names the cause); from then on they go to the node's ROS log."""

    LOGGERS = ('can', 'canopen', 'planter_ros.drive')

    def __init__(self):
        super().__init__(logging.WARNING)
        self.held = []
        self.node = None
        self._saved = []
        for name in self.LOGGERS:
            logger = logging.getLogger(name)
            self._saved.append((logger, logger.propagate))
            logger.addHandler(self)
            logger.propagate = False

    def emit(self, record):
        text = f'{record.name}: {record.getMessage()}'
        if self.node is None:
            self.held.append(text)
        else:
            self.node.get_logger().warning(text)

    def close(self):
        for logger, propagate in self._saved:
            logger.removeHandler(self)
            logger.propagate = propagate
        super().close()


def start_error(exc, config):
    """Our one line for a failed start: the cause, the bus and drive it was tried on, and the
    parameters that choose them."""
    text = f'sync_node: error: {str(exc).splitlines()[0]}'
    if config is None or not isinstance(exc, DriveError):
        return text
    return (f'{text} [tried can_interface={config.can_interface}, can_channel='
            f'{config.can_channel}, drive_node_id={config.drive_node_id}; choose them with '
            '--ros-args -p can_interface:=<socketcan|virtual|...> -p can_channel:=<can0|...> '
            '-p drive_node_id:=<1..127>]')


def main(args=None):
    rclpy.init(args=args)
    library_log = LibraryLog()
    node = None
    error = None
    try:
        node = SyncNode(namespace=interfaces.NAMESPACE)
        node.enable_drive()
        library_log.node = node
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (DriveError, ConfigError, ParameterException) as exc:
        error = start_error(exc, node.drive_config if node is not None else None)
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        library_log.close()
    if error is not None:            # last, after the shutdown: nothing follows our line
        print(error, file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
