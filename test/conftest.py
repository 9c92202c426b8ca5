"""Test set-up shared by every test module.

DDS discovery must stay on loopback in this workplace (and in CI), and each test session gets a
DDS domain of its own: both are set here, before any test module can call rclpy.init().
"""
import os
import sys
from pathlib import Path

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


def pytest_collection_modifyitems(config, items):
    """Modules holding a test marked `slow` run first (the order within a module, and among
    the slow and among the other modules, kept): with two processes (pytest.ini) the long
    modules are then spread over both from the start instead of one process ending alone on
    a long module it took last."""
    slow = {item.nodeid.split('::', 1)[0] for item in items if item.get_closest_marker('slow')}
    items[:] = sorted(items, key=lambda item: item.nodeid.split('::', 1)[0] not in slow)
