"""No command leaves a file it was not asked to write: each runs in an empty working directory
with an empty home and an empty temporary directory, and afterwards those hold exactly what
the command line named (a bag, an output directory), nothing else: no default output file, no
lock file, no scratch space, no log files."""
import os
import signal
import subprocess
import sys
import time

import pytest

from cli_helpers import REPO

from planter_ros.output_files import OutputError

SAMPLE = str(REPO / 'bags' / 'sample_tomato.mcap')
RICE = str(REPO / 'config' / 'rice_three_arm.yaml')

# (command line, the files it was asked to write: paths relative to the working directory)
COMMANDS = {
    'design five-bar': (['design', 'five-bar', '--depth', '0.045', '--spacing', '0.2'], set()),
    'design three-arm': (['design', 'three-arm', '--params', RICE], set()),
    'optimize three-arm': (['optimize', 'three-arm', '--max-time', '2'], set()),
    'replay': (['replay', SAMPLE, '--json'], set()),
    'cam five-bar': (['cam', 'five-bar', '--depth', '0.045', '--design-spacing', '0.2',
                      '--spacing', '0.2', '--speed', '0.3'], set()),
    'analyze': (['analyze', SAMPLE, '--out', 'season', '--workers', '1'],
                {'season', 'season/bags', 'season/bags/bags.parquet', 'season/report.html',
                 'season/plants', 'season/as_planted.zip',
                 'season/TASKDATA.zip', 'season/.planter-analyze.json'}),
    'simulate': (['simulate', 'sim', '--bags', '1', '--duration', '10', '--workers', '1'],
                 {'sim', 'sim/run_0_00000.mcap'}),
    'bench': (['bench', '--quick', '--only', 'five-bar reverse'], set()),
}


def places(tmp_path):
    cwd, home, tmp = (tmp_path / name for name in ('cwd', 'home', 'tmp'))
    for d in (cwd, home, tmp):
        d.mkdir()
    env = dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               HOME=str(home), TMPDIR=str(tmp))
    env.pop('ROS_LOG_DIR', None)
    env.pop('ROS_HOME', None)
    return cwd, home, tmp, env


def everything_in(folder):
    return {str(p.relative_to(folder)) for p in folder.rglob('*')}


# (the demo's: test_a_demo_without_bag_names_its_default_bag_in_its_first_line)
@pytest.mark.parametrize('name', sorted(COMMANDS))
def test_a_command_leaves_only_what_it_was_asked_to_write(tmp_path, name):
    args, asked = COMMANDS[name]
    cwd, home, tmp, env = places(tmp_path)
    out = subprocess.run([sys.executable, '-m', 'planter_ros.cli', *args], cwd=cwd, env=env,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    written = everything_in(cwd)
    if name == 'analyze':                       # the plants dataset's parts: named by the run
        written = {w for w in written if not w.startswith('season/plants/')}
        assert list((cwd / 'season' / 'plants').glob('part-*.parquet'))
    assert written == asked
    assert everything_in(home) == set()
    assert everything_in(tmp) == set()


@pytest.mark.slow
def test_a_killed_analyze_leaves_no_lock_and_the_next_run_cleans_up(tmp_path):
    cwd, home, tmp, env = places(tmp_path)
    bags = cwd / 'bags'
    bags.mkdir()
    for k in range(200):                 # (copies of one bag: one is analysed)
        os.link(REPO / 'bags' / 'sample_tomato.mcap', bags / f'b{k:03d}.mcap')
    # two worker processes: their start (seconds) is the middle the kill lands in (one worker
    # runs in the command's process: its scratch space lives a fraction of a second here)
    args = [sys.executable, '-m', 'planter_ros.cli', 'analyze', 'bags', '--out', 'season',
            '--workers', '2']
    proc = subprocess.Popen(args, cwd=cwd, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not list(tmp.glob('planter-dask-*')) and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.5)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    assert proc.returncode == -signal.SIGKILL        # killed in the middle, not finished
    assert list(tmp.glob('planter-dask-*'))          # a SIGKILL leaves the scratch space ...
    assert not [p for p in everything_in(cwd) if 'lock' in p]     # ... but never a lock
    # the next run: one worker, in its own process (any local cluster's start removes a dead
    # run's scratch space; no worker processes to start for the one bag of 200 links)
    again = subprocess.run(args[:-1] + ['1', '--force'], cwd=cwd, env=env, capture_output=True,
                           text=True, timeout=600)
    assert again.returncode == 0, again.stderr[-2000:]
    assert not [p for p in everything_in(cwd) if 'lock' in p]
    assert everything_in(tmp) == set()          # the killed run's scratch space went too


def test_a_second_analyze_on_a_directory_being_written_is_refused(tmp_path):
    from planter_ros.analysis.season import Season
    with Season(tmp_path / 'season'):
        with pytest.raises(OutputError, match='being written by another planter analyze'):
            Season(tmp_path / 'season')
    with Season(tmp_path / 'season'):          # released when the first one ended
        pass


@pytest.mark.slow
@pytest.mark.realtime
def test_a_demo_without_bag_names_its_default_bag_in_its_first_line(tmp_path):
    """The demo writes its bag, the default one named in its first line, and nothing else."""
    cwd, home, tmp, env = places(tmp_path)
    out = subprocess.run([sys.executable, '-m', 'planter_ros.cli', 'demo', '--duration', '8'],
                         cwd=cwd, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    made = everything_in(cwd)
    bag = [p for p in made if p.count('/') == 1]             # a rosbag2 bag directory
    assert len(bag) == 1 and bag[0].startswith('bags/planter_'), made
    assert {p for p in made if not p.startswith(bag[0])} == {'bags'}
    first = out.stdout.splitlines()[0]
    assert first.endswith(f'bag {bag[0]}') or first.endswith(f'bag {cwd / bag[0]}'), first
    assert everything_in(home) == set() and everything_in(tmp) == set()
