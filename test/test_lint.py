"""Lint as a test, as ament_flake8 runs on ROS packages: ruff with the repository's ruff.toml."""
import os
import shutil
import subprocess
import sys

from cli_helpers import REPO


def test_ruff_finds_nothing():
    ruff = shutil.which('ruff', path=os.path.dirname(sys.executable))
    assert ruff, 'ruff is a test requirement (requirements.txt)'
    out = subprocess.run([ruff, 'check', '--no-cache', '--output-format', 'concise', '.'],
                         cwd=REPO, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout[-4000:] + out.stderr[-2000:]
