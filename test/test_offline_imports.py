"""`planter replay` and `planter analyze` work on recordings alone: they import neither canopen
(the CAN bus) nor rclpy (ROS), in the command's process or in any process it starts (the Dask
workers of analyze).

Each command runs as a user runs it, in a subprocess, with a `sitecustomize` on its PYTHONPATH
that every Python process of the run loads at start (the workers inherit the environment): it
notes, before the import happens, every import of a watched package and the planter_ros frames
that asked for it."""
import os
import subprocess
import sys

import pytest

from cli_helpers import REPO

WATCHED = ('canopen', 'rclpy')
SAMPLE = REPO / 'bags' / 'sample_tomato.mcap'

SITECUSTOMIZE = '''
import os
import sys
import traceback

WATCHED = {watched!r}


class _Watch:
    def find_spec(self, name, path=None, target=None):
        if name in WATCHED:
            frames = [f'{{f.filename}}:{{f.lineno}}' for f in traceback.extract_stack()
                      if 'planter_ros' in f.filename]
            with open(os.environ['PLANTER_IMPORT_LOG'], 'a') as log:
                log.write(f'{{os.getpid()}} {{name}} <- {{" <- ".join(reversed(frames))}}\\n')
        return None


sys.meta_path.insert(0, _Watch())
'''


def run_watched(tmp_path, *args, module=('-m', 'planter_ros.cli'), timeout=300):
    """Run `python -m planter_ros.cli ARGS` (or other arguments) watched; returns the finished
    process and the watched imports it and its children made, one line each."""
    hook = tmp_path / 'hook'
    hook.mkdir(exist_ok=True)
    (hook / 'sitecustomize.py').write_text(SITECUSTOMIZE.format(watched=WATCHED))
    log = tmp_path / 'imports.log'
    log.write_text('')
    env = dict(os.environ, PYTHONPATH=os.pathsep.join((str(hook), str(REPO))),
               PLANTER_IMPORT_LOG=str(log), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    out = subprocess.run([sys.executable, *module, *map(str, args)], capture_output=True,
                         text=True, timeout=timeout, env=env, cwd=REPO)
    return out, log.read_text().splitlines()


def test_the_watch_sees_an_import_of_rclpy_and_canopen(tmp_path):
    """The test itself: an import of either is noted (so a silent pass means none happened)."""
    out, imports = run_watched(tmp_path, module=('-c', 'import canopen, rclpy'))
    assert out.returncode == 0, out.stderr
    assert sorted(line.split()[1] for line in imports) == ['canopen', 'rclpy']


def test_replay_with_every_output_imports_neither_canopen_nor_rclpy(tmp_path):
    out, imports = run_watched(
        tmp_path, 'replay', SAMPLE, '--json', '--plot', tmp_path / 'replay.png',
        '--geojson', tmp_path / 'map.geojson', '--csv', tmp_path / 'plants.csv',
        '--shapefile', tmp_path / 'map.zip', '--isoxml', tmp_path / 'TASKDATA.zip')
    assert out.returncode == 0, out.stderr[-2000:]
    assert '"plants"' in out.stdout and (tmp_path / 'TASKDATA.zip').exists()
    assert imports == []


@pytest.mark.slow
def test_analyze_and_its_workers_import_neither_canopen_nor_rclpy(tmp_path):
    out, imports = run_watched(tmp_path, 'analyze', REPO / 'bags', '--out', tmp_path / 'season',
                               '--workers', '2', '--json')
    assert out.returncode == 0, out.stderr[-2000:]
    assert (tmp_path / 'season' / 'plants').exists()
    assert imports == []
