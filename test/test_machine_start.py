"""The machine file at every start (issue 22 items 1, 2 and 4): before enabling, the master checks
each drive against its machine file (identity 0x1018, modes 0x6502, the PDO mapping read back,
the drive's EDS) and refuses a mismatch in one line naming the row, node, object, expected and
found; it applies the commissioned polarity and homing, so the commissioned phase offset puts
the joint angle where the tip really is after a drive reset; the sync node's run-time limits
get the scene's plausibility checks."""
import dataclasses
import json
import logging
import math
import re
import uuid

import can
import pytest
from rclpy.parameter import Parameter
from std_msgs.msg import String

from cli_helpers import REPO, run_planter

from planter_ros import diagnostics
from planter_ros.command.engine import CommandEngine
from planter_ros.command.settings import CommandSettings
from planter_ros.commission import SimulatedObserver, commission_machine, updated_machine
from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.control.machine_law import TurnConfig
from planter_ros.control.phase_lock import PhaseLockConfig
from planter_ros.drive.cia402 import Cia402Drive, DriveConfig
from planter_ros.drive.eds import default_eds_path
from planter_ros.drive.errors import DictionaryError, DriveRefusedError
from planter_ros.drive.setup import DriveSetup
from planter_ros.simdrive.drive import SimulatedDrive
from planter_ros.simdrive.mechanism import simulated_mechanism
from planter_ros.simdrive.spec import SimSpec
from planter_ros.rows import Row
from planter_ros.scene.machine_file import (CanBus, MachineFileError, open_machine, parse_machine,
                                       write_machine)
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
from planter_ros.sensing.row_speed import YawRateLimits

pytestmark = pytest.mark.realtime          # (test/conftest.py)

MACHINE = REPO / 'config' / 'machines' / 'tomato_4row_tractor.yaml'
ROW = 'left_outer'
GEAR, COUNTS = 20.0, 131072


@pytest.fixture
def bench():
    """make(**sim kwargs) -> a started simulated drive (node 1) on a fresh virtual channel, and
    master(setup, **config) -> a Cia402Drive for it; all stopped at teardown."""
    channel = f'planter-test-{uuid.uuid4().hex}'
    bus = can.Bus(interface='virtual', channel=channel)
    sims, drives = [], []

    def make(node_id=1, **kwargs):
        kwargs.setdefault('supported_modes', (3, 8))
        sim = SimulatedDrive(channel, node_id=node_id, spec=SimSpec(
            counts_per_motor_rev=COUNTS, gear_ratio=GEAR, **kwargs))
        sim.start()
        sims.append(sim)
        return sim

    def master(setup=None, **config):
        config = {'can_interface': 'virtual', 'can_channel': 'vcan0', 'drive_node_id': 1,
                  'motor_gear_ratio': GEAR, 'counts_per_motor_rev': COUNTS,
                  'step_timeout': 0.5, **config}
        drive = Cia402Drive(DriveConfig(**config), bus=bus, setup=setup)
        drives.append(drive)
        return drive

    yield make, master, bus
    for drive in drives:
        drive.shutdown()
    bus.shutdown()
    for sim in sims:
        sim.stop()


def refused(drive, kind=DriveRefusedError):
    with pytest.raises(kind) as info:
        drive.connect_and_enable()
    drive.shutdown()                     # off the bus: the next master takes it
    text = str(info.value)
    assert '\n' not in text
    return text


def test_a_drive_with_another_identity_is_refused_naming_the_object(bench):
    make, master, _ = bench
    make(identity=(0x29C, 0x402, 1, 7))
    text = refused(master(DriveSetup(modes=('csp',), vendor_id=0x29C, product_code=0x403)))
    assert text == ('drive node 1: check against the machine file: 0x1018:2 product code: '
                    'expected 0x00000403, found 0x00000402')
    # the identity the file states, and no more: accepted
    master(DriveSetup(modes=('csp',), vendor_id=0x29C, product_code=0x402,
                      revision=1)).connect_and_enable()


