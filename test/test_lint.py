"""Lint as a test, as ament_flake8 runs on ROS packages: ruff with the repository's ruff.toml, and
the type checker (mypy with mypy.ini) on the whole package: 0 errors."""
import os
import shutil
import subprocess
import sys

import pytest

from cli_helpers import REPO

# mypy checks the whole package, every module (strict on the pure core: mypy.ini); a new
# package or module is checked from its first commit.
TYPE_CHECKED = ('planter_ros',)


def test_ruff_finds_nothing():
    ruff = shutil.which('ruff', path=os.path.dirname(sys.executable))
    assert ruff, 'ruff is a test requirement (requirements.txt)'
    out = subprocess.run([ruff, 'check', '--no-cache', '--output-format', 'concise', '.'],
                         cwd=REPO, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout[-4000:] + out.stderr[-2000:]


@pytest.mark.slow
def test_mypy_finds_nothing_in_the_package():
    """mypy reads every module of the package and the libraries it imports (so their types are
    known) and reports the package's own (--follow-imports=silent). Its cache is the
    repository's .mypy_cache, as for a developer's own `mypy` run: about 20 s cold, a few
    seconds warm."""
    command = [sys.executable, '-m', 'mypy', '--follow-imports=silent', '--no-error-summary',
               *TYPE_CHECKED]
    out = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-6000:] + out.stderr[-2000:]
