"""The simulated drive is a strict CiA 301 / CiA 402 device (planter_ros/simdrive):

* its object dictionary is any EDS, and what it answers for an object the file lacks or holds
  read-only is what canopen's own `LocalNode` (a server we did not write) answers for the same
  file: the same SDO abort codes (records; canopen's arrays make up members 1..255, ours keep to
  the file);
* CiA 301 on PDO timing (its transmission-type table): "synchronous (0..240): the SYNC is the
  trigger to actuate the previous synchronous RPDO and to update the data of the following
  synchronous TPDO; 254/255: asynchronous". A synchronous RPDO acts only at the next SYNC, a
  synchronous TPDO is sent only after a SYNC, an event RPDO acts at once, an event TPDO goes on
  its timer without any SYNC;
* it interpolates over 60C2h, sets the error register's bit 0 with any error bit, and after
  homing takes CSP up from where the shaft is (no following error).
"""
from __future__ import annotations

import struct
import time
import uuid

import can
import canopen
from canopen.sdo import SdoAbortedError
import pytest

from cli_helpers import REPO
from drive_helpers import drain, wait_until
from planter_ros.drive.cia402 import Cia402Drive, DriveConfig
from planter_ros.drive.states import OPERATION_ENABLED, SWITCH_ON_DISABLED
from planter_ros.drive.words import SW_FOLLOWING_ERROR
from planter_ros.simdrive.drive import SimulatedDrive
from planter_ros.simdrive.node import StrictNode
from planter_ros.simdrive.spec import SimSpec

EDS = REPO / 'test' / 'eds'
NODE = 5

pytestmark = pytest.mark.realtime


def abort_code(call, *args, **kwargs) -> int | None:
    try:
        call(*args, **kwargs)
    except SdoAbortedError as exc:
        return exc.code
    return None


@pytest.mark.parametrize('profile', sorted(p.stem for p in EDS.glob('*.eds')))
def test_absent_and_read_only_objects_abort_as_canopen_localnode_does(profile):
    path = str(EDS / f'{profile}.eds')
    ours, reference = StrictNode(NODE, path), canopen.LocalNode(NODE, path)
    dictionary = reference.object_dictionary
    probes = [(index, 0) for index in (0x1006, 0x1016, 0x603F, 0x6007, 0x607C, 0x607E, 0x2345,
                                       0x60FF, 0x6502)]
    for index in dictionary:
        obj = dictionary[index]
        if isinstance(obj, canopen.objectdictionary.ODRecord):
            probes += [(index, sub) for sub in range(0, 8)]
        elif isinstance(obj, canopen.objectdictionary.ODVariable):
            probes.append((index, 0))
    compared = 0
    for index, sub in probes:
        read = [abort_code(n.get_data, index, sub, check_readable=True)
                for n in (ours, reference)]
        assert read[0] == read[1], (profile, hex(index), sub)
        if read[0] is None:
            data = ours.get_data(index, sub)
            written = [abort_code(n.set_data, index, sub, data, check_writable=True)
                       for n in (ours, reference)]
            if 'w' not in dictionary.get_variable(index, sub).access_type:
                assert written == [0x06010002, 0x06010002], (profile, hex(index), sub)
        compared += 1
    assert compared > 100