def test_a_drive_without_a_mode_the_row_needs_is_refused(bench):
    make, master, _ = bench
    make(supported_modes=(3,))
    text = refused(master(DriveSetup(modes=('pv', 'csp')), operation_mode='velocity'))
    assert text == ('drive node 1: check against the machine file: 0x6502 supported drive '
                    'modes: expected csp, found 0x00000024')


def test_a_drive_eds_with_a_wrong_type_or_a_missing_object_is_refused(bench, tmp_path):
    make, master, _ = bench
    make()
    eds = default_eds_path().read_text()
    wrong = tmp_path / 'wrong_type.eds'
    # 0x6064 position actual value declared UNSIGNED32 (0x0007) instead of INTEGER32
    block = re.search(r'\[6064\][^\[]*', eds).group(0)
    wrong.write_text(eds.replace(block, re.sub(r'DataType=0x0*4', 'DataType=0x0007', block)))
    setup = DriveSetup(modes=('csp',), homing_method=19, eds=str(wrong))
    # refused from the drive's EDS before anything moves: the start-up plan (drive.plan)
    assert refused(master(setup), DictionaryError) == (
        'drive node 1: 0x6064 position actual value is UNSIGNED32 in this drive\'s EDS: the '
        'master reads and writes it as INTEGER32; correct the EDS (the drive maker\'s is right)')
    missing = tmp_path / 'no_homing.eds'
    block = re.search(r'\[6098\][^\[]*', eds).group(0)
    missing.write_text(eds.replace(block, ''))
    text = refused(master(dataclasses.replace(setup, eds=str(missing))), DictionaryError)
    assert text == ('drive node 1: 0x6098 homing method is not in this drive\'s EDS: homing at '
                    'start needs it; use homing_method 0 (none) or a drive that homes')
    # a machine file naming an EDS that is not there is refused when it is read
    data = MACHINE.read_text().replace('modes: [csp, pv]\n', 'modes: [csp, pv]\n'
                                       '    eds: drives/nowhere.eds\n', 1)
    with pytest.raises(MachineFileError, match=r'rows.left_outer.eds = .drives/nowhere.eds. '
                                               'is not a file'):
        parse_machine(data, MACHINE)


def test_a_pdo_mapping_that_does_not_read_back_is_refused(bench):
    make, master, _ = bench
    sim = make()
    # a drive that takes the writes but keeps a fixed mapping in TPDO2's second entry
    sim.node.add_read_callback(lambda index, subindex, od: 0x60770010
                               if (index, subindex) == (0x1A01, 2) else None)
    text = refused(master(DriveSetup(modes=('csp',))))
    assert text == ('drive node 1: PDO mapping read back (0x1400/0x1600, 0x1800/0x1A00): '
                    '1A01h:2 TPDO2 mapping: expected 0x606C0020 (606Ch velocity actual value), '
                    'found 0x60770010')


def test_a_refused_row_is_left_out_with_an_error_naming_row_node_and_object(bench):
    make, _, bus = bench
    make(identity=(0, 0x402, 2, 0))
    make(node_id=2)
    lines = []
    law = (PhaseLockConfig(), GroundSpeedLimits(), YawRateLimits(), TurnConfig())
    rows = [Row(0, 'a', 0.0, 1), Row(1, 'b', 0.5, 2)]
    config = DriveConfig(can_interface='virtual', can_channel='vcan0', step_timeout=0.3,
                         motor_gear_ratio=GEAR, counts_per_motor_rev=COUNTS)
    setups = {'a': DriveSetup(modes=('csp',), revision=1), 'b': DriveSetup(modes=('csp',))}
    engine = CommandEngine(CommandSettings(config, SyncLoopConfig(), rows, law, setups=setups),
                           bus=bus, log=lambda level, text: lines.append((level, text)))
    try:
        engine.enable()
        errors = [text for level, text in lines if level == logging.ERROR]
        assert errors == ['row a left out: drive node 1: check against the machine file: '
                          '0x1018:3 revision number: expected 0x00000001, found 0x00000002']
        assert engine.unit('b').running and not engine.unit('a').running
        levels = {report.task: report.level for report, _ in engine.reports(0.0)}
        assert levels['a'] == diagnostics.ERROR, levels
    finally:
        engine.shutdown()


