"""sync_node: ground speed -> phase-locked mechanism speed -> CiA 402 drive over CAN.

The control law is the pure `PhaseLock`; this node only moves data: ground-speed samples and
drive feedback in, one velocity RPDO out. The frame is sent inside the ground-speed callback
(the latency that matters is sample -> frame); a control timer sends the master heartbeat,
keeps commanding while samples are missing (stale -> ramp to 0 -> halt) and publishes
joint_states. The blocking enable runs once at start-up, never in a callback. A drive fault
(statusword bit 3 or EMCY) commands 0 and waits for an explicit `reset_fault` call.
"""

import json
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
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import TwistStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, String
from std_srvs.srv import Trigger

from planter_ros import interfaces
from planter_ros.control.phase_lock import ControlConfigError, PhaseLock, PhaseLockConfig
from planter_ros.drive.cia402 import Cia402Drive, DriveConfig, DriveError
from planter_ros.nodes.qos import DESIGN_QOS, DIAGNOSTICS_QOS, GROUND_SPEED_QOS, STATE_QOS

OPERATION_ENABLED = 'OPERATION ENABLED'
SEND_ERROR_HOLD = 2.0      # s a CAN send error keeps the drive status at ERROR


def _f(lo, hi):
    return {'floating_point_range': [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]}


def _i(lo, hi):
    return {'integer_range': [IntegerRange(from_value=lo, to_value=hi, step=1)]}


# name -> (default, description, range kwargs); fixed at start-up (read-only)
DRIVE_PARAMETERS = {
    'can_interface': ('virtual', "python-can interface: 'socketcan' on a machine, 'virtual' "
                      'in tests and the demo', {}),
    'can_channel': ('planter0', "CAN channel: 'can0' on a machine", {}),
    'can_bitrate': (500_000, 'CAN bit rate (bit/s)', _i(10_000, 1_000_000)),
    'drive_node_id': (1, 'CANopen node id of the servo drive', _i(1, 127)),
    'motor_gear_ratio': (1.0, 'motor revolutions per mechanism revolution', _f(0.01, 1000.0)),
    'counts_per_motor_rev': (4096, 'encoder counts per motor revolution (0x6064 units)',
                             _i(1, 1 << 24)),
    'heartbeat_period': (0.1, 'our CANopen heartbeat period (s), sent from the control loop',
                         _f(0.01, 1.0)),
    'drive_heartbeat_timeout': (0.35, "drive heartbeat older than this (s) = drive lost: "
                                'command 0, report ERROR, wait for reset_fault',
                                _f(0.05, 5.0)),
    'master_heartbeat_timeout': (0.3, "the drive's timeout for our heartbeat (s, 0x1016): "
                                 'it stops the motor if this process dies or hangs',
                                 _f(0.02, 5.0)),
    'command_timeout': (0.2, "drive-side command watchdog (s): the drive quick-stops if our "
                        'frames stop (process dead or hung)', _f(0.02, 5.0)),
    'step_timeout': (0.5, 'timeout of each enable/disable state-machine step (s)',
                     _f(0.05, 10.0)),
    'control_period': (0.02, 'control loop period (s): heartbeat, stale handling, joint_states',
                       _f(0.002, 0.1)),
    'diagnostics_period': (1.0, '/diagnostics period (s)', _f(0.1, 10.0)),
}

# name -> (description, range kwargs); defaults from PhaseLockConfig; changeable at run time
LAW_PARAMETERS = {
    'max_speed': ('mechanism speed limit (rad/s)', _f(0.1, 100.0)),
    'max_acceleration': ('mechanism acceleration limit (rad/s²)', _f(0.1, 1000.0)),
    'phase_gain': ('phase correction gain (1/s): rad/s of correction per rad of phase error',
                   _f(0.0, 50.0)),
    'max_correction': ('bound of the phase correction (rad/s)', _f(0.0, 50.0)),
    'phase_lock': ('true: phase-locked to travelled distance; false: speed-only', {}),
    'ground_speed_timeout': ('no accepted ground-speed sample for this long (s) = stale: '
                             'ramp to 0, then halt', _f(0.05, 10.0)),
    'max_ground_speed': ('faster samples are implausible and rejected (m/s)', _f(0.1, 10.0)),
    'max_ground_acceleration': ('samples jumping more than this allows are spikes, rejected '
                                '(m/s²)', _f(0.1, 50.0)),
    'ground_speed_tolerance': ('sensor noise allowed on top of the spike limit (m/s)',
                               _f(0.0, 1.0)),
}


