"""Enable sequence of the CiA 402 master against the simulated drive (virtual CAN bus)."""
import struct

import can
import pytest

from drive_helpers import RPDO1, SDO_RX, drain, rpdo_frames
from planter_ros.drive.cia402 import Cia402Drive, DriveConfig, DriveError
from planter_ros.simdrive.fault_bus import FaultBus
from planter_ros.simdrive.drive import SimulatedDrive
from planter_ros.simdrive.spec import SimSpec

pytestmark = pytest.mark.realtime          # (test/conftest.py)


def test_enable_reaches_operation_enabled_in_profile_velocity(sim, make_drive):
    drive = make_drive()
    drive.connect_and_enable()
    status = drive.status()
    assert status.state == 'OPERATION ENABLED' and status.enabled and not status.fault
    assert sim.state == 'OPERATION ENABLED'
    assert sim.mode_display == 3
    assert sim.nmt_state == 'OPERATIONAL'
    # the master's mapping is in the drive's object dictionary (the EDS default differs)
    od = sim.node
    assert od.sdo[0x1600][0].raw == 2
    assert od.sdo[0x1600][1].raw >> 16 == 0x6040 and od.sdo[0x1600][2].raw >> 16 == 0x60FF
    assert od.sdo[0x1400][5].raw == 200            # RPDO deadline = command_timeout
    assert od.sdo[0x6007].raw == 3                 # quick stop on a communication error
    assert od.sdo[0x1016][1].raw == (127 << 16) | 300
    assert sim.heartbeat_period == pytest.approx(0.05)
    assert status.heartbeat_age < 0.35


def test_target_velocity_is_zero_before_enable(sim, make_drive, spy):
    # a stale non-zero 0x60FF from an earlier session must not move the motor on enable
    sim.node.sdo[0x60FF].raw = 50_000
    drive = make_drive()
    drive.connect_and_enable()
    frames = drain(spy)
    sdo_60ff = [i for i, m in enumerate(frames) if m.arbitration_id == SDO_RX
                and m.data[0] & 0xE0 == 0x20
                and struct.unpack_from('<H', bytes(m.data), 1)[0] == 0x60FF]
    assert sdo_60ff, 'no SDO download of 0x60FF'
    assert struct.unpack_from('<i', bytes(frames[sdo_60ff[0]].data), 4)[0] == 0
    first_rpdo = next(i for i, m in enumerate(frames) if m.arbitration_id == RPDO1)
    assert sdo_60ff[0] < first_rpdo
    enable_frames = rpdo_frames(frames)
    assert [cw for cw, _ in enable_frames][:1] == [0x06]
    assert 0x0F in [cw for cw, _ in enable_frames]
    assert all(v == 0 for _, v in enable_frames)
    assert sim.target_at_enable == 0
    # the NMT start comes after 0x60FF = 0 and the mode confirmation
    nmt_start = next(i for i, m in enumerate(frames)
                     if m.arbitration_id == 0 and m.data[0] == 0x01)
    assert sdo_60ff[0] < nmt_start < first_rpdo


@pytest.mark.parametrize('held, step', [
    ('SWITCH ON DISABLED', "shutdown (0x06)"),
    ('READY TO SWITCH ON', "switch on (0x07)"),
    ('SWITCHED ON', "enable operation (0x0F)"),
])
def test_each_enable_step_times_out_with_a_one_line_error_naming_it(sim, make_drive, held, step):
    sim.hold_state(held)
    drive = make_drive(step_timeout=0.15)
    with pytest.raises(DriveError) as err:
        drive.connect_and_enable()
    message = str(err.value)
    assert step in message and held in message and 'timed out' in message
    assert '\n' not in message
    assert sim.state == held


def test_a_lost_nmt_start_is_repeated_until_the_drive_answers(sim, make_drive, channel):
    """NMT commands are unconfirmed: the pre-operational and the first start command lost on
    the bus, the drive still becomes operational and enabled within the step timeout."""
    bus = FaultBus(can.Bus(interface='virtual', channel=channel))
    bus.drop(0x000, 2, sent=True)
    try:
        drive = make_drive(bus=bus, step_timeout=0.5)
        drive.connect_and_enable()
        assert bus.counts['lost_sent'] == 2
        assert sim.nmt_state == 'OPERATIONAL' and sim.state == 'OPERATION ENABLED'
        drive.shutdown()
    finally:
        bus.shutdown()


def test_no_drive_on_the_bus_names_the_first_step(make_drive):
    # nobody answers: each SDO attempt waits sdo_timeout (the default 1 s, twice, only adds
    # waiting; the error names the first step whatever the timeout)
    drive = make_drive(step_timeout=0.1, sdo_timeout=0.25)
    with pytest.raises(DriveError, match=r'identify \(SDO 0x1000.*no SDO answer') as err:
        drive.connect_and_enable()
    assert '\n' not in str(err.value)


def test_mode_not_confirmed_by_0x6061_is_an_error(channel, make_drive):
    sim = SimulatedDrive(channel)              # it says it offers mode 3 (6502h bit 2) ...
    sim.device.control.supported = ()          # ... but 6060h = 3 leaves 6061h where it was
    sim.start()
    drive = make_drive(step_timeout=0.1)
    try:
        with pytest.raises(DriveError, match=r'0x6061 reads 0 after writing 3'):
            drive.connect_and_enable()
        assert sim.state == 'SWITCH ON DISABLED'           # never enabled
    finally:
        # the master off the bus while its drive still answers (the fixture's shutdown after
        # sim.stop() waited 2 s for a silent bus)
        drive.shutdown()
        sim.stop()


