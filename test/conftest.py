"""Test set-up shared by every test module.

DDS discovery must stay on loopback in this workplace (and in CI), and each test session gets a
DDS domain of its own: both are set here, before any test module can call rclpy.init().
"""
import os
import sys
import time
from pathlib import Path

import pytest

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

# Every test graph runs in a DDS domain of this test session's own: a second test run, a demo
# or any other ROS process on the host can neither see nor disturb it.
from planter_ros.dds_domain import isolate_environment  # noqa: E402

isolate_environment()

# CI runs the property tests derandomized: the same examples every run, so a red build is a
# reproducible finding, not luck; locally they keep exploring new examples.
from hypothesis import settings  # noqa: E402

settings.register_profile('ci', derandomize=True)
if os.environ.get('CI'):
    settings.load_profile('ci')

# the rclpy fixture (a fresh Context and executor per test), for every test module
from ros_fixtures import ros  # noqa: E402, F401
# the watcher of host stalls (a real-time test that failed meanwhile runs once more)
import host_stalls  # noqa: E402
# the CAN drive fixtures (a virtual channel per test, the simulated drive, masters)
from drive_helpers import channel, enabled, make_drive, sim, spy  # noqa: E402, F401
# the rice three-arm scene and its mechanism (module scope), for the three-arm test modules
from three_arm_fixtures import mech, params  # noqa: E402, F401


# Modules whose tests pass only when scheduled in real time: live ROS graphs, simulated drives
# and their masters, `planter demo` runs, commissioning, signal and process-death timings. (Not
# the bench smoke run: it reports what it measured, whatever the host; run beside them, at the
# lower priority, its CPU hogs cannot starve them.) With two processes (pytest.ini) they
# all run on one process, one after the other as in a serial run, while the other process runs
# the rest at a lower CPU priority (so it never starves them), until they are done. A new module
# with a live graph or a drive (the `ros`, `sim`, `channel`... fixtures) belongs here.
REALTIME_MODULES = {
    'test_acceptance.py', 'test_bus_load.py', 'test_cam_demo.py',
    'test_cam_law.py', 'test_command_process.py', 'test_commission.py', 'test_csp.py',
    'test_demo.py', 'test_demo_stops.py', 'test_design_node.py', 'test_die_with_parent.py',
    'test_drive_enable.py',
    'test_drive_faults.py', 'test_drive_motion.py', 'test_drive_objects.py', 'test_drive_set.py',
    'test_drive_shutdown.py', 'test_drive_vcan.py', 'test_ground_speed_sources.py',
    'test_machine_node.py', 'test_monitor_node.py', 'test_params_files.py',
    'test_recorder_signals.py', 'test_sections.py', 'test_seedlings.py', 'test_stop_signals.py',
    'test_sync_node.py', 'test_sync_node_start.py',
    # on main since this list was made (drives, demos): real-time once merged
    'test_bus_faults.py', 'test_demo_tray.py', 'test_machine_start.py',
    'test_seedling_sensor_rows.py'}
# and single real-time tests of modules that are not (their module's other tests run beside)
REALTIME_TESTS = {
    'test_no_leftovers.py::test_a_command_leaves_only_what_it_was_asked_to_write[demo]',
    'test_no_leftovers.py::test_a_demo_without_bag_names_its_default_bag_in_its_first_line'}
BACKGROUND_NICE = 10
REALTIME_NICE = -10


def _module(nodeid):
    return nodeid.split('::', 1)[0]


