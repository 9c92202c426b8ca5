"""No feedback lost on its way to the recording: every sample the command process sends reaches
joint_states with its own stamp, however long the sync node's shell stalls (its DDS, its GIL,
here the whole process stopped), and a shell that stalls too long for the queue is said, not
silent (doc/command.md, "Feedback to the recording")."""
import logging
import os
import signal
import threading
import time
import uuid

import pytest

from planter_ros import interfaces
from planter_ros.command import inbox as inbox_module
from planter_ros.command.client import CommandClient
from planter_ros.command.settings import CommandSettings
from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.control.machine_law import TurnConfig
from planter_ros.control.phase_lock import PhaseLockConfig
from planter_ros.drive.config import DriveConfig
from planter_ros.rows import Row
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
from planter_ros.sensing.row_speed import YawRateLimits

STALL = 0.6          # s the sync node's process is stopped


def _client(log):
    """A client that is never started: its reader's side is fed by hand (pure queue tests)."""
    return CommandClient(
        CommandSettings(DriveConfig(), SyncLoopConfig(), [Row(0, 'left', 0.0, 1)],
                        (PhaseLockConfig(), GroundSpeedLimits(), YawRateLimits(),
                         TurnConfig())),
        log=lambda level, text: log.append((level, text)))


def _fb(stamp):
    return {'feedback': [['left/sun_bar', stamp, 1.0, stamp]]}


def test_samples_wait_in_order_and_a_repeated_sample_is_not_published_twice():
    client = _client([])
    for stamp in (1.00, 1.01, 1.01, 1.02):           # the process repeats the last one
        client._handle('fb', _fb(stamp))
    taken = client.take_feedback()
    assert [batch[0].stamp for batch in taken] == [1.00, 1.01, 1.02]
    assert client.take_feedback() == []
    assert client.feedback_dropped == 0


def test_a_full_queue_drops_the_oldest_counts_it_and_says_so_once(monkeypatch):
    monkeypatch.setattr(inbox_module, 'FEEDBACK_QUEUE', 5)
    log = []
    client = _client(log)
    for k in range(8):
        client._handle('fb', _fb(1.0 + 0.01 * k))
    assert [round(batch[0].stamp, 2) for batch in client.take_feedback()] == \
        [1.03, 1.04, 1.05, 1.06, 1.07]
    assert client.feedback_dropped == 3
    errors = [text for level, text in log if level >= logging.ERROR]
    assert len(errors) == 1 and 'joint feedback lost' in errors[0]
    report = client.process_report(time.monotonic())
    assert '3 feedback sample(s) dropped' in report.message
    assert ('feedback samples dropped', 3) in report.values


@pytest.mark.realtime
def test_a_stalled_shell_publishes_every_sample_afterwards_with_its_own_stamp():
    """The demo's command path (sync node shell + command process in CSP + drives' process);
    the shell's process is stopped for 0.6 s while the machine runs: the recorder still gets a
    joint_states sample for every SYNC, none further apart than two SYNC periods."""
    import rclpy
    from geometry_msgs.msg import TwistStamped
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import String

    from planter_ros.host.dds_domain import claim_private_domain
    from planter_ros.demo.sync_process import SyncProcess, SyncProcessSettings
    from planter_ros.design import to_json
    from planter_ros.sim.runs import five_bar_design_message

    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    domain = claim_private_domain()
    rows = (('rows', ['r1', 'r2']), ('r1.lateral_offset', 0.25), ('r1.drive_node_id', 1),
            ('r2.lateral_offset', -0.25), ('r2.drive_node_id', 2))
    channel = f'planter-test-fb-{uuid.uuid4().hex[:8]}'
    sync = SyncProcess(SyncProcessSettings(
        domain, channel, (1, 2), interfaces.NAMESPACE,
        rows + (('can_interface', 'virtual'), ('can_channel', channel)), 'error',
        {'supported_modes': [3, 8]}, command_process=True))
    context = Context()
    rclpy.init(context=context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    node = Node('recorder', context=context, namespace=interfaces.NAMESPACE)
    stamps = []
    recording = threading.Event()

    def on_joint(msg):
        if recording.is_set():
            stamps.append(msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec)
    # the recorder here is the test's instrument, not the product's: a queue deep enough for
    # the whole run (its loop takes one sample per turn, and a loaded host may slow the loop
    # below the 100 Hz the samples come at; the recorder's own depth, 100, would then drop
    # the oldest and show a hole the shell never made)
    interfaces.JOINT_STATES.subscribe(node, on_joint,
                                      qos=interfaces.JOINT_STATES.recording_qos().deeper(2000))
    speed_pub = interfaces.GROUND_SPEED.publisher(node)
    design_pub = interfaces.DESIGN.publisher(node)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    period = DriveConfig().sync_period
    speed = TwistStamped()
    speed.twist.linear.x = 0.3

    def run(seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            speed_pub.publish(speed)
            sync.poll(0.0)
            executor.spin_once(timeout_sec=0.02)
    try:
        sync.wait_for('ready', 120.0)
        design_pub.publish(String(data=to_json(five_bar_design_message(spacing=0.2))))
        # joint_states name the joints of the design in force: wait for it (DDS discovery
        # of the design topic can take a while on a loaded host), then for a steady run
        deadline = time.monotonic() + 30.0
        while sync.status.spacing is None:
            assert time.monotonic() < deadline, 'the design never came into force'
            run(0.1)
        run(1.0)
        recording.set()
        run(0.5)
        stopped_at = time.time()
        os.kill(sync.process.pid, signal.SIGSTOP)
        try:
            run(STALL)
        finally:
            os.kill(sync.process.pid, signal.SIGCONT)
        run(1.5)
        recording.clear()
    finally:
        report = sync.stop()
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()
    assert report is not None, 'the sync process sent no report'
    trips = report.drives.watchdog_trips
    assert stamps, 'no joint_states recorded'
    ordered = sorted(stamps)
    holes = [b - a for a, b in zip(ordered, ordered[1:])]
    # the stall lies inside the recorded span, and its samples are there
    assert ordered[0] < stopped_at < stopped_at + STALL < ordered[-1]
    during = [t for t in ordered if stopped_at <= t <= stopped_at + STALL]
    assert len(during) >= 0.8 * STALL / period, (len(during), trips)
    assert max(holes) <= 2 * period, f'largest joint_states hole {max(holes) * 1e3:.1f} ms'
    assert len(set(stamps)) == len(stamps), 'a sample was published twice'
    assert not trips
