"""Faults, EMCY, explicit reset, lost heartbeats, the drive's watchdog and CAN send errors."""

import can
import pytest
from can.interfaces.virtual import VirtualBus

from drive_helpers import control_loop, drain, rpdo_frames, wait_until
from planter_ros.drive.cia402 import DriveError

pytestmark = pytest.mark.realtime          # (test/conftest.py)


def _reach_speed(drive, speed=2.0):
    assert control_loop(drive, speed, until=lambda: abs(drive.status().velocity - speed) < 0.02)


def test_fault_bit_and_emcy_stop_commands_until_an_explicit_reset(enabled, spy):
    drive, sim = enabled
    _reach_speed(drive)
    sim.inject_fault(0x7500)
    assert control_loop(drive, 2.0, until=lambda: drive.status().state == 'FAULT')
    status = drive.status()
    assert status.fault and status.error_code == 0x7500 and not status.enabled
    assert 'EMCY 0x7500' in status.fault_reason
    # commands are refused (zero speed, no state change) for as long as nobody resets
    drain(spy)
    control_loop(drive, 2.0, timeout=0.3)
    frames = rpdo_frames(drain(spy))
    assert frames and all(v == 0 and not cw & 0x80 for cw, v in frames)
    assert sim.state == 'FAULT' and sim.target_velocity == 0.0
    assert drive.status().fault
    # explicit reset: the reset edge, then the way back to OPERATION ENABLED, then speed
    drive.request_fault_reset()
    assert control_loop(drive, 2.0, until=lambda: drive.status().enabled)
    controlwords = [cw for cw, _ in rpdo_frames(drain(spy))]
    assert controlwords[0] == 0x80
    assert controlwords[1:4] == [0x06, 0x07, 0x0F]
    status = drive.status()
    assert not status.fault and status.error_code == 0 and status.fault_reason == ''
    _reach_speed(drive)
    assert sim.motor_velocity == pytest.approx(25.0, rel=0.02)


def test_emcy_alone_is_a_fault_commands_go_to_zero_and_reset_clears_it(enabled):
    drive, sim = enabled
    _reach_speed(drive)
    sim.send_emcy(0x4210)                        # over-temperature warning, drive stays enabled
    assert control_loop(drive, 2.0, until=lambda: drive.status().fault)
    assert drive.status().error_code == 0x4210
    assert control_loop(drive, 2.0, until=lambda: abs(sim.motor_velocity) < 0.01)
    assert sim.state == 'OPERATION ENABLED' and sim.target_velocity == 0.0
    drive.request_fault_reset()
    _reach_speed(drive)
    assert not drive.status().fault


def test_a_persistent_fault_gets_one_reset_edge_per_request_never_a_loop(enabled, spy):
    drive, sim = enabled
    sim.inject_fault(0x3210, persistent=True)
    assert control_loop(drive, 1.0, until=lambda: drive.status().state == 'FAULT')
    drain(spy)
    drive.request_fault_reset()
    assert control_loop(drive, 1.0, until=lambda: not drive.status().resetting)
    control_loop(drive, 1.0, timeout=0.2)        # and after giving up: still no new edge
    controlwords = [cw for cw, _ in rpdo_frames(drain(spy))]
    rising_edges = sum(1 for a, b in zip([0] + controlwords, controlwords)
                       if b & 0x80 and not a & 0x80)
    assert rising_edges == 1
    status = drive.status()
    assert status.fault and status.state == 'FAULT' and status.error_code == 0x3210


def test_lost_drive_heartbeat_is_seen_and_latched(enabled):
    drive, sim = enabled
    _reach_speed(drive)
    assert drive.status().heartbeat_age < drive.config.drive_heartbeat_timeout
    sim.set_heartbeat_enabled(False)
    assert control_loop(drive, 2.0, until=lambda: drive.status().heartbeat_lost)
    status = drive.status()
    assert status.heartbeat_age > drive.config.drive_heartbeat_timeout
    assert status.fault and status.fault_reason == 'drive heartbeat lost'
    assert status.error_code == 0x8130
    assert control_loop(drive, 2.0, until=lambda: sim.target_velocity == 0.0)
    # the heartbeat comes back: still latched until the explicit reset
    sim.set_heartbeat_enabled(True)
    assert control_loop(drive, 2.0, until=lambda: not drive.status().heartbeat_lost)
    assert drive.status().fault
    drive.request_fault_reset()
    _reach_speed(drive)


