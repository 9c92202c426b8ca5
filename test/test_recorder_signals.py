"""A recording process killed or stopped: SIGKILL loses at most ~1 s, SIGTERM/SIGINT finalise.

Each test runs the recorder in a child process (DDS on loopback, a private domain).
"""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from planter_ros import interfaces
from planter_ros.recording.bag_reader import MAGIC, read_recording
from planter_ros.recording.cdr import decode_ground_speed

pytestmark = pytest.mark.realtime(apart=True)   # processes of its own (test/conftest.py)

REPO = Path(__file__).resolve().parents[1]
RATE = 500.0          # messages per second written by the child

WRITER = r'''
import sys, time
from geometry_msgs.msg import TwistStamped
from planter_ros.recording.recorder import BagLayout, Recorder
rec = Recorder(sys.argv[1], BagLayout(flush_period=1.0))
rec.add_topic('/planter/ground_speed', 'geometry_msgs/msg/TwistStamped')
msg = TwistStamped()
start = time.monotonic()
i = 0
while True:
    msg.twist.linear.x = float(i)
    rec.write_message('/planter/ground_speed', msg, time.time_ns())
    i += 1
    if i % 25 == 0:
        print(i, flush=True)
    time.sleep(max(0.0, start + i / {rate} - time.monotonic()))
'''.replace('{rate}', repr(RATE))


def child_env():
    return dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')


def test_sigkill_loses_at_most_about_one_second(tmp_path):
    bag = tmp_path / 'killed.mcap'
    child = subprocess.Popen([sys.executable, '-c', WRITER, str(bag)], stdout=subprocess.PIPE,
                             text=True, env=child_env())
    reported = 0
    try:
        while reported < 1.5 * RATE:     # about 3 s of recording
            line = child.stdout.readline()
            assert line, 'writer died'
            reported = int(line)
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=10)
    rest = child.stdout.read().split()
    written = int(rest[-1]) if rest else reported      # at least this many were written
    rec = read_recording(bag, (interfaces.GROUND_SPEED,))
    assert any('not finalised' in w for w in rec.warnings)
    raws = rec.topics[interfaces.GROUND_SPEED].raw
    _, values = decode_ground_speed(raws)
    recovered = len(values)
    assert np.array_equal(values, np.arange(recovered))          # an intact prefix
    lost = written - recovered
    print(f'SIGKILL: {written}+ written, {recovered} recovered, lost {lost} '
          f'({lost / RATE:.2f} s at {RATE:.0f} msg/s)')
    assert recovered > 0
    assert lost <= 1.25 * RATE + 25          # flush period 1 s, plus the report granularity


MONITOR = 'from planter_ros.nodes.monitor_node import main; main()'


@pytest.mark.parametrize('sig', [signal.SIGTERM, signal.SIGINT])
def test_signal_finalises_the_monitors_bag(tmp_path, sig):
    from mcap.reader import make_reader
    bag = tmp_path / 'monitor.mcap'
    child = subprocess.Popen(
        [sys.executable, '-c', MONITOR, '--ros-args', '-p', f'bag_path:={bag}',
         '-p', 'flush_period:=0.5'],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=child_env())
    try:
        deadline = time.monotonic() + 30
        # running once its first diagnostics (1 Hz, recorded through its own subscription)
        # reached the file
        while not (bag.exists() and bag.stat().st_size > 2000):
            assert child.poll() is None, child.stdout.read()
            assert time.monotonic() < deadline
            time.sleep(0.1)
        time.sleep(1.0)
        child.send_signal(sig)
        out, _ = child.communicate(timeout=20)
    finally:
        if child.poll() is None:
            child.kill()
    assert child.returncode == 0, out
    data = bag.read_bytes()
    assert data.endswith(MAGIC)
    with open(bag, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary.statistics.message_count >= 1
        assert 'rosbag2' in {m.name for m in reader.iter_metadata()}
    assert 'Traceback' not in out
