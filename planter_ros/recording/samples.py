"""Sample recordings: a realistic measured input stream and the bags made from it.

`simulate_run` is the machine without ROS: a ground-speed profile (start, cruise with noise, a
speed step, stop), the sync node's phase-locked law and the drive model of control.simulation,
measured as an encoder and a speed sensor would (quantised angle, noisy speeds). `record_sample` feeds that
stream to the real monitor node over ROS (simulated clock, lock-step, so a 30 s run records in
a few seconds) and lets it record its bag — the committed `bags/sample_*.mcap` come from
`python -m planter_ros.recording.samples` (see README). `write_input_bag` writes only the input
topics straight through the recorder (fast; for the replay speed benchmark).
The demo (`planter demo`) replaces the stand-in with the real sync node and simulated drive.
"""

from dataclasses import dataclass
import json
import math

import numpy as np

from planter_ros import interfaces

SIM_EPOCH = 1_700_000_000.0      # s: fixed start of simulated time (deterministic bags)


@dataclass
class Run:
    """A simulated measured stream (SI units, times in s on the simulated clock)."""

    design: dict                 # the `design` topic's JSON dict
    speed_t: np.ndarray          # ground speed measurement times
    speed_v: np.ndarray          # measured ground speed (m/s)
    joint_t: np.ndarray          # drive feedback times
    joint_pos: np.ndarray        # measured shaft angle (rad, unwrapped)
    joint_vel: np.ndarray        # measured shaft speed (rad/s)
    command: np.ndarray          # shaft speed command at joint_t (rad/s)


def five_bar_design_message(depth=0.045, spacing=0.2, hole_ratio=0.05, method='exact',
                            ground_speed=0.2):
    """The design topic's dict for a five-bar scene (tomato defaults), as design_node makes it."""
    from planter_ros.kinematics.scene_design import design_for_scene
    return design_for_scene({'mechanism': 'five_bar', 'planting_depth': depth,
                             'plant_spacing': spacing, 'hole_ratio': hole_ratio,
                             'design_method': method, 'nominal_ground_speed': ground_speed})


def speed_profile(t, cruise, duration, step_at=None, step=1.25, ramp=2.0):
    """True ground speed (m/s): ramp up, cruise, a step to step·cruise, ramp down to a stop."""
    step_at = 0.5 * duration if step_at is None else step_at
    up = np.clip(t / ramp, 0.0, 1.0)
    down = np.clip((duration - t) / ramp, 0.0, 1.0)
    level = np.where(t < step_at, cruise, step * cruise)
    return level * np.minimum(up, down)


def simulate_run(design, duration=30.0, cruise=0.2, speed_rate=20.0, joint_rate=100.0,
                 drive_lag=0.08, phase_gain=4.0, speed_noise=0.02, encoder_counts=4096,
                 step=1.25, stall_at=None, stall_for=0.8, stall_level=0.2, seed=1):
    """Measured stream of a planting run (see module doc). Deterministic for a given seed.

    The machine is the sync node's own law (control.phase_lock; `phase_gain` = 0 is speed-only)
    against the drive model of control.simulation, sampled as the drive and sensor would:
    joint states at `joint_rate` (encoder-quantised angle, noisy speed), ground speed at
    `speed_rate` with relative noise `speed_noise`. `stall_at` (s) makes the drive lose most of
    its torque for `stall_for` s (it reaches `stall_level` of what is commanded): the shaft
    drags behind the ground, then the phase lock catches up.
    """
    from planter_ros.control.phase_lock import PhaseLock, PhaseLockConfig
    from planter_ros.control.simulation import DriveModel, simulate

    rng = np.random.default_rng(seed)
    n = design['plants_per_revolution']
    spacing = design['plant_spacing']
    law = PhaseLock(PhaseLockConfig(phase_gain=phase_gain, phase_lock=phase_gain > 0,
                                    max_acceleration=200.0, max_correction=20.0))
    law.set_design(spacing, n, 0.0)

    def true_speed(t):
        # slow true speed variation (soil, slip) on top of the profile
        wobble = 1.0 + 0.03 * math.sin(2 * math.pi * t / 7.0) \
            + 0.02 * math.sin(2 * math.pi * t / 2.3)
        return float(speed_profile(t, cruise, duration, step=step)) * wobble

    readings = []

    def sensor(t, v):
        reading = v * (1.0 + rng.normal(0.0, speed_noise))
        readings.append((t, reading))
        return reading

    nominal = DriveModel(time_constant=drive_lag, max_acceleration=1e3)
    changes = [] if stall_at is None else [
        (stall_at, DriveModel(time_constant=drive_lag, max_acceleration=1e3,
                              speed_scale=stall_level)),
        (stall_at + stall_for, nominal)]
    dt = 1.0 / joint_rate
    sim = simulate(law, true_speed, duration, drive=nominal, dt=dt / 4, sample_period=1.0 /
                   speed_rate, feedback_period=dt, sensor=sensor, drive_change=changes)
    every = 4                                    # feedback samples on the integration grid
    t = sim.t[::every]
    quantum = 2 * math.pi / encoder_counts
    joint_pos = np.round(sim.angle[::every] / quantum) * quantum
    joint_vel = sim.speed[::every] + rng.normal(0.0, 0.01 * 2 * math.pi * cruise /
                                                (n * spacing), t.size)
    speed_t, speed_v = (np.array(c) for c in zip(*readings))
    return Run(design=design, speed_t=SIM_EPOCH + speed_t, speed_v=speed_v,
               joint_t=SIM_EPOCH + t, joint_pos=joint_pos, joint_vel=joint_vel,
               command=sim.command[::every])


