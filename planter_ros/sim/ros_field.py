"""The simulated field of the demo: a ground-speed sensor, a GNSS receiver, the rows' cup
sensors on a simulated tray and an observer of the mechanism.

GroundSpeedSource publishes TwistStamped along a field profile (t -> true speed, m/s, and the
yaw rate on its curves in twist.angular.z) with Gaussian noise and, at given times, the glitches
real wheel/radar sensors produce (a spike, a NaN) that the sync node must reject. The profile's
exact travelled distance (each row's own, on a curve) is the reference for the demo's spacing
figures; Observer collects each row's measured mechanism angle to compare.
"""


from __future__ import annotations

from collections.abc import Sequence
import math
from typing import TYPE_CHECKING, Any

import numpy as np
from geometry_msgs.msg import TwistStamped
from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import JointState

from planter_ros import interfaces
from planter_ros.design import Design, from_json
from planter_ros.kinematics.arrays import FloatArray
from planter_ros.prediction import planting_model_from_design

from .closed_loop import MotionSensor
from .field import FieldProfile
from .gnss import SimulatedGnss, fix_positions, navsatfix
from .spacing import plant_positions
from .tray import SensedCycles, Tray

if TYPE_CHECKING:
    from std_msgs.msg import Float64, String

    from planter_ros.rows import Row


class GroundSpeedSource(Node):
    """Publishes `ground_speed` at `rate` Hz from `profile(t)` (t in s since start), read as
    `sensor` says (a MotionSensor, default its defaults: Gaussian noise and its seed; the yaw
    rate's noise a MEMS gyro's at 20 Hz), and at the `glitches` (t, value) that value instead
    of the reading."""

    def __init__(self, profile: FieldProfile, sensor: MotionSensor | None = None,
                 rate: float = 20.0, glitches: Sequence[tuple[float, float]] = (),
                 **kwargs: Any) -> None:
        super().__init__('ground_speed_source', **kwargs)
        sensor = sensor or MotionSensor()
        self.profile = profile
        self.noise = sensor.noise
        self.yaw_noise = sensor.yaw_noise     # rad/s, a MEMS gyro's noise at 20 Hz
        self.glitches = sorted(glitches)      # (t, value) published instead of the reading
        self._rng = np.random.default_rng(sensor.seed)
        self._pub = interfaces.GROUND_SPEED.publisher(self)
        self.start = self.get_clock().now()
        self.samples = 0
        self.create_timer(1.0 / rate, self._tick)

    def restart(self) -> None:
        """The field run starts now (the graph is matched): t = 0 of the profile."""
        self.start = self.get_clock().now()

    def elapsed(self, now: Time | None = None) -> float:
        return ((now or self.get_clock().now()) - self.start).nanoseconds * 1e-9

    def _tick(self) -> None:
        now = self.get_clock().now()
        t = self.elapsed(now)
        v = self.profile(t)
        reading = v + self._rng.normal(0.0, self.noise) if v > 0.0 else 0.0
        yaw = getattr(self.profile, 'yaw_rate', lambda _t: 0.0)(t)
        yaw_reading = yaw + self._rng.normal(0.0, self.yaw_noise)
        if self.glitches and t >= self.glitches[0][0]:
            reading = self.glitches.pop(0)[1]
        msg = TwistStamped()
        msg.header.stamp = now.to_msg()
        msg.header.frame_id = 'base_link'
        msg.twist.linear.x = float(reading)
        msg.twist.angular.z = float(yaw_reading)
        self._pub.publish(msg)
        self.samples += 1


class GnssSource(Node):
    """Publishes `gnss/fix` at the receiver's rate along the profile's path (sim.gnss), on the
    clock of `start` (the ground-speed source's start: both describe one machine)."""

    def __init__(self, profile: FieldProfile, gnss: SimulatedGnss, start: Time,
                 antenna: Sequence[float] = (0.0, 0.0), seed: int = 0, **kwargs: Any) -> None:
        super().__init__('gnss_source', **kwargs)
        self.profile, self.gnss, self.start = profile, gnss, start
        self.antenna = tuple(antenna)
        self._rng = np.random.default_rng(seed + 1)
        self._pub = interfaces.GNSS_FIX.publisher(self)
        self.fixes = 0
        # the projection now, not in the first tick (pyproj's import would stall the executor)
        fix_positions(profile, np.zeros(1), gnss, self.antenna)
        self.create_timer(1.0 / gnss.rate, self._tick)

    def _tick(self) -> None:
        now = self.get_clock().now()
        t = (now - self.start).nanoseconds * 1e-9
        if t < 0.0:
            return
        lat, lon, alt = fix_positions(self.profile, np.array([t]), self.gnss, self.antenna,
                                      self._rng)
        self._pub.publish(navsatfix(now.to_msg(), lat[0], lon[0], alt[0], self.gnss.noise))
        self.fixes += 1