def _realtime(nodeid):
    module, _, test = nodeid.partition('::')
    module = module.rsplit('/', 1)[-1]
    return module in REALTIME_MODULES or f'{module}::{test}' in REALTIME_TESTS


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """Whole modules as units of work (their module fixtures made once), the real-time modules
    together as one unit (xdist's own --dist loadgroup cannot group with this pytest)."""
    from xdist.scheduler import LoadScopeScheduling

    class RealtimeTogether(LoadScopeScheduling):
        def _split_scope(self, nodeid):
            return 'realtime' if _realtime(nodeid) else _module(nodeid)
    return RealtimeTogether(config, log)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """The real-time modules first (one process takes them as one unit, the unit it is given
    first); then the modules with a test marked `slow`, so that both processes end together.
    Orders kept otherwise."""
    slow = {_module(item.nodeid) for item in items if item.get_closest_marker('slow')}
    items[:] = sorted(items, key=lambda item: (not _realtime(item.nodeid),
                                               _module(item.nodeid) not in slow))
    config.stash[_LAST_REALTIME] = next((item.nodeid for item in reversed(items)
                                         if _realtime(item.nodeid)), None)


_LAST_REALTIME = pytest.StashKey[str]()


def _realtime_done_file(config):
    """A file every process of this session sees: there once the real-time tests are done."""
    base = config._tmp_path_factory.getbasetemp()       # the session's (the worker's)
    root = base.parent if base.name.startswith('popen-gw') else base
    return root / 'realtime-tests-done'


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    """The CPU priority of this process for the test: the real-time tests at REALTIME_NICE (the
    priority the sync shell asks for on a machine, doc/command.md), so that other work on the
    host (a second test process, a build) does not starve their 10 ms loops and 0.2 s
    watchdogs; the other tests at BACKGROUND_NICE while real-time tests still run elsewhere,
    else 0. Without the right to raise a priority (not root), what can be set is set."""
    done = (item.config.stash.get(_LAST_REALTIME, None) is None
            or _realtime_done_file(item.config).exists())
    if _realtime(item.nodeid):
        wanted = REALTIME_NICE
    else:
        wanted = 0 if done else BACKGROUND_NICE
    _set_nice(wanted)


def _set_nice(wanted):
    if os.getpriority(os.PRIO_PROCESS, 0) == wanted:
        return
    for value in (wanted, 0):
        try:
            os.setpriority(os.PRIO_PROCESS, 0, value)
            return
        except PermissionError:
            continue


def pytest_runtest_teardown(item, nextitem):
    if item.nodeid == item.config.stash.get(_LAST_REALTIME, None):
        _realtime_done_file(item.config).touch()


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_protocol(item, nextitem):
    """A real-time test that failed while the host itself stopped scheduling processes for more
    than host_stalls.STARVED s (its watcher process saw it) runs once more; the re-run is named
    in the warnings summary. A stall inside the test process (a lock, the GIL, DDS) is no reason:
    the failure stands."""
    if not _realtime(item.nodeid):
        return None
    from _pytest.runner import runtestprotocol
    watcher = host_stalls.watcher(REALTIME_NICE)
    item.ihook.pytest_runtest_logstart(nodeid=item.nodeid, location=item.location)
    start = time.monotonic()
    reports = runtestprotocol(item, nextitem=nextitem, log=False)
    if any(report.failed for report in reports):
        host_stalls.wait_for_reports()
        stall = watcher.longest(start, time.monotonic())
        if stall > host_stalls.STARVED:
            item.warn(pytest.PytestWarning(
                f'the host left every process unscheduled for {stall * 1000:.0f} ms during this '
                f'test, which then failed ({_failure_line(reports)}): run once more'))
            item._initrequest()
            reports = runtestprotocol(item, nextitem=nextitem, log=False)
    for report in reports:
        item.ihook.pytest_runtest_logreport(report=report)
    item.ihook.pytest_runtest_logfinish(nodeid=item.nodeid, location=item.location)
    return True


def _failure_line(reports):
    report = next(report for report in reports if report.failed)
    crash = getattr(report.longrepr, 'reprcrash', None)
    first = crash.message.splitlines()[:1] if crash else []
    return f'{report.when}: {first[0]}' if first else report.when


def pytest_sessionfinish(session):
    host_stalls.close()
