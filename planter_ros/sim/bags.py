"""Bags of simulated runs, written straight through the recorder (no ROS graph): the same
topics, types and QoS the monitor records (interfaces.MONITOR_INPUTS), log time = measurement
time. Fast; for the replay benchmark and the recording tests."""

from planter_ros import interfaces
from planter_ros.recording.recorder import Recorder


def write_input_bag(run, path, **recorder_options):
    """Write a run's measured inputs (design, ground_speed, joint_states, speed_command) into a
    bag at `path`. Returns the closed Recorder."""
    rec = Recorder(path, **recorder_options)
    for topic in (interfaces.DESIGN, interfaces.GROUND_SPEED, interfaces.JOINT_STATES,
                  interfaces.SPEED_COMMAND):
        rec.add_topic(topic.resolved(), topic.type_name, topic.recording_qos())
    for stamp, topic, msg in run.messages():
        rec.write_message(topic.resolved(), msg, stamp)
    rec.close()
    return rec
