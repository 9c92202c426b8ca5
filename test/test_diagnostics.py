"""Diagnostics in one module (planter_ros.diagnostics): a report becomes the status a tool reads
(level byte, `<node>: <task>` name, every value as text) and reads back the same; section states
of a bag recorded before the `sections` topic are still found; and no other module of the
package builds or imports diagnostic messages."""
import ast

import pytest
from diagnostic_msgs.msg import DiagnosticStatus

from cli_helpers import REPO
from planter_ros import diagnostics


def test_a_report_becomes_the_status_tools_read_and_reads_back():
    report = diagnostics.Report(diagnostics.DRIVE, diagnostics.STALE, 'no feedback',
                                (('send errors', 0), ('velocity', '1.0000 rad/s')))
    msg = diagnostics.array([(report, 'virtual:can0 node 1')], 'sync_node')
    (status,) = msg.status
    assert status.level == DiagnosticStatus.STALE and status.name == 'sync_node: drive'
    assert status.hardware_id == 'virtual:can0 node 1' and status.message == 'no feedback'
    assert diagnostics.values(status) == {'send errors': '0', 'velocity': '1.0000 rad/s'}
    assert diagnostics.level_of(status) == diagnostics.STALE
    assert diagnostics.task_of(status.name) == diagnostics.DRIVE


def test_the_worst_level_ranks_stale_above_warn_and_error_above_all():
    assert diagnostics.worst([diagnostics.OK, diagnostics.WARN]) == diagnostics.WARN
    assert diagnostics.worst([diagnostics.WARN, diagnostics.STALE]) == diagnostics.STALE
    assert diagnostics.worst([diagnostics.STALE, diagnostics.ERROR]) == diagnostics.ERROR


def test_section_states_of_the_old_form_are_read_per_row_and_for_the_implicit_row():
    def report(task, state):
        return diagnostics.Report(task, diagnostics.OK, 'tracking',
                                  (('row speed', '0.2000 m/s'), (diagnostics.SECTION, state)))
    statuses = diagnostics.array([(report('left', 'off'), 'x'), (report('right', 'on'), 'x'),
                                  (report(diagnostics.DRIVE, 'maybe'), 'x')], 'sync_node').status
    assert diagnostics.section_states(statuses) == {'left': False, 'right': True}
    single = diagnostics.array([(report(diagnostics.PHASE_LOCK, 'off'), 'x')], 'sync_node')
    assert diagnostics.section_states(single.status) == {'': False}


def test_a_recorded_array_is_decoded_without_rclpy_as_rclpy_wrote_it():
    from rclpy.serialization import serialize_message
    report = diagnostics.Report('left', diagnostics.WARN, '1 plant(s) skipped',
                                ((diagnostics.SECTION, diagnostics.SECTION_OFF),))
    msg = diagnostics.array([(report, 'virtual:can0 node 1')], 'sync_node')
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345
    got = diagnostics.decode(serialize_message(msg))
    assert (got.header.stamp.sec, got.header.stamp.nanosec) == (12, 345)
    assert diagnostics.level_of(got.status[0]) == diagnostics.WARN
    assert diagnostics.section_states(got.status) == {'left': False}
    for bad in (b'', b'\x00\x01\x00\x00\xff\xff', serialize_message(msg)[:30]):
        with pytest.raises(ValueError, match='not a DiagnosticArray'):
            diagnostics.decode(bad)


def test_no_other_module_builds_or_imports_diagnostic_messages():
    """One place builds DiagnosticStatus and KeyValue: every node goes through it."""
    offenders = []
    for path in sorted((REPO / 'planter_ros').rglob('*.py')):
        if path.name == 'diagnostics.py' and path.parent.name == 'planter_ros':
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.Name) and node.id in ('DiagnosticStatus', 'KeyValue'):
                names = [node.id]
            offenders += [f'{path.relative_to(REPO)}:{node.lineno} {name}' for name in names
                          if name.startswith('diagnostic_msgs') or name in ('DiagnosticStatus',
                                                                             'KeyValue')]
    assert offenders == []
