"""Section state on a topic of its own (`sections`, sensor_msgs/JointState, latched): how a
message names the rows, the breaks the states make, and replay reading them from a bag, the
new topic and, for a bag recorded before it, the sync node's /diagnostics."""
import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState

from planter_ros import diagnostics, interfaces
from planter_ros.control.phase_lock import PlantingAngles
from planter_ros.prediction import SectionBreaks, planting_model_from_design
from planter_ros.recording.replay import replay
from planter_ros.rows import Row
from planter_ros.sim.bags import MachineBagOptions, write_machine_bag
from planter_ros.sim.closed_loop import (
    LoopTiming, MotionSensor, RowDesign, RowEvents, SimMachine, simulate_rows)
from planter_ros.sim.field import field_profile
from planter_ros.sim.runs import five_bar_design_message

FAST = LoopTiming(dt=0.002)          # s: a coarser integration step than the default
EXACT = MotionSensor(noise=0.0, yaw_noise=0.0)   # the sensor reads the truth

pytestmark = pytest.mark.realtime          # (test/conftest.py)

D = 0.2
ROWS = [Row(0, 'left', 0.5, 1), Row(1, 'right', -0.5, 2)]
OFF = 3.1                  # s the left row's section is off
EPOCH = 1_700_000_000.0


def test_a_message_names_each_row_and_reads_back():
    names, positions = interfaces.section_fields({'left': False, 'right': True})
    assert names == ['left', 'right'] and positions == [0.0, 1.0]
    assert interfaces.section_states(names, positions) == {'left': False, 'right': True}
    # the implicit row of a scene without rows is named ''; a NaN says nothing of its row
    assert interfaces.section_states(['', 'x'], [1.0, math.nan]) == {'': True}
    topic = interfaces.SECTIONS
    assert topic.msg_class() is JointState and topic in interfaces.MONITOR_INPUTS
    assert (topic.qos.reliability, topic.qos.durability) == ('reliable', 'transient_local')


def test_a_break_is_the_instant_a_row_is_on_again_after_being_off():
    breaks = SectionBreaks()
    assert breaks.update(1.0, {'left': True, 'right': True}) == []
    assert breaks.update(2.0, {'left': False, 'right': True}) == []
    assert breaks.update(2.5, {'left': False, 'right': False}) == []
    assert breaks.update(4.0, {'left': True, 'right': False}) == [('left', 4.0, 4.0)]
    assert breaks.update(5.0, {'left': True, 'right': True}) == [('right', 5.0, 5.0)]
    assert breaks.update(6.0, {'left': True, 'right': True}) == []


@pytest.fixture(scope='module', params=[8.1, 8.4])
def machine(request):
    """Two rows on a straight field; the left one switched off at t_off and on OFF s later.
    Switched off at 8.4 s, the mechanism cannot stop in front of the soil: one more plant."""
    t_off = request.param
    design = five_bar_design_message()
    model = planting_model_from_design(design)
    angles = PlantingAngles(float(model.planting_phase), float(model.entry_angle),
                            float(model.exit_angle))
    profile = field_profile(20.0, 0.2)
    runs = simulate_rows(SimMachine([r.lateral_offset for r in ROWS], timing=FAST), profile,
                         18.0, RowDesign(D, planting=angles), EXACT,
                         RowEvents(switches=[(t_off, 0, False), (t_off + OFF, 0, True)]))
    return design, profile, runs, t_off


def left_spacings(tmp_path, machine, extra, name):
    design, profile, runs, _ = machine
    bag = tmp_path / name
    write_machine_bag(ROWS, runs, profile, design, bag, MachineBagOptions(EPOCH, extra=extra))
    result = replay(bag)
    left = result.plants.row == 0
    return result.plants.time[left] - EPOCH, result.plants.spacing[left]


def sections_message(left_on):
    names, positions = interfaces.section_fields({'left': left_on, 'right': True})
    return JointState(name=names, position=positions)


def old_diagnostics(left_on):
    """The sync node's /diagnostics as it was before the `sections` topic."""
    state = diagnostics.SECTION_ON if left_on else diagnostics.SECTION_OFF
    return diagnostics.array([(diagnostics.Report(row, diagnostics.OK, 'tracking', (
        ('row speed', '0.2000 m/s'), (diagnostics.SECTION, state if row == 'left' else 'on'))),
        'virtual:can0') for row in ('left', 'right')], 'sync_node')


def test_replay_ends_the_rows_sequence_where_the_sections_topic_says_it_was_off(tmp_path,
                                                                              machine):
    t_off = machine[3]
    t, spacing = left_spacings(tmp_path, machine, (), 'blind.mcap')
    first = int(np.argmax(t > t_off + OFF))
    assert spacing[first] > 1.5 * D                     # without the states: a miss that was none
    extra = [(0.0, interfaces.SECTIONS, sections_message(True)),
             (t_off, interfaces.SECTIONS, sections_message(False)),
             (t_off + OFF, interfaces.SECTIONS, sections_message(True))]
    t, spacing = left_spacings(tmp_path, machine, extra, 'sections.mcap')
    first = int(np.argmax(t > t_off + OFF))
    assert np.isnan(spacing[first]) and np.count_nonzero(np.isnan(spacing)) == 2
    assert np.nanmax(spacing) < 1.5 * D
    # a plant set after the switch-off (the mechanism could not stop before the soil) keeps
    # its spacing: the break is the switch-on instant
    committed = (t > t_off) & (t < t_off + OFF)
    assert np.count_nonzero(committed) == (1 if t_off == 8.4 else 0)
    assert np.all(np.isfinite(spacing[committed]))


def test_a_bag_recorded_before_the_sections_topic_still_has_its_breaks(tmp_path, machine):
    """The section states of such a bag are in the sync node's 1 Hz /diagnostics."""
    t_off = machine[3]
    extra = [(float(s), interfaces.DIAGNOSTICS, old_diagnostics(not t_off <= s < t_off + OFF))
             for s in np.arange(0.5, 17.0, 1.0)]
    t, spacing = left_spacings(tmp_path, machine, extra, 'old.mcap')
    first = int(np.argmax(t > t_off + OFF))
    assert np.isnan(spacing[first]) and np.count_nonzero(np.isnan(spacing)) == 2
    assert isinstance(extra[0][2], DiagnosticArray)
