"""Test set-up shared by every test module.

DDS discovery must stay on loopback in this workplace (and in CI): the variable is set here,
before any test module can call rclpy.init().
"""
import os
import sys
from pathlib import Path

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

# CI runs the property tests derandomized: the same examples every run, so a red build is a
# reproducible finding, not luck; locally they keep exploring new examples.
from hypothesis import settings  # noqa: E402

settings.register_profile('ci', derandomize=True)
if os.environ.get('CI'):
    settings.load_profile('ci')
