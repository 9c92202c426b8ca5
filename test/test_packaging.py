"""A plain `pip install .` into a fresh venv gives a package that imports and runs: the runtime
dependencies are declared in setup.py (requirements.txt only pins them for the bootstrap)."""
import os
import shutil
import subprocess
import sys

import pytest

from cli_helpers import REPO


@pytest.mark.slow
def test_pip_install_into_a_fresh_venv_imports_and_runs(tmp_path):
    src = tmp_path / 'src'
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(
        '.venv', '.git', 'build', 'install', 'log', '__pycache__', '*.egg-info', 'bags',
        '.hypothesis', '.pytest_cache', '.ruff_cache'))
    venv = tmp_path / 'venv'
    subprocess.run([sys.executable, '-m', 'venv', str(venv)], check=True, timeout=120)
    # --no-compile: no .pyc written for the ~50 dependencies at install time (a third of the
    # install's time); the imports below compile what they load, as on any first run
    pip = subprocess.run([str(venv / 'bin' / 'python'), '-m', 'pip', 'install', '--quiet',
                          '--no-compile', '--disable-pip-version-check', str(src)],
                         capture_output=True, text=True, timeout=900)
    assert pip.returncode == 0, pip.stderr[-3000:]
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    env.pop('PYTHONPATH', None)
    helped = subprocess.run([str(venv / 'bin' / 'planter'), '--help'], capture_output=True,
                            text=True, timeout=60, env=env, cwd=tmp_path)
    assert helped.returncode == 0 and 'demo' in helped.stdout, helped.stderr
    code = ('import planter_ros.nodes.sync_node, planter_ros.nodes.monitor_node, '
            'planter_ros.nodes.design_node, planter_ros.recording.replay, '
            'planter_ros.kinematics.three_arm; print("ok")')
    imported = subprocess.run([str(venv / 'bin' / 'python'), '-c', code], capture_output=True,
                              text=True, timeout=120, env=env, cwd=tmp_path)
    assert imported.stdout.strip() == 'ok', imported.stderr[-2000:]


# install_requires name -> the rosdep keys package.xml must list for it
ROSDEP = {'ros-jazzy-rclpy': {'rclpy'},
          'ros-jazzy-common-interfaces': {'std_msgs', 'std_srvs', 'geometry_msgs',
                                          'sensor_msgs', 'diagnostic_msgs'},
          'numpy': {'python3-numpy'}, 'scipy': {'python3-scipy'}, 'PyYAML': {'python3-yaml'},
          'python-can': {'python3-can'}, 'canopen': {'python3-canopen'},
          'mcap': {'python3-mcap'}, 'zstandard': {'python3-zstandard'},
          'rosbags': {'python3-rosbags'}, 'matplotlib': {'python3-matplotlib'},
          'mpmath': {'python3-mpmath'}, 'pyproj': {'python3-pyproj'},
          'dask': {'python3-dask', 'python3-distributed'}, 'pyarrow': {'python3-pyarrow'},
          'pyshp': {'python3-pyshp'}, 'cantools': {'python3-cantools'},
          # no Debian package (isoxml, isal) or too old a one (xsdata 22.12): pip on a ROS
          # machine
          'isoxml': set(), 'xsdata': set(), 'isal': set(),
          'setuptools': set()}


def test_package_xml_lists_every_runtime_dependency_of_setup_py():
    import ast
    import re
    import xml.etree.ElementTree as ET
    tree = ast.parse((REPO / 'setup.py').read_text())
    call = next(n for n in ast.walk(tree) if isinstance(n, ast.Call)
                and getattr(n.func, 'id', '') == 'setup')
    requires = next(k.value for k in call.keywords if k.arg == 'install_requires')
    names = {re.split(r'[\[<>=]', ast.literal_eval(e))[0] for e in requires.elts}
    assert set(ROSDEP) == names, 'a new dependency needs its rosdep key here and in package.xml'
    exec_depends = {e.text for e in ET.parse(REPO / 'package.xml').getroot()
                    .findall('exec_depend')}
    wanted = set().union(*ROSDEP.values())
    assert wanted <= exec_depends, sorted(wanted - exec_depends)
    assert exec_depends <= wanted, sorted(exec_depends - wanted)