def test_drive_watchdog_quick_stops_when_commands_stop(enabled):
    drive, sim = enabled
    _reach_speed(drive)
    # the master process hangs: no more command frames and no more heartbeats
    assert wait_until(lambda: sim.quick_stopped, timeout=2.0)
    reason, code = sim.watchdog_trips[0]
    assert code in (0x8250, 0x8130)
    assert wait_until(lambda: abs(sim.motor_velocity) < 0.01, timeout=2.0)
    assert sim.state in ('QUICK STOP ACTIVE', 'SWITCH ON DISABLED')
    # the master, when it runs again, sees why (EMCY) and waits for an explicit reset
    status = drive.status()
    assert status.fault and status.error_code == code and not status.enabled


def test_rpdo_deadline_alone_trips_the_watchdog(enabled):
    drive, sim = enabled
    _reach_speed(drive)
    # heartbeats keep coming (say, from a thread that survived) but commands stop
    assert wait_until(lambda: (drive.send_heartbeat(), sim.quick_stopped)[1], timeout=2.0,
                      period=0.02)
    assert sim.watchdog_trips[0][1] == 0x8250


def test_master_heartbeat_alone_trips_the_watchdog(enabled):
    drive, sim = enabled
    _reach_speed(drive)
    # commands keep coming but the heartbeat stopped
    assert wait_until(lambda: (drive.send_velocity(2.0), sim.quick_stopped)[1], timeout=2.0,
                      period=0.01)
    assert sim.watchdog_trips[0][1] == 0x8130


class FailingBus(VirtualBus):
    """A virtual bus whose transmit fails on demand, like a full SocketCAN tx queue."""
    failing = False

    def send(self, msg, timeout=None):
        if self.failing:
            raise can.CanOperationError('Failed to transmit: No buffer space available '
                                        '[Error Code 105]')
        super().send(msg, timeout)


@pytest.fixture
def failing_bus(channel):
    bus = FailingBus(channel=channel)
    yield bus
    bus.shutdown()


def test_can_send_error_is_a_drive_error_not_a_crash(sim, make_drive, failing_bus):
    drive = make_drive(bus=failing_bus)
    drive.connect_and_enable()
    failing_bus.failing = True
    for call in (lambda: drive.send_velocity(1.0), drive.send_heartbeat):
        with pytest.raises(DriveError, match='CAN send of .* failed .*No buffer space') as err:
            call()
        assert '\n' not in str(err.value)
    assert drive.status().state == 'OPERATION ENABLED'        # feedback still flows
    failing_bus.failing = False                               # the bus recovers
    control_loop(drive, 1.0, until=lambda: abs(drive.status().velocity - 1.0) < 0.01)
    failing_bus.failing = True
    drive.shutdown()                                          # never raises


def test_can_send_error_during_enable_names_the_step(sim, make_drive, failing_bus):
    failing_bus.failing = True
    drive = make_drive(bus=failing_bus)
    with pytest.raises(DriveError, match='NMT pre-operational.*No buffer space'):
        drive.connect_and_enable()


def test_send_error_in_sdo_configuration_names_the_step(sim, make_drive, failing_bus, monkeypatch):
    drive = make_drive(bus=failing_bus)
    sent = []

    def send(msg, timeout=None):                              # NMT passes, the first SDO fails
        sent.append(msg)
        if len(sent) > 1:
            raise can.CanOperationError('bus-off')
        VirtualBus.send(failing_bus, msg, timeout)
    monkeypatch.setattr(failing_bus, 'send', send)
    with pytest.raises(DriveError,
                       match=r'identify \(SDO 0x1000 device type\): CAN send failed.*bus-off'):
        drive.connect_and_enable()
