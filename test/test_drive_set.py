"""Several drives on one bus (one canopen Network, one master heartbeat): enabled at once, an
absent drive left out while the others are kept fed, faults per drive, shutdown of all."""
import time

import can
import pytest

from drive_helpers import wait_until
from planter_ros.drive.cia402 import DriveConfig
from planter_ros.drive.drive_set import DriveSet
from planter_ros.drive.simulated_drive import SimulatedBus

pytestmark = pytest.mark.realtime          # (test/conftest.py)


def test_drives_enable_at_once_an_absent_one_is_left_out_and_the_others_are_fed(channel):
    sims = SimulatedBus(channel, [1, 2])
    sims.start()
    spy = can.Bus(interface='virtual', channel=channel)
    drives = DriveSet(DriveConfig(can_interface='virtual', can_channel=channel, step_timeout=0.3),
                      {'a': 1, 'b': 2, 'c': 3})
    try:
        failed = drives.enable()
        assert list(failed) == ['c'] and 'drive node 3' in str(failed['c'])
        assert set(drives.enabled) == {'a', 'b'}
        # while c was waited for (> 0.3 s, more than the 0.2 s command timeout), a and b were
        # commanded: no watchdog tripped
        assert all(not d.watchdog_trips for d in sims.drives)
        assert [d.state for d in sims.drives] == ['OPERATION ENABLED'] * 2
        a, b = drives.enabled['a'], drives.enabled['b']
        assert a.canbus is b.canbus and a.node.network is b.node.network   # one Network

        def step():
            drives.send_heartbeat()
            a.send_velocity(2.0)
            b.send_velocity(3.0)
            return (abs(sims.drives[0].motor_velocity - 2.0) < 0.02
                    and abs(sims.drives[1].motor_velocity - 3.0) < 0.02)
        assert wait_until(step, timeout=3.0)
        # one heartbeat frame for the bus, not one per drive
        while spy.recv(timeout=0) is not None:
            pass
        drives.send_heartbeat()
        a.send_velocity(2.0)
        b.send_velocity(3.0)
        frames = []
        end = time.monotonic() + 0.05
        while time.monotonic() < end:
            msg = spy.recv(timeout=0.01)
            if msg is not None:
                frames.append(msg)
        assert sum(m.arbitration_id == 0x77F for m in frames) == 1
        # a fault on b is b's only
        sims.drives[1].inject_fault(0x7500)
        assert wait_until(lambda: (a.send_velocity(2.0), b.send_velocity(3.0),
                                   drives.send_heartbeat(), b.status().fault)[-1])
        assert not a.status().fault and a.status().enabled
    finally:
        drives.shutdown()
        spy.shutdown()
        sims.stop()
    assert sims.drives[0].state != 'OPERATION ENABLED'
    assert sims.drives[0].target_velocity == 0.0
