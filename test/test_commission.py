"""`planter commission` against the simulated drive (issue 22 item 2): a mechanism with a random
(seeded) offset between the encoder's zero and its bottom, wired reversed or not; commissioning
must find the polarity and, after homing, the bottom within 0.5 degrees. Against a real switch
(delay, hysteresis, jitter; issue 31): the bottom within a tolerance derived from the jitter,
where fewer than four edges would miss it."""
import dataclasses
import math
import shutil
import uuid

import can
import numpy as np
import pytest

from cli_helpers import REPO, run_planter

from planter_ros.commission import (CommissionError, SimulatedObserver, commission_machine,
                                    updated_machine)
from planter_ros.commission.procedure import EDGE_SPEED
from planter_ros.drive.cia402 import Cia402Drive, DriveConfig
from planter_ros.drive.errors import DriveRefusedError
from planter_ros.simdrive.drive import SimulatedDrive
from planter_ros.simdrive.spec import SimSpec
from planter_ros.scene.machine_file import CanBus, open_machine, write_machine

pytestmark = pytest.mark.realtime          # (test/conftest.py)

MACHINE = REPO / 'config' / 'machines' / 'tomato_4row_tractor.yaml'
ROW = 'left_outer'


@pytest.fixture
def rig():
    """(machine on a virtual channel, make(simulated drive kwargs) -> sim, bus)."""
    channel = f'planter-test-{uuid.uuid4().hex}'
    machine = open_machine(MACHINE)
    machine = dataclasses.replace(machine, can=CanBus(interface='virtual', channel='vcan0'))
    bus = can.Bus(interface='virtual', channel=channel)
    sims = []

    def make(row_changes=None, **kwargs):
        nonlocal machine
        if row_changes:
            rows = dict(machine.rows)
            rows[ROW] = dataclasses.replace(rows[ROW], **row_changes)
            machine = dataclasses.replace(machine, rows=rows)
        row = machine.rows[ROW]
        kwargs.setdefault('supported_modes', (3, 8))
        sim = SimulatedDrive(channel, node_id=row.node_id, spec=SimSpec(
            counts_per_motor_rev=row.encoder_counts, gear_ratio=row.gear_ratio, **kwargs))
        sim.start()
        sims.append(sim)
        return machine, sim

    yield make, bus
    bus.shutdown()
    for sim in sims:
        sim.stop()


@pytest.mark.slow
@pytest.mark.parametrize('seed, method, reversed_', [(7, 19, True), (11, 34, False)])
def test_commissioning_finds_a_random_offset_and_the_polarity(rig, tmp_path, seed, method,
                                                               reversed_):
    make, bus = rig
    offset = float(np.random.default_rng(seed).uniform(0.0, 2.0 * math.pi))
    machine, sim = make({'homing_method': method, 'polarity': 'normal', 'phase_offset': 0.0},
                        mechanical_offset=offset, motor_reversed=reversed_)
    [found] = commission_machine(machine, [ROW], SimulatedObserver({ROW: sim}), bus=bus)
    assert found.polarity == ('reversed' if reversed_ else 'normal')
    assert found.homed
    # the switch was found (no offset: the user would have to set it by eye)
    assert found.phase_offset is not None, f'no switch edges found: {found.edges}'
    # the stored phase is where the simulated tip is lowest, to 0.5 degrees
    error = math.degrees(sim.mechanism_angle_at(found.phase_offset))
    assert abs(error) <= 0.5, error
    # a forward step of the commanded angle turns the mechanism forward (polarity applied)
    step = sim.mechanism_angle_at(found.phase_offset + 0.1) - sim.mechanism_angle_at(
        found.phase_offset)
    assert step == pytest.approx(0.1, abs=1e-6)
    assert math.degrees(found.switch_width) == pytest.approx(math.degrees(0.2), abs=0.5)
    if method == 19:       # home switch: home is its lower edge, so the bottom is half its width
        assert found.phase_offset == pytest.approx(0.1, abs=math.radians(0.5))
    # written and read back strictly
    path = tmp_path / 'machine.yaml'
    write_machine(updated_machine(machine, [found]), path)
    row = open_machine(path).rows[ROW]
    assert row.polarity == found.polarity
    assert row.phase_offset == pytest.approx(found.phase_offset, abs=1e-6)
    assert open_machine(path).rows['right_outer'] == machine.rows['right_outer']


def test_a_drive_without_the_modes_the_machine_file_needs_is_refused(rig):
    make, bus = rig
    machine, sim = make({'modes': ['csp', 'pv']}, supported_modes=(3,))
    with pytest.raises(CommissionError, match=r'row left_outer: node 1 supports modes '
                                              r'0x00000024 .*without csp'):
        commission_machine(machine, [ROW], SimulatedObserver({ROW: sim}), bus=bus)