def test_mapping_capacity_mappability_and_valid_pdos_are_enforced():
    idm = StrictNode(NODE, str(EDS / 'idm_like.eds'))

    def write(node, index, sub, value, fmt='<I'):
        return abort_code(node.set_data, index, sub, struct.pack(fmt, value),
                          check_writable=True)
    assert write(idm, 0x1600, 0, 0, '<B') == 0x08000022     # RPDO1 valid: mapping locked
    assert write(idm, 0x1400, 1, 0x80000205) is None        # invalid now
    assert write(idm, 0x1600, 1, 0x60400010) == 0x08000022  # count not 0 yet
    assert write(idm, 0x1600, 0, 0, '<B') is None
    assert write(idm, 0x1600, 1, 0x60400010) is None
    assert write(idm, 0x1600, 0, 2, '<B') == 0x06040042     # takes one entry
    assert write(idm, 0x1600, 0, 1, '<B') is None
    assert write(idm, 0x1400, 1, 0x00000305) is None        # valid again, another COB-ID
    assert write(idm, 0x1400, 1, 0x00000306) == 0x06090030  # bits 0..29 while valid
    assert write(idm, 0x1400, 2, 245, '<B') == 0x06090030   # reserved transmission type
    prl = StrictNode(NODE, str(EDS / 'prl_like.eds'))
    assert write(prl, 0x1400, 1, 0x80000205) is None
    assert write(prl, 0x1600, 0, 0, '<B') is None
    assert write(prl, 0x1600, 2, 0x607A0020) == 0x06040041  # not PDO-mappable
    assert write(prl, 0x1600, 2, 0x23450020) == 0x06040041  # no such object
    assert write(prl, 0x1600, 2, 0x60FF0010) == 0x06040041  # a length unlike its type's


@pytest.fixture
def wire():
    """(simulated drive on the project's EDS, a canopen SDO client, a raw bus, the channel)."""
    channel = f'planter-test-{uuid.uuid4().hex}'
    sim = SimulatedDrive(channel, node_id=NODE, spec=SimSpec(supported_modes=(3, 8)))
    sim.start()
    raw = can.Bus(interface='virtual', channel=channel)
    network = canopen.Network(can.Bus(interface='virtual', channel=channel))
    network.connect()
    client = network.add_node(NODE, canopen.objectdictionary.ObjectDictionary())
    yield sim, client.sdo, raw, channel
    network.disconnect()
    raw.shutdown()
    sim.stop()


def configure(sdo, rpdo_type: int, tpdo_type: int, event_ms: int = 0) -> None:
    """RPDO1 = controlword, TPDO1 = statusword, by SDO in CiA 301's order."""
    def put(index, sub, value, fmt):
        sdo.download(index, sub, struct.pack(fmt, value))
    for comm, mapping, cob, entry, trans in ((0x1400, 0x1600, 0x200, 0x60400010, rpdo_type),
                                              (0x1800, 0x1A00, 0x180, 0x60410010, tpdo_type)):
        put(comm, 1, 0x80000000 | cob + NODE, '<I')
        put(comm, 2, trans, '<B')
        put(mapping, 0, 0, '<B')
        put(mapping, 1, entry, '<I')
        put(mapping, 0, 1, '<B')
        put(comm, 1, cob + NODE, '<I')
    put(0x1800, 5, event_ms, '<H')
    for number in (1, 2, 3):                       # the other TPDOs off
        put(0x1801 + number - 1, 1, 0x80000000 | 0x280 + 0x100 * (number - 1) + NODE, '<I')


def statuswords(frames) -> list[int]:
    return [struct.unpack_from('<H', bytes(m.data))[0] for m in frames
            if m.arbitration_id == 0x180 + NODE]


def test_a_synchronous_rpdo_acts_at_the_next_sync_and_its_tpdo_comes_only_after_one(wire):
    sim, sdo, raw, _ = wire
    configure(sdo, rpdo_type=1, tpdo_type=1)
    raw.send(can.Message(arbitration_id=0, data=[1, NODE], is_extended_id=False))   # NMT start
    assert wait_until(lambda: sim.nmt_state == 'OPERATIONAL', 1.0)
    time.sleep(0.05)
    drain(raw)
    raw.send(can.Message(arbitration_id=0x200 + NODE, data=struct.pack('<H', 0x06),
                         is_extended_id=False))
    time.sleep(0.1)
    assert sim.state == SWITCH_ON_DISABLED             # received, not acted on: no SYNC yet
    assert statuswords(drain(raw)) == []               # and no synchronous TPDO either
    raw.send(can.Message(arbitration_id=0x80, data=b'', is_extended_id=False))      # SYNC
    assert wait_until(lambda: sim.state == 'READY TO SWITCH ON', 0.5)
    time.sleep(0.05)
    # the TPDO after that SYNC carries the state sampled at it: before the RPDO acted
    assert statuswords(drain(raw)) == [0x0240]
    raw.send(can.Message(arbitration_id=0x80, data=b'', is_extended_id=False))
    time.sleep(0.05)
    assert statuswords(drain(raw)) == [0x0231]