def test_missing_drive_heartbeat_fails_enable(sim, make_drive):
    sim.set_heartbeat_enabled(False)
    drive = make_drive(step_timeout=0.1)
    with pytest.raises(DriveError, match=r"drive heartbeat: no heartbeat within"):
        drive.connect_and_enable()
    assert sim.state == 'SWITCH ON DISABLED'


def test_encoder_resolution_mismatch_is_refused(sim, make_drive):
    drive = make_drive(counts_per_motor_rev=10_000)
    with pytest.raises(DriveError, match=r'4096/1 increments per motor rev but '
                                         r'counts_per_motor_rev=10000'):
        drive.connect_and_enable()


def test_drive_in_fault_at_start_needs_an_explicit_reset(sim, make_drive):
    sim.inject_fault(0x2310)
    drive = make_drive()
    with pytest.raises(DriveError, match=r'FAULT \(error code 0x2310\); call request_fault_reset'):
        drive.connect_and_enable()
    assert sim.state == 'FAULT'
    drive.request_fault_reset()
    drive.connect_and_enable()
    assert sim.state == 'OPERATION ENABLED' and not drive.status().fault


def test_a_drive_left_enabled_by_a_dead_master_is_re_enabled_from_the_bottom(
        channel, sim, make_drive, spy):
    dead_bus = can.Bus(interface='virtual', channel=channel)
    try:
        # long drive-side timeouts so the simulated drive's watchdog stays out of this test
        first = make_drive(bus=dead_bus, command_timeout=5.0, master_heartbeat_timeout=5.0)
        first.connect_and_enable()
    finally:                                 # the old master's process dies: its bus is gone
        if first.canbus.network is not None:
            first.canbus.network.notifier.stop(0.1)
        dead_bus.shutdown()
    assert sim.state == 'OPERATION ENABLED'
    drain(spy)
    second = make_drive()
    second.connect_and_enable()
    controlwords = [cw for cw, _ in rpdo_frames(drain(spy))]
    assert controlwords[0] == 0x00           # disable voltage first, then the normal sequence
    assert {0x06, 0x07, 0x0F} <= set(controlwords)
    assert second.status().enabled


@pytest.mark.parametrize('field, value, allowed', [
    ('drive_node_id', 0, '1..127'),
    ('motor_gear_ratio', float('nan'), '0.01..1000'),
    ('motor_gear_ratio', -2.0, '0.01..1000'),
    ('counts_per_motor_rev', 0, '1..16777216'),
    ('command_timeout', 0.0, '0.02..5 s'),
    ('drive_heartbeat_timeout', 0.05, '> drive_heartbeat_period'),
    ('master_node_id', 1, 'except drive_node_id=1'),
    ('can_channel', '', 'a non-empty name'),
])
def test_bad_config_is_a_one_line_error_naming_value_and_range(field, value, allowed):
    with pytest.raises(DriveError) as err:
        Cia402Drive(DriveConfig(**{field: value}))
    message = str(err.value)
    assert field in message and allowed in message and '\n' not in message


def test_unknown_interface_is_a_drive_error():
    drive = Cia402Drive(DriveConfig(can_interface='no-such-interface', can_channel='x'))
    with pytest.raises(DriveError, match=r'open bus: no-such-interface:x'):
        drive.connect_and_enable()
    drive.shutdown()


def test_sync_flows_from_before_the_nmt_start_through_enabling_and_homing(channel, spy,
                                                                          make_drive):
    """A strict CiA 301 drive acts on a synchronous RPDO only at a SYNC and sends its
    synchronous TPDO only after one: the master's start-up produces SYNC from before the NMT
    start until the drive is enabled and homed (before, it sent none: the enable timed out)."""
    sim = SimulatedDrive(channel, spec=SimSpec(supported_modes=(3, 8)))
    sim.start()
    drive = make_drive(operation_mode='csp')
    try:
        drive.connect_and_enable()
        frames = drain(spy)
        ids = [(m.arbitration_id, bytes(m.data)) for m in frames]
        nmt_start = ids.index((0x000, bytes([0x01, 1])))
        syncs = [i for i, (cob, _) in enumerate(ids) if cob == 0x080]
        assert syncs and syncs[0] < nmt_start and syncs[-1] > nmt_start
        assert drive.canbus.syncs_sent == len(syncs) >= 5
        # gaps between start-up SYNCs: the period, never a silence the drive would notice
        stamps = [frames[i].timestamp for i in syncs]
        assert max(b - a for a, b in zip(stamps, stamps[1:])) < 0.05
        drive.home(37, 1.0, 0.05, timeout=5.0)       # homing in CSP waits on SYNC too
        assert any(m.arbitration_id == 0x080 for m in drain(spy))
        assert drive.status().enabled and sim.mode_display == 8
    finally:
        drive.shutdown()        # while the drive answers (after sim.stop(): 2.3 s of waiting)
        sim.stop()