def test_homing_with_a_method_the_drive_lacks_is_a_homing_error(rig):
    make, bus = rig
    machine, sim = make()
    row = machine.rows[ROW]
    drive = Cia402Drive(DriveConfig(can_interface='virtual', can_channel='vcan0',
                                    drive_node_id=row.node_id, operation_mode='velocity',
                                    motor_gear_ratio=row.gear_ratio,
                                    counts_per_motor_rev=row.encoder_counts), bus=bus)
    try:
        drive.connect_and_enable()
        with pytest.raises(DriveRefusedError, match='homing error'):
            drive.home(1, 1.0, 0.05, timeout=5.0)
        # method 35: here is home (position 0), and the drive still jogs afterwards
        drive.jog(0.5, timeout=0.5)
        drive.home(35, 1.0, 0.05, timeout=5.0)
        assert abs(drive.status().position) < 1e-3
        assert sim.mode_display == 3
    finally:
        drive.shutdown()


@pytest.mark.slow
def test_the_command_line_commissions_and_rewrites_the_machine_file(tmp_path):
    path = tmp_path / 'machine.yaml'
    shutil.copy(MACHINE, path)
    before = open_machine(path)
    done = run_planter('commission', '--machine', str(path), '--simulated', '--seed', '5',
                       '--row', 'left_inner', timeout=240)
    assert done.returncode == 0, done.stderr
    after = open_machine(path)
    assert after.rows['left_outer'] == before.rows['left_outer']
    out = done.stdout
    assert 'row left_inner (node 2):' in out and '[by eye]' in out
    error = float(out.split('phase error ')[1].split(' deg')[0])
    assert abs(error) <= 0.5
    assert f'phase offset {after.rows["left_inner"].phase_offset:.5f} rad' in out
    refused = run_planter('commission', '--machine', str(path), '--simulated', '--row', 'nope')
    assert refused.returncode == 2 and refused.stderr.count('\n') == 1
    assert 'allowed left_outer' in refused.stderr


@pytest.mark.parametrize('extra, message', [
    (['--output', ''], '--output is empty: allowed a file name ending in .yaml or .yml'),
    (['--output', 'missing/dir/m.yaml'], 'missing'),
    (['--output', '.'], '--output = . is a directory'),
    (['--output', 'm.txt'], 'unsupported extension'),
    (['--seed', '-1'], "--seed = '-1' is out of range: allowed integer 0..4294967295"),
    (['--seed', str(2 ** 32)], "--seed = '4294967296' is out of range"),
    (['--seed', 'x'], "--seed = 'x' is out of range"),
])
def test_a_bad_output_or_seed_is_refused_before_anything_moves(tmp_path, extra, message):
    """One line, exit 2, in well under the 15 s the first row's motion takes, and the input
    machine file untouched (`--output ''` used to rewrite it)."""
    import time
    path = tmp_path / 'machine.yaml'
    shutil.copy(MACHINE, path)
    before = path.read_bytes()
    start = time.monotonic()
    out = run_planter('commission', '--machine', path, '--simulated', '--row', 'left_inner',
                      *extra, cwd=tmp_path, timeout=120)
    assert out.returncode == 2 and out.stdout == '', out.stderr
    assert out.stderr.count('\n') == 1 and message in out.stderr, out.stderr
    assert time.monotonic() - start < 10.0
    assert path.read_bytes() == before


def test_a_relative_eds_names_the_same_file_from_another_directory(tmp_path):
    """A machine file whose rows name their EDS relative to it, written elsewhere (commission
    --output in another directory): the paths are rewritten to name the same file, and the
    written file reads back (it used to be refused, after the motion)."""
    here = tmp_path / 'tractor'
    here.mkdir()
    shutil.copy(REPO / 'config' / 'planter_drive.eds', here / 'drive.eds')
    text = MACHINE.read_text()
    path = here / 'machine.yaml'
    path.write_text(text)
    machine = open_machine(path)
    rows = {name: dataclasses.replace(row, eds='drive.eds') for name, row in machine.rows.items()}
    machine = dataclasses.replace(machine, rows=rows)
    elsewhere = tmp_path / 'out' / 'deeper'
    elsewhere.mkdir(parents=True)
    write_machine(machine, elsewhere / 'machine.yaml')
    written = open_machine(elsewhere / 'machine.yaml')
    for row in written.rows.values():
        assert row.eds == '../../tractor/drive.eds'
        assert written.eds_path(row).resolve() == (here / 'drive.eds').resolve()
    # in its own directory nothing changes
    write_machine(machine, here / 'again.yaml')
    assert open_machine(here / 'again.yaml').rows[ROW].eds == 'drive.eds'


