"""The base install is enough for the machine: the package with no extra, installed into a fresh
venv, gives design_node, sync_node (on a simulated bus), monitor_node, ground_speed_node and the
command process, which start and answer; a command that needs an extra says in one line which
one to install (exit 2). The roles themselves: planter_ros/dependencies.py (their agreement with
package.xml and requirements.txt: test_dependencies.py)."""
import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from cli_helpers import REPO

PROBE = textwrap.dedent('''
    # every node of the graph answers a service call (its parameter list)
    import sys, time
    import rclpy
    from rcl_interfaces.srv import ListParameters
    rclpy.init()
    node = rclpy.create_node('probe')
    wanted = sys.argv[1].split(',')
    answered = {}
    deadline = time.monotonic() + 60
    while len(answered) < len(wanted) and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.2)
        for name in wanted:
            if name in answered:
                continue
            client = node.create_client(ListParameters, f'/planter/{name}/list_parameters')
            if client.wait_for_service(timeout_sec=0.5):
                future = client.call_async(ListParameters.Request())
                rclpy.spin_until_future_complete(node, future, timeout_sec=5)
                if future.result() is not None:
                    answered[name] = len(future.result().result.names)
            node.destroy_client(client)
    print('answered', ' '.join(f'{k}:{v}' for k, v in sorted(answered.items())), flush=True)
''')

SYNC = textwrap.dedent('''
    # sync_node's main on a virtual bus with a simulated drive in the same process
    import os, sys
    from planter_ros.simdrive.drive import SimulatedDrive
    from planter_ros.nodes.sync_node import main
    channel = f'base{os.getpid()}'
    sim = SimulatedDrive(channel)
    sim.start()
    code = main(['--ros-args', '-r', '__ns:=/planter', '-p', 'can_interface:=virtual',
                 '-p', f'can_channel:={channel}'])
    sim.stop()
    raise SystemExit(code)
''')

COMMAND = textwrap.dedent('''
    # the command process, fed by its client, on simulated drives over a CAN socket pair
    import time
    from planter_ros.command.client import CommandClient
    from planter_ros.command.settings import CommandSettings
    from planter_ros.control.loop_timing import SyncLoopConfig
    from planter_ros.control.machine_law import TurnConfig
    from planter_ros.control.phase_lock import PhaseLockConfig
    from planter_ros.drive.config import DriveConfig
    from planter_ros.simdrive.bus import SimulatedBus
    from planter_ros.drive.socket_bus import INTERFACE, SocketPairBus, socket_pair
    from planter_ros.rows import Row
    from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
    from planter_ros.sensing.row_speed import YawRateLimits
    ours, theirs = socket_pair()
    sims = SimulatedBus(SocketPairBus(ours), [1])
    sims.start()
    client = CommandClient(CommandSettings(
        DriveConfig(can_interface=INTERFACE, can_channel=str(theirs.fileno())),
        SyncLoopConfig(realtime_priority=0), [Row(0, 'left', 0.0, 1)],
        (PhaseLockConfig(), GroundSpeedLimits(), YawRateLimits(), TurnConfig())),
        log=lambda level, text: None)
    client.enable()
    for _ in range(20):
        client.sample(0.3, 0.0, time.monotonic())
        time.sleep(0.02)
    reply = client.section('left', False, time.monotonic())
    print('command process answered:', reply.ok, reply.message, flush=True)
    client.shutdown()
    print('exit', client.exit.reason if client.exit else None, client.process.returncode)
    sims.stop()
''')


@pytest.fixture(scope='module')
def base_venv(tmp_path_factory):
    """A fresh venv with the package alone installed into it, no extra: the base install. The
    package's metadata decides what comes with it; it is installed as scripts/bootstrap.sh
    installs (uv with pip's own configuration: scripts/uv-pip-install; 6 s of CPU where
    `pip install .` takes 25 s, and the same packages at the same versions), or with pip where
    the venv has no uv."""
    tmp = tmp_path_factory.mktemp('base')
    src = tmp / 'src'
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(
        '.venv', '.git', 'build', 'install', 'log', '__pycache__', '*.egg-info', 'bags',
        '.hypothesis', '.pytest_cache', '.ruff_cache', '.mypy_cache', 'test'))
    venv = tmp / 'venv'
    subprocess.run([sys.executable, '-m', 'venv', str(venv)], check=True, timeout=120)
    python = str(venv / 'bin' / 'python')
    uv = Path(sys.executable).with_name('uv')
    if uv.exists():
        install = [str(REPO / 'scripts' / 'uv-pip-install'), python, str(src)]
    else:
        # --no-compile: no .pyc written for the dependencies at install time (a third of the
        # install's time); the imports below compile what they load, as on any first run
        install = [python, '-m', 'pip', 'install', '--quiet', '--no-compile',
                   '--disable-pip-version-check', str(src)]
    done = subprocess.run(install, capture_output=True, text=True, timeout=900,
                          env=dict(os.environ, UV=str(uv)))
    assert done.returncode == 0, done.stderr[-3000:]
    return venv, tmp