def test_polarity_and_homing_at_start_put_the_commissioned_phase_where_the_tip_is_lowest(
        bench, tmp_path):
    """Commissioned at one power-up (random offset, reversed wiring); started again at another
    (a drive reset: the encoder counts from elsewhere): after the start the commissioned phase
    offset is the bottom to 0.5 degrees, and without the machine file's setup it is not."""
    make, master, bus = bench
    machine = open_machine(MACHINE)
    machine = dataclasses.replace(machine, can=CanBus(interface='virtual', channel='vcan0'))
    rows = dict(machine.rows)
    rows[ROW] = dataclasses.replace(rows[ROW], homing_method=19, polarity='normal',
                                    phase_offset=0.0)
    machine = dataclasses.replace(machine, rows=rows)
    first, wiring = simulated_mechanism(3, 1, 0)
    again, _ = simulated_mechanism(3, 1, 1)
    assert wiring and abs(first - again) > 0.5          # reversed; powered up elsewhere
    # a wide switch: commissioning polls it by SDO, which a loaded host may make slow
    switch = {'motor_reversed': wiring, 'home_switch_width': 0.5}
    sim = make(mechanical_offset=first, **switch)
    [found] = commission_machine(machine, [ROW], SimulatedObserver({ROW: sim}), bus=bus)
    assert found.phase_offset is not None and found.homed
    path = tmp_path / 'machine.yaml'
    write_machine(updated_machine(machine, [found]), path)
    commissioned = open_machine(path)
    setup = commissioned.drive_setups()[ROW]
    assert setup.polarity == 'reversed' and setup.vendor_id == 0 and setup.revision == 1
    sim.stop()
    sim = make(mechanical_offset=again, **switch)
    drive = master(setup, operation_mode='velocity')
    drive.connect_and_enable()
    error = math.degrees(sim.mechanism_angle_at(setup.phase_offset))
    assert abs(error) <= 0.5, error
    step = sim.mechanism_angle_at(setup.phase_offset + 0.1) - sim.mechanism_angle_at(
        setup.phase_offset)
    assert step == pytest.approx(0.1, abs=1e-6)          # forward is forward
    drive.shutdown()
    sim.stop()
    # the same start without the machine file's setup: neither homed nor turned round
    sim = make(mechanical_offset=again, **switch)
    plain = master(None, operation_mode='velocity')
    plain.connect_and_enable()
    assert abs(math.degrees(sim.mechanism_angle_at(setup.phase_offset))) > 5.0


def test_sync_node_takes_the_machine_file_and_checks_its_run_time_limits(ros, tmp_path):
    from test_sync_node import TOMATO, Rig
    path = tmp_path / 'machine.yaml'
    path.write_text(MACHINE.read_text().split('  left_inner:')[0].replace(
        'homing_method: 34', 'homing_method: 0'))
    rig = Rig(ros, sim_kwargs={'counts_per_motor_rev': COUNTS, 'gear_ratio': GEAR,
                               'supported_modes': (3, 8)},
              machine_file=str(path))
    try:
        # the machine file's rows, node ids and drive train, its setup at the drive
        [unit] = rig.sync.engine.units
        assert unit.row.name == ROW and unit.row.drive_node_id == 1
        assert unit.row.lateral_offset == 0.75
        assert unit.drive.config.motor_gear_ratio == GEAR
        assert unit.drive.config.counts_per_motor_rev == COUNTS
        assert unit.drive.setup.modes == ('csp', 'pv') and unit.running
        # the design in force: 0.3 m/s at d = 0.2 m needs the sun bar at 9.42 rad/s
        rig.design_pub.publish(String(data=json.dumps({**TOMATO,
                                                        'nominal_ground_speed': 0.3})))
        assert ros.spin_until(lambda: rig.sync._design is not None
                              and rig.sync._design.nominal_ground_speed == 0.3)
        [result] = rig.sync.set_parameters([Parameter('max_speed', value=5.0)])
        assert not result.successful
        assert result.reason == (
            'nominal_ground_speed = 0.3 m/s needs the sun bar at 9.42 rad/s (90 r/min) for '
            'plant_spacing = 0.2 m: over max_speed = 5 rad/s (48 r/min) of the sync law; '
            'allowed nominal_ground_speed <= 0.159 m/s at this spacing')
        [result] = rig.sync.set_parameters([Parameter('max_acceleration', value=1.0)])
        assert not result.successful and 'over max_acceleration = 1 rad/s²' in result.reason
        assert rig.sync.engine.law.config.max_speed == PhaseLockConfig().max_speed   # unchanged
        [result] = rig.sync.set_parameters([Parameter('max_speed', value=15.0)])
        assert result.successful and rig.sync.engine.law.config.max_speed == 15.0
    finally:
        rig.close()