def _topic(name):
    return f'/{interfaces.NAMESPACE}/{name}'


def _ns(seconds):
    return int(round(seconds * 1e9))


def write_input_bag(run, path, **recorder_options):
    """Write a run's measured inputs (design, ground_speed, joint_states, speed_command) straight
    into a bag through the recorder, log time = measurement time. Returns the Recorder."""
    from builtin_interfaces.msg import Time
    from geometry_msgs.msg import TwistStamped
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64, String
    from planter_ros.recording.recorder import Recorder
    from planter_ros.nodes.monitor_node import input_qos

    rec = Recorder(path, **recorder_options)
    qos = input_qos()
    rec.add_topic(_topic(interfaces.DESIGN), 'std_msgs/msg/String', qos['design'])
    rec.add_topic(_topic(interfaces.GROUND_SPEED), 'geometry_msgs/msg/TwistStamped',
                  qos['speed'])
    rec.add_topic(_topic(interfaces.JOINT_STATES), 'sensor_msgs/msg/JointState', qos['stream'])
    rec.add_topic(_topic(interfaces.SPEED_COMMAND), 'std_msgs/msg/Float64', qos['stream'])
    joint = interfaces.MECHANISM_JOINT[run.design['mechanism']]
    t0 = _ns(min(run.speed_t[0], run.joint_t[0])) - 1_000_000
    rec.write_message(_topic(interfaces.DESIGN), String(data=json.dumps(run.design)), t0)
    events = sorted([(_ns(t), 0, i) for i, t in enumerate(run.speed_t)]
                    + [(_ns(t), 1, i) for i, t in enumerate(run.joint_t)])
    msg_v, msg_j = TwistStamped(), JointState(name=[joint])
    for stamp, kind, i in events:
        sec, nsec = divmod(stamp, 1_000_000_000)
        if kind == 0:
            msg_v.header.stamp = Time(sec=sec, nanosec=nsec)
            msg_v.twist.linear.x = float(run.speed_v[i])
            rec.write_message(_topic(interfaces.GROUND_SPEED), msg_v, stamp)
        else:
            msg_j.header.stamp = Time(sec=sec, nanosec=nsec)
            msg_j.position = [float(run.joint_pos[i])]
            msg_j.velocity = [float(run.joint_vel[i])]
            rec.write_message(_topic(interfaces.JOINT_STATES), msg_j, stamp)
            rec.write_message(_topic(interfaces.SPEED_COMMAND),
                              Float64(data=float(run.command[i])), stamp)
    rec.close()
    return rec