# ------------------------------------------------------------ a real switch (issue 31)
# The bottom switch as a real one is (simdrive.switch): its input shows a change DELAY s late
# plus a jitter drawn from [0, JITTER) s per change, and its edges lie HYST apart crossed
# forwards and backwards. Exaggerated against a real drive's input (a few ms, a fraction of a
# degree) so that each effect stands out of the procedure's own timing.
SWITCH_WIDTH, HYST, DELAY, JITTER = 0.25, 2.0 ** -5, 0.1, 0.02     # rad, rad, s, s
# s: how late the procedure can read an edge's position on its own (procedure._switch_edges):
# its poll loop (5 ms sleep + the 60FDh SDO upload), the motor's 2 ms tick, the position's age
# (one 10 ms SYNC period): about 20 ms, allowed 50 ms for a loaded 2-core host
POLL = 0.05
# Each edge is read at (its angle) +- EDGE_SPEED x (DELAY + jitter + poll lateness), + when
# crossed forwards, - backwards, and the hysteresis moves it +-HYST/2 the same way. The
# middle of the four edges (two crossed each way) cancels DELAY and HYST exactly; of the
# random lateness, in [0, JITTER + POLL) per edge, it keeps (2 x forwards - 2 x backwards)/4,
# at most EDGE_SPEED x (JITTER + POLL) / 2:
TOLERANCE = EDGE_SPEED * (JITTER + POLL) / 2         # 1.75 mrad, 0.10 degrees
# a middle from one direction alone keeps DELAY and HYST, and all of the random lateness:
ONE_SIDED_SPREAD = EDGE_SPEED * (JITTER + POLL)
# rad: the encoder's zero this far before the bottom (the mechanical offset), so the direction
# jog (0.3 rad forwards) ends about 0.35 rad before the switch and the search for it at 1 rad/s
# (homing's or the procedure's) is short; what is asserted is measured on the slow passes over
# the switch, which do not depend on where the search began (4.0 rad took 3.6 s more per case)
START_BEFORE = 0.8


@pytest.mark.slow
@pytest.mark.parametrize('hysteresis, method', [(HYST, 19), (0.0, 0)],
                         ids=['hysteresis-delay-jitter-homed', 'delay-jitter'])
def test_four_edges_cancel_the_switch_delay_and_hysteresis(rig, hysteresis, method):
    """The phase offset is the true bottom within TOLERANCE; a procedure using fewer edges
    (from the same measured edges) would miss it by about EDGE_SPEED x DELAY + HYST / 2, more
    than TOLERANCE: this test catches a regression to fewer edges."""
    make, bus = rig
    machine, sim = make({'homing_method': method, 'polarity': 'normal', 'phase_offset': 0.0},
                        mechanical_offset=START_BEFORE, home_switch_width=SWITCH_WIDTH,
                        home_switch_hysteresis=hysteresis, home_switch_delay=DELAY,
                        home_switch_jitter=JITTER, seed=31)
    [found] = commission_machine(machine, [ROW], SimulatedObserver({ROW: sim}), bus=bus)
    assert found.homed == bool(method)
    assert found.phase_offset is not None, f'no switch edges found: {found.edges}'
    true = sim.mechanism_angle_at            # master's rad -> true angle from the bottom
    error = true(found.phase_offset)
    lower_back, lower_fwd, upper_fwd, upper_back = found.edges
    one_way = EDGE_SPEED * DELAY + hysteresis / 2        # what one direction keeps
    misses = {
        # homing-like: one edge crossed forwards, the switch's nominal half width added
        'one edge': true(lower_fwd + SWITCH_WIDTH / 2),
        'two edges forwards': true(0.5 * (lower_fwd + upper_fwd)),
        'two edges backwards': -true(0.5 * (lower_back + upper_back)),
    }
    print(f'\n{hysteresis=} rad: four edges {error * 1e3:+.3f} mrad (tolerance '
          f'{TOLERANCE * 1e3:.3f}); switch width {found.switch_width:.5f} rad; fewer edges '
          + ', '.join(f'{k} {v * 1e3:+.3f} mrad' for k, v in misses.items())
          + f' (model {one_way * 1e3:.3f})')
    assert abs(error) <= TOLERANCE
    assert found.switch_width == pytest.approx(SWITCH_WIDTH, abs=2 * TOLERANCE)
    for name, miss in misses.items():
        assert miss > TOLERANCE, name                  # fewer edges: caught
        assert miss == pytest.approx(one_way, abs=ONE_SIDED_SPREAD), name