class SyncNode(Node):
    """Keeps the planting mechanism in step with the ground through a CiA 402 drive."""

    def __init__(self, bus=None, **kwargs):
        super().__init__('sync_node', **kwargs)
        for name, (default, description, rng) in DRIVE_PARAMETERS.items():
            self.declare_parameter(name, default, ParameterDescriptor(
                description=description, read_only=True, **rng))
        defaults = PhaseLockConfig()
        for name, (description, rng) in LAW_PARAMETERS.items():
            self.declare_parameter(name, getattr(defaults, name),
                                   ParameterDescriptor(description=description, **rng))
        p = {name: self.get_parameter(name).value for name in DRIVE_PARAMETERS}
        self.drive_config = DriveConfig(
            interface=p['can_interface'], channel=p['can_channel'], bitrate=p['can_bitrate'],
            node_id=p['drive_node_id'], motor_gear_ratio=p['motor_gear_ratio'],
            counts_per_motor_rev=p['counts_per_motor_rev'],
            heartbeat_period=p['heartbeat_period'],
            master_heartbeat_timeout=p['master_heartbeat_timeout'],
            drive_heartbeat_timeout=p['drive_heartbeat_timeout'],
            command_timeout=p['command_timeout'], step_timeout=p['step_timeout'])
        self.hardware_id = (f"{p['can_interface']}:{p['can_channel']} "
                            f"node {p['drive_node_id']}")
        self.law = PhaseLock(PhaseLockConfig(
            **{name: self.get_parameter(name).value for name in LAW_PARAMETERS}))
        self.drive = Cia402Drive(self.drive_config, bus=bus)
        self._lock = threading.Lock()
        self._enabled = False
        self._shut_down = False
        self._joint = None
        self._status = None
        self._halt_reason = 'drive not enabled'
        self._fault_reported = False
        self.command_value = 0.0
        self.send_errors = 0
        self._last_send_error = None        # (monotonic time, message)
        self._last_heartbeat = -math.inf

        group = MutuallyExclusiveCallbackGroup()    # one control thread of execution
        self._joint_pub = self.create_publisher(JointState, interfaces.JOINT_STATES, STATE_QOS)
        self._cmd_pub = self.create_publisher(Float64, interfaces.SPEED_COMMAND, STATE_QOS)
        self._diag_pub = self.create_publisher(DiagnosticArray, interfaces.DIAGNOSTICS,
                                               DIAGNOSTICS_QOS)
        self.create_subscription(TwistStamped, interfaces.GROUND_SPEED, self._on_ground_speed,
                                 GROUND_SPEED_QOS, callback_group=group)
        self.create_subscription(String, interfaces.DESIGN, self._on_design, DESIGN_QOS,
                                 callback_group=group)
        self.create_service(Trigger, 'reset_fault', self._on_reset_fault, callback_group=group)
        self.create_timer(p['control_period'], self._on_control, callback_group=group)
        self.create_timer(p['diagnostics_period'], self._on_diagnostics, callback_group=group)
        self.add_on_set_parameters_callback(self._validate)

    # ---------------------------------------------------------------- life cycle
    def enable_drive(self):
        """BLOCKING: configure and enable the drive (start-up only, never from a callback)."""
        self.drive.connect_and_enable()
        with self._lock:
            self._enabled = True
            self._halt_reason = None
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
        if status is not None and joint is not None and _has_feedback(status):
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
        except (ValueError, KeyError, TypeError, ControlConfigError) as exc:
            self.get_logger().error(f'design ignored, keeping the last one: {exc}')
            return
        self.get_logger().info(f"design: {design['mechanism']}, d = {spacing} m, "
                               f'{n} plant(s) per revolution')

    def _on_reset_fault(self, _request, response):
        with self._lock:
            status = self.drive.status()
            if not status.fault and status.state != 'FAULT':
                response.success = False
                response.message = f'no drive fault to reset (state {status.state})'
                return response
            self.drive.request_fault_reset()
            response.success = True
            response.message = (f'fault reset requested (error 0x{status.error_code:04X}); the '
                                'drive re-enables if the cause is gone')
        self.get_logger().warning(response.message)
        return response

    def _validate(self, parameters):
        values = {name: self.get_parameter(name).value for name in LAW_PARAMETERS}
        touched = False
        for p in parameters:
            if p.name in LAW_PARAMETERS:
                values[p.name] = p.value
                touched = True
        if not touched:
            return SetParametersResult(successful=True)
        try:
            config = PhaseLockConfig(**values)
        except ControlConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        with self._lock:
            self.law.config = config
        return SetParametersResult(successful=True)

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
        if _has_feedback(status):
            self.law.feedback(status.position, status.velocity, status.stamp)
        reason = self._halt_check(status)
        if reason != self._halt_reason:
            self._report_halt(reason, status)
            self._halt_reason = reason
        if reason is None:
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

    def _halt_check(self, status):
        if status.fault or status.state == 'FAULT':
            why = status.fault_reason or status.state
            return f'drive fault 0x{status.error_code:04X} ({why})'
        if status.heartbeat_age > self.drive_config.drive_heartbeat_timeout:
            return 'drive heartbeat lost'
        if status.state != OPERATION_ENABLED:
            return f'drive not enabled ({status.state})'
        return None

    def _report_halt(self, reason, status):
        log = self.get_logger()
        if reason is None:
            log.info('drive back in operation: resuming')
        elif reason.startswith('drive fault'):
            log.error(f'{reason} (state {status.state}): commanding 0; call the reset_fault '
                      'service once the cause is cleared')
        else:
            log.warning(f'{reason}: commanding 0')

    def _send_failed(self, now, exc):
        self.send_errors += 1
        first = self._last_send_error is None or now - self._last_send_error[0] > SEND_ERROR_HOLD
        self._last_send_error = (now, str(exc))
        if first:
            self.get_logger().error(f'CAN send failed: {exc}')

    # ---------------------------------------------------------------- diagnostics
    def _on_diagnostics(self):
        now = time.monotonic()
        with self._lock:
            statuses = [self._drive_status(now), self._ground_status(now),
                        self._phase_status(now)]
        msg = DiagnosticArray(status=statuses)
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(msg)

    def diagnostics(self):
        """The DiagnosticStatus list the next /diagnostics message will carry (for tests)."""
        now = time.monotonic()
        with self._lock:
            return [self._drive_status(now), self._ground_status(now), self._phase_status(now)]

    def _make(self, task, level, message, values):
        return DiagnosticStatus(level=level, name=f'{self.get_name()}: {task}', message=message,
                                hardware_id=self.hardware_id,
                                values=[KeyValue(key=k, value=str(v)) for k, v in values])

    def _drive_status(self, now):
        st = self._status if self._enabled or self._status is not None else None
        values = [('enabled', self._enabled), ('send errors', self.send_errors)]
        if st is None:
            return self._make('drive', DiagnosticStatus.ERROR if not self._shut_down else
                              DiagnosticStatus.STALE, self._halt_reason or 'not enabled', values)
        values = [('drive state', st.state), ('statusword', f'0x{st.statusword:04X}'),
                  ('error code', f'0x{st.error_code:04X}'),
                  ('heartbeat age', f'{st.heartbeat_age:.3f} s'),
                  ('position', f'{st.position:.4f} rad'),
                  ('velocity', f'{st.velocity:.4f} rad/s'),
                  ('command', f'{self.command_value:.4f} rad/s')] + values
        recent = self._last_send_error and now - self._last_send_error[0] <= SEND_ERROR_HOLD
        if recent:
            values.append(('last send error', self._last_send_error[1]))
            return self._make('drive', DiagnosticStatus.ERROR,
                              f'CAN send error: {self._last_send_error[1]}', values)
        if self._halt_reason is not None:
            return self._make('drive', DiagnosticStatus.ERROR, self._halt_reason, values)
        if not _has_feedback(st):
            return self._make('drive', DiagnosticStatus.STALE, 'no feedback from the drive',
                              values)
        return self._make('drive', DiagnosticStatus.OK, 'operation enabled', values)

    def _ground_status(self, now):
        law = self.law
        rejected = sum(law.rejected.values())
        values = [('ground speed', f'{law.ground_speed_value:.4f} m/s'),
                  ('travelled', f'{law.travelled(now):.4f} m'),
                  ('accepted samples', law.accepted), ('rejected samples', rejected)]
        values += [(f'rejected {k}', v) for k, v in law.rejected.items()]
        if law.stale(now):
            return self._make('ground speed', DiagnosticStatus.STALE, law.state(now), values)
        if rejected:
            return self._make('ground speed', DiagnosticStatus.WARN,
                              f'{rejected} sample(s) rejected since start', values)
        return self._make('ground speed', DiagnosticStatus.OK, 'fresh', values)

    def _phase_status(self, now):
        law = self.law
        error = law.last_error
        metres = error * law.plants_per_revolution * law.spacing / (2 * math.pi) \
            if law.spacing else 0.0
        values = [('mode', 'phase-locked' if law.config.phase_lock else 'speed-only'),
                  ('state', law.state(now)), ('phase error', f'{error:.4f} rad'),
                  ('phase error along row', f'{metres:.4f} m'),
                  ('phase slips', law.phase_slips),
                  ('command', f'{self.command_value:.4f} rad/s')]
        if law.spacing is None:
            return self._make('phase lock', DiagnosticStatus.STALE, 'waiting for design', values)
        if law.phase_slips:
            return self._make('phase lock', DiagnosticStatus.WARN,
                              f'{law.phase_slips} plant(s) skipped to stay on the grid', values)
        return self._make('phase lock', DiagnosticStatus.OK, law.state(now), values)


def _has_feedback(status):
    return status.stamp is not None and math.isfinite(status.stamp) and status.stamp > 0.0


def main(args=None):
    rclpy.init(args=args)
    node = None
    code = 0
    try:
        node = SyncNode(namespace=interfaces.NAMESPACE)
        node.enable_drive()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (DriveError, ParameterException) as exc:
        print(f'sync_node: error: {str(exc).splitlines()[0]}', file=sys.stderr)
        code = 1
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