class SeedlingSensor(Node):
    """Each planting row's cup sensor on a simulated tray (sim.tray): follows the rows' measured
    shaft angles (joint_states) and publishes `seedlings` (one JointState per cup: the row's
    joint, the count 0/1/2, stamped with the feedback sample that saw the cup pass the sensor,
    half a cycle before its planting angle), as `planter simulate`'s runs record it. `rows`:
    the planting rows; each row's tray draws from its own generator of `seed`."""

    def __init__(self, design: Design, rows: Sequence[Row], empty_rate: float = 0.0,
                 double_rate: float = 0.0, seed: int = 0, **kwargs: Any) -> None:
        super().__init__('seedling_sensor', **kwargs)
        self._message = JointState
        model = planting_model_from_design(design, 0.0)      # its phase and cycle only
        self._rows: dict[str, SensedCycles] = {row.joint(design.mechanism): SensedCycles(
            model, Tray(empty_rate, double_rate, np.random.default_rng([seed, row.index, 3])))
            for row in rows}
        self.read: dict[str, list[float]] = {joint: [] for joint in self._rows}  # published
        self._pub = interfaces.SEEDLINGS.publisher(self)
        interfaces.JOINT_STATES.subscribe(self, self._on_joint)

    def _on_joint(self, msg: JointState) -> None:
        names = list(msg.name) or [next(iter(self._rows))]   # a drive that leaves names out
        for name, angle in zip(names, msg.position):
            cycles = self._rows.get(name)
            for _, count in cycles.add(angle) if cycles is not None else ():
                out = self._message(name=[name], position=[float(count)])
                out.header.stamp = msg.header.stamp
                self._pub.publish(out)
                self.read[name].append(count)


def _since(start: Time, time: Time) -> float:
    """Seconds from `start` to `time`."""
    return (time - start).nanoseconds * 1e-9


class Observer(Node):
    """Collects joint_states (measured), the speed commands and the designs for the demo's
    summary, per joint (one per row; `sun_bar` / `carrier` in a scene without rows)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('demo_observer', **kwargs)
        self.start: Time | None = None   # when the field run started
        # joint -> [(t since start, angle rad, velocity rad/s)]
        self.joint: dict[str | None, list[tuple[float, float, float]]] = {}
        # joint (None: speed_command) -> [(t since start, rad/s)]
        self.command: dict[str | None, list[tuple[float, float]]] = {}
        self.designs: list[tuple[Time, Design]] = []     # (received, design), each new one
        interfaces.JOINT_STATES.subscribe(self, self._on_joint)
        interfaces.SPEED_COMMAND.subscribe(self, self._on_command)
        interfaces.SPEED_COMMANDS.subscribe(self, self._on_commands)
        interfaces.DESIGN.subscribe(self, self._on_design)

    def _on_design(self, msg: String) -> None:
        try:
            design = from_json(msg.data)
        except ValueError:
            return                   # the nodes refuse it too (DesignMessageError)
        if not self.designs or self.designs[-1][1] != design:
            self.designs.append((self.get_clock().now(), design))

    def design_changes(self) -> list[tuple[float, Design]]:
        """(t since start s, design) of each design after the first (the one in force when
        the field run started)."""
        start = self.start
        if start is None:
            return []
        return [(_since(start, t), design) for t, design in self.designs[1:]]

    def _on_joint(self, msg: JointState) -> None:
        if self.start is None:
            return
        t = _since(self.start, Time.from_msg(msg.header.stamp))
        names: list[str | None] = list(msg.name) or [None]
        for i, name in enumerate(names[:len(msg.position)]):
            velocity = msg.velocity[i] if len(msg.velocity) > i else math.nan
            self.joint.setdefault(name, []).append((t, msg.position[i], velocity))

    def _on_command(self, msg: Float64) -> None:
        if self.start is not None:
            self.command.setdefault(None, []).append(
                (_since(self.start, self.get_clock().now()), msg.data))

    def _on_commands(self, msg: JointState) -> None:
        if self.start is not None:
            t = _since(self.start, self.get_clock().now())
            for name, value in zip(msg.name, msg.velocity):
                self.command.setdefault(name, []).append((t, value))

    def _joint(self, joint: str | None) -> list[tuple[float, float, float]]:
        rows = self.joint.get(joint)
        if rows is None and len(self.joint) == 1:
            rows = next(iter(self.joint.values()))
        return list(rows or [])

    def window(self, what: str, a: float, b: float, joint: str | None = None) -> FloatArray:
        """Commanded ('command') or measured ('velocity') speeds of `joint` between a and b s."""
        rows: Sequence[tuple[float, ...]]
        if what == 'command':
            rows = self.command.get(joint if joint in self.command else None, [])
            col = 1
        else:
            rows, col = self._joint(joint), 2
        return np.array([r[col] for r in list(rows) if a <= r[0] <= b])

    def plants(self, profile: FieldProfile, design: Design, joint: str | None = None,
               lateral_offset: float = 0.0) -> tuple[FloatArray, FloatArray]:
        """(times s, positions m) of each plant release seen in `joint`'s measured angle; the
        position is the row's own true travelled distance (profile.row_distance)."""
        rows = [r for r in self._joint(joint) if r[0] >= 0.0]
        if len(rows) < 2:
            return np.empty(0), np.empty(0)
        t, angle, _ = (np.array(c) for c in zip(*rows))
        pitch = 2 * math.pi / design.plants_per_revolution
        # the arm starts at the top and releases half a pitch later (five-bar: the bottom)
        release = angle[0] + 0.5 * pitch
        distance = (profile.row_distance(t, lateral_offset) if hasattr(profile, 'row_distance')
                    else profile.distance(t))
        return (plant_positions(angle, t, pitch, release=release),
                plant_positions(angle, distance, pitch, release=release))

    def plant_positions(self, profile: FieldProfile, design: Design, joint: str | None = None,
                        lateral_offset: float = 0.0) -> FloatArray:
        """True travelled distance (m) at each plant release seen in the measured angle."""
        return self.plants(profile, design, joint, lateral_offset)[1]
