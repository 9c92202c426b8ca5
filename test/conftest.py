"""Test set-up shared by every test module.

DDS discovery must stay on loopback in this workplace (and in CI), and each test session gets a
DDS domain of its own: both are set here, before any test module can call rclpy.init().
"""
import os
import sys
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
# the CAN drive fixtures (a virtual channel per test, the simulated drive, masters)
from drive_helpers import channel, enabled, make_drive, sim, spy  # noqa: E402, F401
# the rice three-arm scene and its mechanism (module scope), for the three-arm test modules
from three_arm_fixtures import mech, params  # noqa: E402, F401


# Tests whose pass depends on being scheduled in real time: live ROS graphs, simulated drives
# and their masters, `planter demo` runs, commissioning, signal and process-death timings, the
# bench (its control-loop case loads the CPU on purpose). With two processes (pytest.ini) they
# all run on one process, one after the other as in a serial run, and the other process, which
# runs the rest meanwhile, lowers its CPU priority so it never starves them; it takes its normal
# priority back once they are done (where the user may: root).
REALTIME_MODULES = {'test_acceptance.py', 'test_bench.py', 'test_cam_demo.py',
                    'test_command_process.py', 'test_commission.py', 'test_csp.py',
                    'test_demo.py', 'test_die_with_parent.py', 'test_no_leftovers.py',
                    'test_recorder_signals.py', 'test_stop_signals.py',
                    'test_sync_node_start.py'}
REALTIME_FIXTURES = {'ros', 'sim', 'enabled', 'channel', 'make_drive', 'spy', 'rig', 'machine'}
BACKGROUND_NICE = 10


def _module(item):
    return item.nodeid.split('::', 1)[0]


def _realtime(item):
    return (_module(item).rsplit('/', 1)[-1] in REALTIME_MODULES
            or not REALTIME_FIXTURES.isdisjoint(getattr(item, 'fixturenames', ())))


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """The real-time tests first, as one pytest-xdist group (one process runs them in order);
    then each other module as a group of its own (its module fixtures made once), those with a
    test marked `slow` first, so that both processes end together. Orders kept otherwise."""
    slow = {_module(item) for item in items if item.get_closest_marker('slow')}
    for item in items:
        realtime = _realtime(item)
        item.add_marker(pytest.mark.realtime if realtime else pytest.mark.background)
        item.add_marker(pytest.mark.xdist_group('realtime' if realtime else _module(item)))
    items[:] = sorted(items, key=lambda item: (not _realtime(item), _module(item) not in slow))
    config.stash[_LAST_REALTIME] = next((item.nodeid for item in reversed(items)
                                         if _realtime(item)), None)


_LAST_REALTIME = pytest.StashKey[str]()


def _realtime_done_file(config):
    """A file every process of this session sees: there once the real-time tests are done."""
    base = config._tmp_path_factory.getbasetemp()       # the session's (the worker's)
    root = base.parent if base.name.startswith('popen-gw') else base
    return root / 'realtime-tests-done'


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    done = (item.config.stash.get(_LAST_REALTIME, None) is None
            or _realtime_done_file(item.config).exists())
    niced = os.getpriority(os.PRIO_PROCESS, 0) >= BACKGROUND_NICE
    if item.get_closest_marker('background') and not done and not niced:
        os.nice(BACKGROUND_NICE)
    elif niced and (done or item.get_closest_marker('realtime')):
        try:
            os.setpriority(os.PRIO_PROCESS, 0, 0)
        except PermissionError:
            pass


def pytest_runtest_teardown(item, nextitem):
    if item.nodeid.split('@', 1)[0] == (item.config.stash.get(_LAST_REALTIME, None) or '') \
            .split('@', 1)[0]:
        _realtime_done_file(item.config).touch()