def env():
    """The base venv's processes: no PYTHONPATH; byte code written where PYTHONDONTWRITEBYTECODE
    would keep every process compiling all it imports again (the venv is installed without it,
    as `pip install --no-compile` would)."""
    out = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    out.pop('PYTHONPATH', None)
    out.pop('PYTHONDONTWRITEBYTECODE', None)
    return out


@pytest.mark.slow
def test_the_base_install_has_no_extra_and_says_which_one_a_command_needs(base_venv):
    venv, tmp = base_venv
    listed = subprocess.run([str(venv / 'bin' / 'python'), '-m', 'pip', 'list',
                             '--format=freeze'], capture_output=True, text=True, timeout=60)
    names = {line.split('==')[0].lower() for line in listed.stdout.split()}
    assert not names & {'dask', 'pyarrow', 'pandas', 'duckdb', 'matplotlib', 'pytest', 'ruff',
                        'mpmath', 'colcon-core'}, sorted(names)
    assert {'canopen', 'mcap', 'isal', 'lz4', 'zstandard'} <= names
    helped = subprocess.run([str(venv / 'bin' / 'planter'), '--help'], capture_output=True,
                            text=True, timeout=60, env=env(), cwd=tmp)
    assert helped.returncode == 0 and 'demo' in helped.stdout, helped.stderr
    for args, what in ((['analyze', str(REPO / 'bags'), '--out', str(tmp / 'season')],
                        "planter analyze needs the 'analysis' extra"),
                       (['bench'], "planter bench needs the 'dev' extra"),
                       (['design', 'five-bar', '--depth', '0.045', '--spacing', '0.2', '--plot',
                         str(tmp / 'p.png')], "planter design five-bar --plot needs the "
                        "'analysis' extra")):
        out = subprocess.run([str(venv / 'bin' / 'planter'), *args], capture_output=True,
                             text=True, timeout=60, env=env(), cwd=tmp)
        assert out.returncode == 2 and out.stderr.count('\n') == 1, out.stderr
        assert what in out.stderr and "pip install 'planter_ros[" in out.stderr, out.stderr
        assert not (tmp / 'season').exists()


@pytest.mark.slow
def test_in_the_base_install_every_node_and_the_command_process_start_and_answer(base_venv):
    venv, tmp = base_venv
    bin_ = venv / 'bin'
    scene = str(REPO / 'config' / 'tomato_five_bar.yaml')
    ns = ['-r', '__ns:=/planter']
    procs = {
        'design_node': [str(bin_ / 'design_node'), '--ros-args', *ns, '--params-file', scene],
        'monitor_node': [str(bin_ / 'monitor_node'), '--ros-args', *ns, '--params-file', scene],
        'ground_speed_node': [str(bin_ / 'ground_speed_node'), '--ros-args', *ns],
        'sync_node': [str(bin_ / 'python'), '-c', SYNC]}
    started = {name: subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                      text=True, env=env(), cwd=tmp)
               for name, cmd in procs.items()}
    try:
        probe = subprocess.run([str(bin_ / 'python'), '-c', PROBE, ','.join(procs)],
                               capture_output=True, text=True, timeout=120, env=env(), cwd=tmp)
        command = subprocess.run([str(bin_ / 'python'), '-c', COMMAND], capture_output=True,
                                 text=True, timeout=120, env=env(), cwd=tmp)
    finally:
        for proc in started.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        outs = {name: proc.communicate(timeout=60)[0] for name, proc in started.items()}
    answered = dict(re.findall(r'(\w+):(\d+)', probe.stdout))
    assert set(answered) == set(procs), (probe.stdout, probe.stderr, outs)
    assert all(int(count) > 0 for count in answered.values())
    for name, proc in started.items():
        assert proc.returncode == 0 and 'Traceback' not in outs[name], (name, outs[name])
    assert 'command process answered: True row left off' in command.stdout, command.stderr
    assert 'exit stop 0' in command.stdout, command.stdout + command.stderr
