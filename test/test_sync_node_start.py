"""`sync_node` started as the README says: its defaults are the launch file's (socketcan, can0),
and a start that finds no bus or no drive is one line on stderr naming the interface, channel
and node id it tried and the parameters that choose them, with no library log line before it."""
import os
from pathlib import Path
import re
import subprocess
import sys
import uuid

import pytest

from planter_ros.config import spec_of
from planter_ros.drive.config import DriveConfig

pytestmark = pytest.mark.realtime          # (test/conftest.py)

REPO = Path(__file__).resolve().parents[1]
SYNC_NODE = 'from planter_ros.nodes.sync_node import main; raise SystemExit(main())'


def start(*ros_args):
    env = dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    argv = [sys.executable, '-c', SYNC_NODE] + (['--ros-args', *ros_args] if ros_args else [])
    return subprocess.run(argv, capture_output=True, text=True, timeout=60, env=env, cwd=REPO)


def test_the_defaults_are_the_launch_files():
    launch = (REPO / 'launch' / 'planter.launch.py').read_text()
    for name in ('can_interface', 'can_channel'):
        declared = re.search(rf"DeclareLaunchArgument\('{name}', default_value='([^']*)'",
                             launch).group(1)
        assert spec_of(DriveConfig, name).default == declared
    assert (DriveConfig().can_interface, DriveConfig().can_channel) == ('socketcan', 'can0')


def test_no_bus_is_one_line_naming_what_was_tried_and_how_to_choose():
    """On this machine either SocketCAN is missing or can0 is: the default start fails at the
    bus, and says where it looked."""
    out = start()
    assert out.returncode == 1
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    line = lines[0]
    assert line.startswith('sync_node: error: ') and 'open bus: socketcan:can0' in line
    assert 'can_interface=socketcan, can_channel=can0, drive_node_id=1' in line
    assert '-p can_interface:=' in line and '-p can_channel:=' in line


def test_no_drive_on_the_bus_is_one_line_without_library_noise():
    """A virtual bus nobody answers on: canopen logs an SDO abort; it must not reach stderr."""
    channel = f'nobody-{uuid.uuid4().hex[:8]}'
    out = start('-p', 'can_interface:=virtual', '-p', f'can_channel:={channel}',
                '-p', 'step_timeout:=0.2', '-p', 'drive_node_id:=5',
                '-p', 'sdo_timeout:=0.25')     # nobody answers: the default 1 s x 2 only waits
    assert out.returncode == 1
    assert out.stderr.count('\n') == 1, out.stderr
    line = out.stderr.strip()
    assert line.startswith('sync_node: error: drive node 5: identify')
    assert f'virtual:{channel}' in line and 'drive_node_id=5' in line and 'Transfer' not in line
