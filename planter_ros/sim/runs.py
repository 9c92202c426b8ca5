"""Measured streams of simulated planting runs: what the drive and the ground-speed sensor of a
machine would report, made without ROS from the sync node's own law (control.phase_lock)
against the drive model of sim.closed_loop. Deterministic for a given seed; the sample bags,
the replay benchmark and many tests are made from them.
"""

from collections.abc import Iterator
from dataclasses import dataclass
import math
from typing import Any

from builtin_interfaces.msg import Time
from geometry_msgs.msg import TwistStamped
import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, String

from planter_ros import interfaces
from planter_ros.control.phase_lock import PhaseLock, PhaseLockConfig
from planter_ros.design import Design, design_for_scene, to_json

from .closed_loop import (
    DriveChange, DriveModel, DriveSchedule, LoopTiming, SpeedSensor, simulate)
from .field import speed_profile

SIM_EPOCH = 1_700_000_000.0      # s: fixed start of simulated time (deterministic bags)


@dataclass
class Run:
    """A simulated measured stream (SI units, times in s on the simulated clock)."""

    design: Design               # what the `design` topic carries (planter_ros.design)
    speed_t: np.ndarray          # ground speed measurement times
    speed_v: np.ndarray          # measured ground speed (m/s)
    joint_t: np.ndarray          # drive feedback times
    joint_pos: np.ndarray        # measured shaft angle (rad, unwrapped)
    joint_vel: np.ndarray        # measured shaft speed (rad/s)
    command: np.ndarray          # shaft speed command at joint_t (rad/s)

    def messages(self) -> Iterator[tuple[int, interfaces.Topic, Any]]:
        """The stream as ROS messages in time order: (time ns, Topic, message), the design first
        (1 ms before the first sample), then ground speed and joint state + speed command."""
        joint = interfaces.MECHANISM_JOINT[self.design.mechanism]
        t0 = _ns(min(self.speed_t[0], self.joint_t[0])) - 1_000_000
        yield t0, interfaces.DESIGN, String(data=to_json(self.design))
        events = sorted([(_ns(t), 0, i) for i, t in enumerate(self.speed_t)]
                        + [(_ns(t), 1, i) for i, t in enumerate(self.joint_t)])
        for stamp, kind, i in events:
            sec, nsec = divmod(stamp, 1_000_000_000)
            if kind == 0:
                twist = TwistStamped()
                twist.header.stamp = Time(sec=sec, nanosec=nsec)
                twist.twist.linear.x = float(self.speed_v[i])
                yield stamp, interfaces.GROUND_SPEED, twist
            else:
                state = JointState(name=[joint], position=[float(self.joint_pos[i])],
                                   velocity=[float(self.joint_vel[i])])
                state.header.stamp = Time(sec=sec, nanosec=nsec)
                yield stamp, interfaces.JOINT_STATES, state
                yield stamp, interfaces.SPEED_COMMAND, Float64(data=float(self.command[i]))


def _ns(seconds: float) -> int:
    return int(round(seconds * 1e9))


def five_bar_design_message(depth: float = 0.045, spacing: float = 0.2,
                            hole_ratio: float = 0.05, method: str = 'exact',
                            ground_speed: float = 0.2, nozzle_width: float = 0.04) -> Design:
    """The design of a five-bar scene (tomato defaults), as design_node makes it."""
    return design_for_scene({'mechanism': 'five_bar', 'planting_depth': depth,
                             'plant_spacing': spacing, 'hole_ratio': hole_ratio,
                             'design_method': method, 'nominal_ground_speed': ground_speed,
                             'nozzle_width': nozzle_width})


