"""`colcon build` is how a ROS machine installs the package: prove it works and installs the
console scripts where `ros2 run planter_ros NAME` looks for them (lib/planter_ros)."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_colcon_build_installs_the_package_and_its_executables(tmp_path):
    colcon = shutil.which('colcon', path=os.path.dirname(sys.executable))
    assert colcon, 'colcon-common-extensions is a test requirement (requirements.txt)'
    src = tmp_path / 'src'
    src.mkdir()
    # a clean copy of the package, as a ROS workspace would have it
    shutil.copytree(REPO, src / 'planter_ros', ignore=shutil.ignore_patterns(
        '.venv', '.git', 'build', 'install', 'log', '__pycache__', '*.egg-info', 'bags',
        '.hypothesis', '.pytest_cache', '.mypy_cache'))
    env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ['PATH'])
    out = subprocess.run(
        [colcon, 'build', '--base-paths', str(src), '--build-base', str(tmp_path / 'build'),
         '--install-base', str(tmp_path / 'install'), '--event-handlers', 'console_direct-'],
        cwd=tmp_path, capture_output=True, text=True, timeout=300, env=env)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    prefix = tmp_path / 'install' / 'planter_ros'
    for exe in ('planter', 'design_node', 'sync_node', 'monitor_node'):
        assert (prefix / 'lib' / 'planter_ros' / exe).is_file(), exe
    assert (prefix / 'share' / 'planter_ros' / 'package.xml').is_file()
    assert (prefix / 'share' / 'planter_ros' / 'config' / 'tomato_five_bar.yaml').is_file()
    assert (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' /
            'planter_ros').is_file()
    # the installed command line runs from the install space
    site = next((prefix / 'lib').glob('python3*/site-packages'))
    run = subprocess.run([sys.executable, str(prefix / 'lib' / 'planter_ros' / 'planter'),
                          'design', 'five-bar', '--depth', '0.045', '--spacing', '0.2', '--json'],
                         capture_output=True, text=True, timeout=60,
                         env=dict(env, PYTHONPATH=str(site)), cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert '"l1"' in run.stdout
