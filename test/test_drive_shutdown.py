"""Clean shutdown of the CiA 402 master, as seen on the bus."""
import pytest

from drive_helpers import NODE_ID, control_loop, drain, rpdo_frames
from planter_ros.drive.cia402 import DriveError

pytestmark = pytest.mark.realtime          # (test/conftest.py)


def test_shutdown_sequence_on_the_bus(enabled, spy):
    drive, sim = enabled
    assert control_loop(drive, 2.0, until=lambda: abs(drive.status().velocity - 2.0) < 0.02)
    drain(spy)
    drive.shutdown()
    frames = drain(spy)
    ids = [m.arbitration_id for m in frames]
    rpdos = rpdo_frames(frames)
    # 0x60FF = 0 first (drive still enabled so it ramps down), then the disable controlword
    assert rpdos[0] == (0x0F, 0)
    assert all(v == 0 for _, v in rpdos)
    first_disable = next(i for i, (cw, _) in enumerate(rpdos) if cw == 0x06)
    assert all(cw == 0x0F for cw, _ in rpdos[:first_disable])
    # then NMT pre-operational for our node, after the last command frame
    nmt = [i for i, m in enumerate(frames) if m.arbitration_id == 0]
    assert [bytes(frames[i].data) for i in nmt] == [bytes([0x80, NODE_ID])]
    last_rpdo = max(i for i, cid in enumerate(ids) if cid == 0x200 + NODE_ID)
    assert nmt[0] > last_rpdo
    # the drive stopped the motor, is disabled and pre-operational, no watchdog trip
    assert abs(sim.motor_velocity) < 0.2
    assert sim.state == 'READY TO SWITCH ON'
    assert sim.nmt_state == 'PRE-OPERATIONAL'
    assert sim.node.sdo[0x1016][1].raw == 0        # it no longer watches our heartbeat
    assert sim.watchdog_trips == []


def test_shutdown_is_idempotent_and_ends_the_session(enabled, spy):
    drive, _ = enabled
    drive.shutdown()
    drain(spy)
    drive.shutdown()
    assert drain(spy) == []
    with pytest.raises(DriveError, match='not connected'):
        drive.send_velocity(0.5)


def test_shutdown_without_a_drive_returns(make_drive):
    # nobody answers: a short sdo_timeout (the default 1 s, twice, only adds waiting)
    drive = make_drive(step_timeout=0.05, sdo_timeout=0.25)
    with pytest.raises(DriveError):
        drive.connect_and_enable()
    drive.shutdown()                                # no drive, nothing to wait for
    drive.shutdown()


def test_reconnect_after_shutdown(enabled):
    drive, sim = enabled
    drive.shutdown()
    drive.connect_and_enable()
    assert control_loop(drive, 1.0, until=lambda: abs(drive.status().velocity - 1.0) < 0.01)
    assert sim.state == 'OPERATION ENABLED'