@dataclass(frozen=True)
class RunOptions:
    """A simulated planting run (`simulate_run`): its `duration` (s) along the speed profile of
    `cruise` (m/s) with a `step` to step·cruise half-way; the ground-speed sensor at
    `speed_rate` (Hz) with relative noise `speed_noise`; joint states at `joint_rate` (Hz) from
    an encoder of `encoder_counts` per revolution; the drive's lag `drive_lag` (s) and the
    law's `phase_gain` (0: speed-only); `stall_at` (s; None: no stall) makes the drive reach
    only `stall_level` of its command for `stall_for` s; the noise drawn from `seed`."""

    duration: float = 30.0
    cruise: float = 0.2
    speed_rate: float = 20.0
    joint_rate: float = 100.0
    drive_lag: float = 0.08
    phase_gain: float = 4.0
    speed_noise: float = 0.02
    encoder_counts: int = 4096
    step: float = 1.25
    stall_at: float | None = None
    stall_for: float = 0.8
    stall_level: float = 0.2
    seed: int = 1


def simulate_run(design: Design, options: RunOptions = RunOptions()) -> Run:
    """Measured stream of a planting run (see module doc and RunOptions). Deterministic for a
    given seed.

    The machine is the sync node's own law (control.phase_lock; `phase_gain` = 0 is speed-only)
    against the drive model of sim.closed_loop, sampled as the drive and sensor would:
    joint states at `joint_rate` (encoder-quantised angle, noisy speed), ground speed at
    `speed_rate` with relative noise `speed_noise`. `stall_at` (s) makes the drive lose most of
    its torque for `stall_for` s (it reaches `stall_level` of what is commanded): the shaft
    drags behind the ground, then the phase lock catches up.
    """
    o = options
    duration, cruise, step, speed_noise, drive_lag = (o.duration, o.cruise, o.step,
                                                      o.speed_noise, o.drive_lag)
    phase_gain, stall_at, stall_for, stall_level = (o.phase_gain, o.stall_at, o.stall_for,
                                                    o.stall_level)
    rng = np.random.default_rng(o.seed)
    n = design.plants_per_revolution
    spacing = design.plant_spacing
    law = PhaseLock(PhaseLockConfig(phase_gain=phase_gain, phase_lock=phase_gain > 0,
                                    max_acceleration=200.0, max_correction=20.0))
    law.set_design(spacing, n, 0.0)

    def true_speed(t: float) -> float:
        # slow true speed variation (soil, slip) on top of the profile
        wobble = 1.0 + 0.03 * math.sin(2 * math.pi * t / 7.0) \
            + 0.02 * math.sin(2 * math.pi * t / 2.3)
        return float(speed_profile(t, cruise, duration, step=step)) * wobble

    readings: list[tuple[float, float]] = []

    def sensor(t: float, v: float) -> float:
        reading = v * (1.0 + rng.normal(0.0, speed_noise))
        readings.append((t, reading))
        return reading

    nominal = DriveModel(time_constant=drive_lag, max_acceleration=1e3)
    changes: tuple[DriveChange, ...] = () if stall_at is None else (
        (stall_at, DriveModel(time_constant=drive_lag, max_acceleration=1e3,
                              speed_scale=stall_level)),
        (stall_at + stall_for, nominal))
    dt = 1.0 / o.joint_rate
    sim = simulate(law, true_speed, duration, DriveSchedule(nominal, changes),
                   SpeedSensor(read=sensor), LoopTiming(dt / 4, 1.0 / o.speed_rate, dt))
    every = 4                                    # feedback samples on the integration grid
    t = sim.t[::every]
    quantum = 2 * math.pi / o.encoder_counts
    joint_pos = np.round(sim.angle[::every] / quantum) * quantum
    joint_vel = sim.speed[::every] + rng.normal(0.0, 0.01 * 2 * math.pi * cruise /
                                                (n * spacing), t.size)
    speed_t, speed_v = (np.array(c) for c in zip(*readings))
    return Run(design=design, speed_t=SIM_EPOCH + speed_t, speed_v=speed_v,
               joint_t=SIM_EPOCH + t, joint_pos=joint_pos, joint_vel=joint_vel,
               command=sim.command[::every])
