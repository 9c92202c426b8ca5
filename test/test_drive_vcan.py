"""The same master and simulated drive over SocketCAN `vcan0` (skipped where there is none).

Set up on a Linux machine with:  sudo modprobe vcan && sudo ip link add dev vcan0 type vcan
&& sudo ip link set up vcan0. This kernel (the CI container) has no AF_CAN: the module skips.
"""
import socket
import struct
from pathlib import Path

import can
import pytest

from drive_helpers import control_loop
from planter_ros.drive.cia402 import Cia402Drive, DriveConfig
from planter_ros.drive.simulated_drive import SimulatedDrive

VCAN = 'vcan0'
NODE_ID = 42        # away from node 1, in case a real drive shares a test bench bus


def _vcan_missing() -> str:
    if not hasattr(socket, 'AF_CAN'):
        return 'this Python has no AF_CAN'
    try:
        socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW).close()
    except OSError as exc:
        return f'the kernel has no AF_CAN ({exc.strerror})'
    if not Path('/sys/class/net', VCAN).exists():
        return f'no {VCAN} interface'
    return ''


pytestmark = [pytest.mark.realtime,          # (test/conftest.py)
              pytest.mark.skipif(bool(_vcan_missing()), reason=_vcan_missing() or 'vcan present')]


@pytest.fixture
def vcan_sim():
    bus = can.Bus(interface='socketcan', channel=VCAN)
    sim = SimulatedDrive(bus, node_id=NODE_ID)
    sim.start()
    yield sim
    sim.stop()
    bus.shutdown()


@pytest.fixture
def vcan_drive():
    drive = Cia402Drive(DriveConfig(can_interface='socketcan', can_channel=VCAN,
                                    drive_node_id=NODE_ID,
                                    motor_gear_ratio=12.5))
    yield drive
    drive.shutdown()


@pytest.fixture
def vcan_spy():
    bus = can.Bus(interface='socketcan', channel=VCAN,
                  can_filters=[{'can_id': 0x200 + NODE_ID, 'can_mask': 0x7FF}])
    yield bus
    bus.shutdown()


def test_enable_track_and_shutdown_over_vcan(vcan_sim, vcan_drive, vcan_spy):
    vcan_drive.connect_and_enable()
    assert vcan_sim.state == 'OPERATION ENABLED' and vcan_sim.target_at_enable == 0
    assert control_loop(vcan_drive, 2.0,
                        until=lambda: abs(vcan_drive.status().velocity - 2.0) < 0.01)
    assert vcan_sim.motor_velocity == pytest.approx(25.0, rel=0.01)
    vcan_drive.shutdown()
    assert vcan_sim.state == 'READY TO SWITCH ON' and vcan_sim.nmt_state == 'PRE-OPERATIONAL'
    commands = []
    while (msg := vcan_spy.recv(timeout=0)) is not None:
        commands.append(struct.unpack_from('<Hi', bytes(msg.data)))
    assert commands[-1] == (0x06, 0)                  # the last command: disable, speed 0
