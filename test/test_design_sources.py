"""Design-change authority, pure parts: who published an accepted design, what counts as a
change by another node, and the demo's verdict that fails on it (and on every other reason)."""
from planter_ros.demo.verdict import RowResult, RunOutcome, SPACING_TOLERANCE, judge
from planter_ros import diagnostics
from planter_ros.scene.design_sources import DesignSources, Endpoint, gid_text
from planter_ros.sim.spacing import spacing_in_force, spacing_stats

OURS = Endpoint('/planter/design_node', '01.0f.aa')
STRAY = Endpoint('/planter/design_node', '01.0f.bb')      # same name, another process
TOOL = Endpoint('/tools/publisher', '01.0f.cc')


def test_the_only_publisher_then_the_new_one_is_named_and_a_foreign_change_counted():
    sources = DesignSources()
    first = sources.accepted([OURS])
    assert first.first and first.text == '/planter/design_node (publisher 01.0f.aa)'
    assert sources.report().level == diagnostics.OK
    # a parameter update of our own design node: a change, not a foreign one
    again = sources.accepted([OURS])
    assert not again.foreign and sources.changes == 1 and sources.foreign_changes == 0
    # a second node of the same name appears and its latched design arrives
    stray = sources.accepted([OURS, STRAY])
    assert stray.foreign and stray.text == '/planter/design_node (publisher 01.0f.bb)'
    assert sources.changes == 2 and sources.foreign_changes == 1
    report = sources.report()
    assert report.level == diagnostics.WARN
    assert dict(report.values)['design changes by other nodes'] == 1
    # two known publishers and no new one: both named, not counted as foreign for sure
    both = sources.accepted([OURS, STRAY])
    assert not both.foreign and both.text == '/planter/design_node (one of 2 publishers of ' \
        'that name)'
    tool = sources.accepted([OURS, STRAY, TOOL])
    assert tool.foreign and tool.text.startswith('/tools/publisher')
    assert gid_text(bytes([1, 15, 170])) == '01.0f.aa'


def test_a_publisher_gone_before_its_design_is_taken_is_said_so():
    sources = DesignSources()
    sources.accepted([OURS])
    gone = sources.accepted([])
    assert gone.text == 'a publisher no longer on the graph' and gone.foreign


def report(watchdog_trips=(), rows=None, design=None):
    """The sync process's typed final report (demo.sync_process.SyncReport)."""
    from planter_ros.command.reports import CommandReport, RowReport
    from planter_ros.demo.sync_process import DesignReport, DrivesReport, SyncReport
    rows = rows or [{'label': '', 'faults': 0, 'last_fault': '', 'left_out': ''}]
    command = CommandReport(
        accepted=0, rejected={}, yaw_accepted=0, yaw_rejected={}, phase_slips=0,
        send_errors=0, phase_lock=True, turn_compensation=True,
        rows=[RowReport(loop={}, **row) for row in rows], loop={}, command_timeout=0.2)
    return SyncReport(command, DrivesReport(watchdog_trips=list(watchdog_trips)),
                      DesignReport(**{'changes': 0, 'last_change': '', **(design or {})}))


def test_a_latched_design_that_beats_its_nodes_discovery_is_named_once_the_graph_knows():
    sources = DesignSources()
    sources.accepted([OURS])
    unnamed = Endpoint('_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_', STRAY.gid)
    change = sources.accepted([OURS, unnamed])
    assert change.foreign and not change.named
    sources.refresh([OURS, STRAY])
    named = sources.named(change)
    assert named.named and named.text == '/planter/design_node (publisher 01.0f.bb)'
    assert sources.last_change.text == named.text
    assert '/planter/design_node' in dict(sources.report().values)['design publishers seen']
    # an unnamed sighting later never forgets a name already learnt
    sources.refresh([OURS, unnamed])
    assert sources.named(change).named


def test_the_verdict_passes_a_good_run_and_names_every_reason_of_a_bad_one():
    good = judge([RowResult('', 34, 0.008)], report())
    assert good.passed and good.exit_code == 0
    assert good.line().startswith('verdict: PASS: ') and '5 % of d' in good.line()
    assert judge([RowResult('', 34, 0.99 * SPACING_TOLERANCE)], report()).passed
    assert not judge([RowResult('', 34, 1.01 * SPACING_TOLERANCE)], report()).passed
    bad = judge([RowResult('left', 34, 0.061), RowResult('right', 1, 0.0)], report(
        watchdog_trips=[[2, 'RPDO deadline (0x1400:5) expired', 0x8250]],
        rows=[{'label': 'left', 'faults': 0, 'last_fault': '', 'left_out': ''},
              {'label': 'right', 'faults': 1, 'last_fault': 'drive fault 0x8250 (EMCY)',
               'left_out': ''}],
        design={'changes': 1, 'last_change': '/x/design_node (publisher 01.02)'}),
        RunOutcome(bag_error='recording stopped: [Errno 28] No space left on device'))
    assert not bad.passed and bad.exit_code == 1
    line = bad.line()
    for reason in ('drive watchdog trip: node 2 RPDO deadline (0x1400:5) expired (EMCY 0x8250)',
                   'drive fault on row right (1x, last: drive fault 0x8250 (EMCY))',
                   'row left spacing error RMS 6.10 % of d > 5 %',
                   'row right placed 1 plant(s): spacing not judged (needs 2)',
                   'design changed by another node during the run (1x, the latest from '
                   '/x/design_node (publisher 01.02))',
                   'no bag: recording stopped: [Errno 28] No space left on device'):
        assert reason in line, line
    assert line.count('\n') == 0


def test_the_verdict_of_a_run_whose_drives_never_started_or_whose_monitor_saw_a_change():
    failed = judge([], None, RunOutcome(start_error='drive node 1: open bus: ...'))
    assert failed.reasons == ['drives not started: drive node 1: open bus: ...']
    monitor_only = judge([RowResult('', 20, 0.01)], report(),
                         RunOutcome(monitor_design_changes='1x'))
    assert monitor_only.reasons == ['design changed by another node during the run (1x)']


def test_each_gap_is_scored_against_the_design_in_force_when_its_plant_was_set():
    times = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    positions = [0.1, 0.3, 0.5, 0.7, 1.0, 1.3]
    # the change arrives at 3.3 s: the plant at 4.0 s is still the old design's
    d = spacing_in_force(times, 0.2, [(3.3, 0.3)])
    assert list(d) == [0.2, 0.2, 0.2, 0.3, 0.3]
    stats = spacing_stats(positions, d)
    assert stats.max_abs_spacing_error < 1e-12 and stats.max_abs_drift < 1e-12
    against_one = spacing_stats(positions, 0.2)
    assert against_one.max_abs_spacing_error > 0.099          # what a single d would claim