def test_event_pdos_act_and_report_without_any_sync(wire):
    sim, sdo, raw, _ = wire
    configure(sdo, rpdo_type=255, tpdo_type=255, event_ms=20)
    raw.send(can.Message(arbitration_id=0, data=[1, NODE], is_extended_id=False))
    assert wait_until(lambda: sim.nmt_state == 'OPERATIONAL', 1.0)
    raw.send(can.Message(arbitration_id=0x200 + NODE, data=struct.pack('<H', 0x06),
                         is_extended_id=False))
    assert wait_until(lambda: sim.state == 'READY TO SWITCH ON', 0.2)
    drain(raw)
    time.sleep(0.2)
    words = statuswords(drain(raw))
    assert 6 <= len(words) <= 12 and set(words) == {0x0231}    # every 20 ms, no SYNC sent


def test_the_drive_interpolates_over_60c2_not_1006(wire):
    sim, sdo, _, _ = wire
    sdo.download(0x1006, 0, struct.pack('<I', 10_000))
    sdo.download(0x60C2, 2, struct.pack('<b', -4))
    sdo.download(0x60C2, 1, struct.pack('<B', 25))
    assert sim.interpolation_period == pytest.approx(0.0025)
    sdo.download(0x60C2, 1, struct.pack('<B', 40))
    assert sim.interpolation_period == pytest.approx(0.004)


def test_any_error_bit_comes_with_bit_0_of_the_error_register(wire):
    sim, sdo, raw, _ = wire
    sdo.download(0x1016, 1, struct.pack('<I', (127 << 16) | 50))
    sdo.download(0x6007, 0, struct.pack('<h', 1))      # abort connection: fault
    configure(sdo, rpdo_type=255, tpdo_type=255, event_ms=20)
    raw.send(can.Message(arbitration_id=0, data=[1, NODE], is_extended_id=False))
    for cw in (0x06, 0x07, 0x0F):
        raw.send(can.Message(arbitration_id=0x200 + NODE, data=struct.pack('<H', cw),
                             is_extended_id=False))
        time.sleep(0.02)
    assert sim.state == OPERATION_ENABLED
    raw.send(can.Message(arbitration_id=0x77F, data=[5], is_extended_id=False))  # one heartbeat
    assert wait_until(lambda: sim.state == 'FAULT', 1.0)     # then none: the consumer trips
    emcy = [bytes(m.data) for m in drain(raw) if m.arbitration_id == 0x80 + NODE]
    assert emcy and emcy[0][:3] == struct.pack('<HB', 0x8130, 0x11)
    assert struct.unpack('<B', sdo.upload(0x1001, 0))[0] == 0x11


def test_after_homing_csp_takes_up_from_the_shaft_without_a_following_error(wire):
    sim, _, raw, channel = wire
    drive = Cia402Drive(DriveConfig(can_interface='virtual', can_channel=channel,
                                    drive_node_id=NODE, step_timeout=0.5,
                                    following_error_window=0.05))
    try:
        drive.connect_and_enable()
        drive.move_by(0.5)                             # away from where it enabled
        drain(raw)
        drive.home(19, 3.0, 0.5, timeout=10.0)         # to the switch, then back to CSP
        held = drive.status().position
        for _ in range(40):                            # the loop's targets from where it is
            drive.send_position(held)
            drive.send_heartbeat()
            drive.canbus.send_sync()
            time.sleep(0.01)
        words = statuswords(drain(raw))
        assert len(words) >= 30 and not any(w & SW_FOLLOWING_ERROR for w in words)
        assert sim.following_error_faults == 0 and drive.status().state == OPERATION_ENABLED
    finally:
        drive.shutdown()