@pytest.mark.slow
def test_commissioned_then_a_demo_plants_its_first_plant_within_5_mm(tmp_path):
    """Issue 22's "done when": commissioning against the simulated drive (random offset,
    reversed wiring: seed 1), then a demo with the written machine file, its drives powered up
    at another offset: the bag's first plant is within 5 mm of where the tip was lowest."""
    path = tmp_path / 'machine.yaml'
    path.write_text(MACHINE.read_text().split('  left_inner:')[0].replace(
        'homing_method: 34', 'homing_method: 19').replace('gear_ratio: 20.0',
                                                          'gear_ratio: 10.0'))
    assert simulated_mechanism(1, 1, 0)[1]                 # the seed wires it reversed
    done = run_planter('commission', '--machine', str(path), '--simulated', '--seed', '1',
                       timeout=240)
    assert done.returncode == 0, done.stderr
    assert open_machine(path).rows[ROW].polarity == 'reversed'
    # the bottom found (the phase offset 0.0 a missed switch would leave is 0.1 rad off)
    assert abs(float(done.stdout.split('phase error ')[1].split(' deg')[0])) <= 0.5
    demo = run_planter('demo', '--machine', str(path), '--seed', '1', '--duration', '8',
                       '--bag', str(tmp_path / 'bag'), timeout=400)
    assert demo.returncode == 0, demo.stdout[-3000:] + demo.stderr[-2000:]
    found = re.search(r'row left_outer: recorded \(bag replay\) at ([-\d.]+) m, the tip truly '
                      r'lowest at ([-\d.]+) m along the row: error ([-+\d.]+) mm', demo.stdout)
    assert found, demo.stdout[-3000:]
    assert abs(float(found.group(3))) <= 5.0
    assert float(found.group(2)) >= 0.0


def test_placing_the_phase_offset_moves_every_angle_the_law_holds_so_nothing_jumps():
    from planter_ros.command.design_change import bottom_angle
    from planter_ros.control.phase_lock import PhaseLock
    law = PhaseLock(PhaseLockConfig())
    law.ground_speed(0.3, 0.0)
    law.feedback(1.0, 9.0, 0.0)
    law.set_design(0.2, 1, 0.0)
    law.ground_speed(0.3, 0.1)
    law.feedback(1.85, 9.4, 0.1)
    before = law.phase_error(0.1)
    law.shift_angle(math.pi - 0.25)            # the five-bar's bottom minus a phase offset
    assert law.phase_error(0.1) == pytest.approx(before, abs=1e-12)
    assert law.measured_angle(0.1) == pytest.approx(1.85 + math.pi - 0.25)
    law.command(0.1)
    assert law.command(0.2) > 0.0                 # and it keeps turning forward
    # where a design's tip is lowest: the five-bar's π (θ = 0 at the top)
    from planter_ros.design import from_json
    from test_sync_node import TOMATO
    assert bottom_angle(from_json(json.dumps(TOMATO))) == math.pi
