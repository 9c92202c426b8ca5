"""Speed commands and feedback through the CiA 402 master and the simulated drive."""
import math

import pytest

from drive_helpers import control_loop, drain, rpdo_frames
from planter_ros.drive.cia402 import DriveError

pytestmark = pytest.mark.realtime          # (test/conftest.py)


@pytest.mark.parametrize('speed', [2.0, -0.7])
def test_measured_speed_converges_to_the_command_through_the_gear(enabled, speed):
    drive, sim = enabled                         # gear ratio 12.5
    converged = control_loop(
        drive, speed, until=lambda: abs(drive.status().velocity - speed) < 0.005 * abs(speed))
    assert converged, drive.status()
    assert sim.motor_velocity == pytest.approx(12.5 * speed, rel=0.01)
    assert sim.target_velocity == pytest.approx(12.5 * speed, rel=1e-3)
    status = drive.status()
    assert status.commanded_velocity == pytest.approx(speed, rel=1e-3)
    assert status.state == 'OPERATION ENABLED' and status.enabled and not status.fault
    # the mechanism angle follows the integral of the speed, in the command's direction
    start = status.position
    control_loop(drive, speed, timeout=0.3)
    travelled = drive.status().position - start
    assert math.copysign(1.0, travelled) == math.copysign(1.0, speed)
    assert abs(travelled) == pytest.approx(0.3 * abs(speed), rel=0.35)


def test_velocity_units_on_the_bus_are_encoder_increments_per_second(enabled, spy):
    drive, _ = enabled
    drain(spy)
    drive.send_velocity(1.0)                     # 1 rad/s at the mechanism, gear 12.5
    (controlword, counts), = rpdo_frames(drain(spy))
    assert controlword == 0x0F
    assert counts == round(12.5 * 4096 / (2 * math.pi))


def test_position_is_unwrapped_across_the_32_bit_counter(enabled):
    drive, sim = enabled
    with sim._lock:
        sim._position = 2**31 - 2000.0           # just below the int32 wrap of 0x6064
    control_loop(drive, 5.0, timeout=0.4)        # ~ +0.4 s * 5 rad/s * 12.5 * 652 counts/rad
    status = drive.status()
    counts = status.position * 12.5 * 4096 / (2 * math.pi)
    assert counts > 2**31                        # kept counting up, no jump of -2^32


@pytest.mark.parametrize('bad', [float('nan'), float('inf'), -float('inf'), 1e12])
def test_non_finite_or_huge_speed_is_a_drive_error_and_sends_nothing(enabled, spy, bad):
    drive, _ = enabled
    drain(spy)
    with pytest.raises(DriveError, match='rad/s') as err:
        drive.send_velocity(bad)
    assert '\n' not in str(err.value)
    assert rpdo_frames(drain(spy)) == []


def test_commands_before_connect_are_refused(make_drive):
    drive = make_drive()
    with pytest.raises(DriveError, match='not connected'):
        drive.send_velocity(1.0)
    with pytest.raises(DriveError, match='not connected'):
        drive.send_heartbeat()
    status = drive.status()
    assert status.state == 'UNKNOWN' and status.heartbeat_age == math.inf and not status.enabled