def record_sample(run, bag_path, monitor_parameters=None, timeout=60.0, domain_id=None):
    """Run the real monitor node on `run` over ROS and let it record `bag_path`.

    It runs in a DDS domain of its own (`domain_id`) so other ROS processes on the machine
    cannot mix into the sample. Simulated time (use_sim_time, /clock) advances in lock-step
    with the stream: each sample is published and the monitor is spun until it has taken it,
    so nothing is dropped and the bag's log times are the simulated receive times. Returns the list of plant tables the monitor
    published (its live predictions), in order.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile
    from rosgraph_msgs.msg import Clock
    from builtin_interfaces.msg import Time
    from geometry_msgs.msg import TwistStamped
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64, String
    from planter_ros.dds_domain import claim_private_domain
    from planter_ros.nodes.monitor_node import MonitorNode, input_qos
    import time

    context = rclpy.Context()
    rclpy.init(context=context,
               domain_id=claim_private_domain() if domain_id is None else domain_id)
    params = [Parameter('use_sim_time', value=True), Parameter('bag_path', value=str(bag_path))]
    for name, value in (monitor_parameters or {}).items():
        params.append(Parameter(name, value=value))
    monitor = feeder = executor = None
    try:
        monitor = MonitorNode(context=context, parameter_overrides=params)
        if monitor.recorder is None:
            from planter_ros.recording.recorder import RecorderError
            raise RecorderError(monitor.record_error or 'the monitor is not recording')
        feeder = rclpy.create_node('sample_feeder', namespace=interfaces.NAMESPACE,
                                   context=context)
        qos = input_qos()
        pub_clock = feeder.create_publisher(Clock, '/clock', QoSProfile(depth=100))
        pub_design = feeder.create_publisher(String, interfaces.DESIGN, qos['design'])
        pub_speed = feeder.create_publisher(TwistStamped, interfaces.GROUND_SPEED,
                                            qos['stream'])     # reliable: lock-step feeding
        pub_joint = feeder.create_publisher(JointState, interfaces.JOINT_STATES, qos['stream'])
        pub_cmd = feeder.create_publisher(Float64, interfaces.SPEED_COMMAND, qos['stream'])
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(monitor)
        executor.add_node(feeder)
        deadline = time.monotonic() + timeout

        def spin_until(condition):
            while not condition():
                if time.monotonic() > deadline:
                    raise TimeoutError('monitor did not take the sample stream in time')
                executor.spin_once(timeout_sec=0.01)

        # wait until the monitor's subscriptions matched the feeder
        spin_until(lambda: all(p.get_subscription_count() > 0 for p in
                               (pub_clock, pub_design, pub_speed, pub_joint, pub_cmd)))

        def set_clock(stamp):
            sec, nsec = divmod(stamp, 1_000_000_000)
            pub_clock.publish(Clock(clock=Time(sec=sec, nanosec=nsec)))
            spin_until(lambda: monitor.get_clock().now().nanoseconds == stamp)

        t0 = _ns(min(run.speed_t[0], run.joint_t[0])) - 1_000_000
        set_clock(t0)
        pub_design.publish(String(data=json.dumps(run.design)))
        spin_until(lambda: monitor.has_design)
        joint = interfaces.MECHANISM_JOINT[run.design['mechanism']]
        events = sorted([(_ns(t), 0, i) for i, t in enumerate(run.speed_t)]
                        + [(_ns(t), 1, i) for i, t in enumerate(run.joint_t)])
        msg_v, msg_j = TwistStamped(), JointState(name=[joint])
        for stamp, kind, i in events:
            set_clock(stamp)
            sec, nsec = divmod(stamp, 1_000_000_000)
            taken = monitor.samples_taken
            if kind == 0:
                msg_v.header.stamp = Time(sec=sec, nanosec=nsec)
                msg_v.twist.linear.x = float(run.speed_v[i])
                pub_speed.publish(msg_v)
                spin_until(lambda: monitor.samples_taken > taken)
            else:
                msg_j.header.stamp = Time(sec=sec, nanosec=nsec)
                msg_j.position = [float(run.joint_pos[i])]
                msg_j.velocity = [float(run.joint_vel[i])]
                pub_joint.publish(msg_j)
                pub_cmd.publish(Float64(data=float(run.command[i])))
                spin_until(lambda: monitor.samples_taken > taken + 1)
        return monitor.published_tables()
    finally:
        if executor is not None:
            executor.shutdown()
        if feeder is not None:
            feeder.destroy_node()
        if monitor is not None:
            monitor.destroy_node()
        rclpy.try_shutdown(context=context)


SAMPLES = {
    # name: (design kwargs, simulate_run kwargs); the demo records the other samples
    'pepper_stall': (dict(depth=0.06, spacing=0.3, hole_ratio=0.05, ground_speed=0.3),
                     dict(duration=20.0, cruise=0.3, step=1.6, drive_lag=0.25, phase_gain=1.0,
                          stall_at=7.0, stall_for=3.5, stall_level=0.1, seed=2)),
}


def main(argv=None):
    """Regenerate bags/sample_<name>.mcap (refuses to overwrite: delete them first)."""
    import argparse
    from pathlib import Path
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument('--out', default='bags', help='directory for the sample bags')
    args = parser.parse_args(argv)
    for name, (design_kw, run_kw) in SAMPLES.items():
        path = Path(args.out) / f'sample_{name}.mcap'
        run = simulate_run(five_bar_design_message(**design_kw), **run_kw)
        tables = record_sample(run, path)
        print(f'{path}: {sum(len(t) for t in tables)} plants, {path.stat().st_size} bytes')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
