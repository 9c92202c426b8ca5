"""Run the `planter` command line in a subprocess, as a user would."""
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def run_planter(*args, timeout=120, cwd=None):
    env = dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    return subprocess.run([sys.executable, '-m', 'planter_ros.cli', *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, env=env,
                          cwd=cwd or REPO)
