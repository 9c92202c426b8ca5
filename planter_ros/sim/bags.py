"""Bags of simulated runs, written straight through the recorder (no ROS graph): the same
topics, types and QoS the monitor records (interfaces.MONITOR_INPUTS), log time = measurement
time. Fast; for the replay benchmark and the recording tests."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from builtin_interfaces.msg import Time
from geometry_msgs.msg import TwistStamped
import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from planter_ros import interfaces
from planter_ros.design import Design, to_json
from planter_ros.recording.recorder import BagLayout, Recorder
from planter_ros.rows import Row, rows_record

if TYPE_CHECKING:
    from .closed_loop import RowRun
    from .field import FieldProfile
    from .runs import Run


def write_input_bag(run: Run, path: str | Path, **recorder_options: Any) -> Recorder:
    """Write a run's measured inputs (design, ground_speed, joint_states, speed_command) into a
    bag at `path`. Returns the closed Recorder."""
    rec = Recorder(path, BagLayout(**recorder_options))
    for topic in (interfaces.DESIGN, interfaces.GROUND_SPEED, interfaces.JOINT_STATES,
                  interfaces.SPEED_COMMAND):
        rec.add_topic(topic.resolved(), topic.type_name, topic.recording_qos())
    for stamp, topic, msg in run.messages():
        rec.write_message(topic.resolved(), msg, stamp)
    rec.close()
    return rec


@dataclass(frozen=True)
class MachineBagOptions:
    """How write_machine_bag records: times on the simulated clock from `epoch` (s), ground
    speed every `speed_period` s and joint states every `joint_period` s; `extra`: (t,
    interfaces.Topic, message) written too, the message stamped at t if it has a header (e.g.
    the sync node's section states)."""

    epoch: float = 1_700_000_000.0
    speed_period: float = 0.05
    joint_period: float = 0.01
    extra: Sequence[tuple[float, interfaces.Topic, Any]] = ()


def write_machine_bag(rows: Sequence[Row], runs: Sequence[RowRun], profile: FieldProfile,
                      design: Design, path: str | Path,
                      options: MachineBagOptions = MachineBagOptions()) -> Recorder:
    """Write a simulated machine (sim.closed_loop.simulate_rows: one RowRun per row of `rows`,
    planter_ros.rows.Row) as a monitor would record its inputs: the design, ground speed with
    the profile's true v and yaw rate, one JointState with every row's joint, and the rows
    record, as `options` say (MachineBagOptions). Returns the closed Recorder."""
    epoch, extra = options.epoch, options.extra
    speed_period, joint_period = options.speed_period, options.joint_period
    def stamp(t: float) -> Time:
        sec, nsec = divmod(int(round((epoch + t) * 1e9)), 1_000_000_000)
        return Time(sec=sec, nanosec=nsec)

    def ns(t: float) -> int:
        return int(round((epoch + t) * 1e9))

    rec = Recorder(path)
    topics = (interfaces.DESIGN, interfaces.GROUND_SPEED, interfaces.JOINT_STATES)
    for topic in topics + tuple({topic for _, topic, _ in extra} - set(topics)):
        rec.add_topic(topic.resolved(), topic.type_name, topic.recording_qos())
    rec.add_metadata(interfaces.ROWS_RECORD, rows_record(rows))
    t = runs[0].t
    rec.write_message(interfaces.DESIGN.resolved(), String(data=to_json(design)), ns(-0.001))
    joints = [row.joint(design.mechanism) for row in rows]
    # (t, kind, index into extra): 0 ground speed, 1 joint states, 2 an extra message
    events = sorted([(float(x), 0, -1) for x in np.arange(0.0, t[-1], speed_period)]
                    + [(float(x), 1, -1) for x in np.arange(0.0, t[-1], joint_period)]
                    + [(float(x), 2, k) for k, (x, _, _) in enumerate(extra)])
    for when, kind, k in events:
        if kind == 2:
            _, topic, msg = extra[k]
            if hasattr(msg, 'header'):
                msg.header.stamp = stamp(when)
            rec.write_message(topic.resolved(), msg, ns(when))
        elif kind == 0:
            twist = TwistStamped()
            twist.header.stamp = stamp(when)
            twist.twist.linear.x = float(profile(when))
            twist.twist.angular.z = float(profile.yaw_rate(when))
            rec.write_message(interfaces.GROUND_SPEED.resolved(), twist, ns(when))
        else:
            i = int(np.searchsorted(t, when))
            state = JointState(name=joints, position=[float(r.angle[i]) for r in runs],
                               velocity=[float(r.speed[i]) for r in runs])
            state.header.stamp = stamp(float(t[i]))
            rec.write_message(interfaces.JOINT_STATES.resolved(), state, ns(when))
    rec.close()
    return rec
