"""CANopen objects declared once (drive/objects.py): the doc's tables are generated from them,
the EDS describes each with the same data type, and master, simulator and bus-load count use
the same PDO layouts. Bus and device settings are separate groups with unchanged names."""
from dataclasses import fields
import re

import canopen
import pytest

from cli_helpers import REPO
from planter_ros.drive import bus_load, objects as od
from planter_ros.drive.config import BusConfig, DeviceConfig, DriveConfig
from planter_ros.drive.errors import DriveConfigError
from planter_ros.drive.simulated_drive import SimulatedDrive

pytestmark = pytest.mark.realtime          # (test/conftest.py)


def doc_tables():
    text = (REPO / 'doc' / 'drive.md').read_text()
    match = re.search(r'<!-- objects: generated[^\n]*-->\n(.*?)<!-- /objects -->', text, re.S)
    assert match, 'doc/drive.md lost its generated objects section'
    return match.group(1)


def test_the_doc_tables_are_the_code():
    assert doc_tables() == od.markdown_table(), (
        'doc/drive.md differs from drive/objects.py: regenerate the section between the '
        '"objects" markers with planter_ros.drive.objects.markdown_table()')


def test_every_object_is_in_the_eds_with_its_data_type():
    eds = canopen.objectdictionary.import_od(str(REPO / 'config' / 'planter_drive.eds'))
    for obj in od.OBJECTS:
        entry = eds[obj.index]
        if not isinstance(entry, canopen.objectdictionary.ODVariable):
            entry = entry[obj.subindex]
        assert entry.data_type == obj.dtype, obj.address
        assert entry.subindex == obj.subindex, obj.address
    for layout in od.LAYOUTS:            # PDO entries must be mappable
        for obj in layout.entries:
            assert eds[obj.index].pdo_mappable, obj.address


def test_csp_objects_are_declared():
    addresses = {(o.index, o.subindex) for o in od.OBJECTS}
    for wanted in ((0x607A, 0), (0x60C2, 1), (0x60C2, 2), (0x1005, 0), (0x1006, 0),
                   (0x6065, 0), (0x6066, 0), (0x6502, 0)):
        assert wanted in addresses
    assert od.rpdo_for_mode(8).entries == (od.CONTROLWORD, od.TARGET_POSITION)
    assert od.rpdo_for_mode(3).entries == (od.CONTROLWORD, od.TARGET_VELOCITY)
    with pytest.raises(ValueError, match='mode = 1 is out of range'):
        od.rpdo_for_mode(1)


def test_bus_load_counts_the_declared_frames():
    assert bus_load.RPDO_BYTES == od.RPDO_VELOCITY.frame.size == 6
    assert bus_load.TPDO_BYTES == (4, 8)


def test_the_master_maps_the_declared_layouts(enabled):
    _, sim = enabled
    for layout in (od.RPDO_VELOCITY,) + od.TPDOS:
        maps = sim.node.rpdo if layout.kind == 'RPDO' else sim.node.tpdo
        pdo = maps[layout.number]
        assert tuple((v.index, v.offset, v.length) for v in pdo) == layout.bit_layout
        assert pdo.cob_id == layout.cob_id(sim.node_id)
    assert isinstance(sim, SimulatedDrive)


def test_bus_and_device_settings_are_separate_groups_with_the_old_names():
    bus_names = {f.name for f in fields(BusConfig)}
    device_names = {f.name for f in fields(DeviceConfig)}
    assert bus_names == {'can_interface', 'can_channel', 'can_bitrate', 'master_node_id',
                         'heartbeat_period', 'sync_period'}
    assert 'drive_node_id' in device_names and not bus_names & device_names
    assert {f.name for f in fields(DriveConfig)} == bus_names | device_names
    config = DriveConfig(can_channel='x', drive_node_id=5)
    assert config.bus == BusConfig(can_channel='x')
    assert config.device == DeviceConfig(drive_node_id=5)
    assert DriveConfig.of(config.bus, config.device) == config
    with pytest.raises(DriveConfigError, match='master_node_id = 5 is out of range'):
        DriveConfig(drive_node_id=5, master_node_id=5)
    with pytest.raises(DriveConfigError, match='can_bitrate = 5 is out of range'):
        BusConfig(can_bitrate=5)
