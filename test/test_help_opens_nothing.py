"""Every executable answers --help and --version without touching CAN, DDS or files.

Each console script of setup.py (and every `planter` sub-command) runs in a subprocess under a
guard (a sitecustomize first on the path): importing rclpy (DDS), python-can or canopen (CAN),
creating a socket, opening a file for writing or making a directory ends the process at once
with exit code 97 and a GUARD line naming what was touched. HOME, ROS_HOME, ROS_LOG_DIR and
the working directory are empty directories that must stay empty. The guard is itself tested:
the nodes' own main(), which starts the node, trips it."""
import os
import re
import subprocess
import sys

import pytest

from cli_helpers import REPO

GUARD = r'''
import builtins, io, os, socket, sys

def _tripped(what):
    sys.stderr.write(f'GUARD: {what}\n')
    sys.stderr.flush()
    os._exit(97)

class _NoImport:
    BANNED = ('rclpy', 'can', 'canopen', 'rosbags', 'mcap')
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in self.BANNED:
            _tripped(f'import {name}')
        return None

sys.meta_path.insert(0, _NoImport())

_socket_init = socket.socket.__init__
def _socket(self, *a, **k):
    _tripped('socket')
socket.socket.__init__ = _socket

def _writes(mode):
    return any(c in str(mode) for c in 'wax+')

_open = builtins.open
def _guarded_open(file, mode='r', *a, **k):
    if _writes(mode):
        _tripped(f'open {file!r} for writing')
    return _open(file, mode, *a, **k)
builtins.open = io.open = _guarded_open

_os_open = os.open
def _guarded_os_open(path, flags, *a, **k):
    if flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND):
        _tripped(f'os.open {path!r} for writing')
    return _os_open(path, flags, *a, **k)
os.open = _guarded_os_open

for _name in ('mkdir', 'makedirs'):
    def _mk(*a, _name=_name, **k):
        _tripped(f'os.{_name} {a[0]!r}')
    setattr(os, _name, _mk)
'''


def console_scripts():
    """{name: (module, function)} of setup.py's console scripts."""
    text = (REPO / 'setup.py').read_text()
    return {name: (module, function) for name, module, function in
            re.findall(r"'(\w+) = ([\w.]+):(\w+)'", text)}


def planter_commands():
    """Every `planter` command path: the top level, each group, each sub-command."""
    sys.path.insert(0, str(REPO))
    from planter_ros.cli.main import COMMANDS
    paths = {()}
    for words in COMMANDS:
        paths.update(words[:i] for i in range(1, len(words) + 1))
    return sorted(paths)


@pytest.fixture
def guarded(tmp_path):
    """Run `python -c code args...` under the guard; returns (CompletedProcess, empty dirs)."""
    site = tmp_path / 'site'
    site.mkdir()
    (site / 'sitecustomize.py').write_text(GUARD)
    dirs = {name: tmp_path / name for name in ('home', 'ros_home', 'logs', 'cwd')}
    for path in dirs.values():
        path.mkdir()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), str(REPO)]),
               PYTHONDONTWRITEBYTECODE='1', ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               HOME=str(dirs['home']), ROS_HOME=str(dirs['ros_home']),
               ROS_LOG_DIR=str(dirs['logs']), MPLCONFIGDIR=str(dirs['home']))

    def run(code, *args):
        done = subprocess.run([sys.executable, '-c', code, *args], capture_output=True,
                              text=True, timeout=120, env=env, cwd=dirs['cwd'])
        left = {name: sorted(os.listdir(path)) for name, path in dirs.items()
                if os.listdir(path)}
        return done, left
    return run


def script(module, function, name):
    return (f'import sys; sys.argv[0] = {name!r}; from {module} import {function} as f; '
            'sys.exit(f())')


@pytest.mark.parametrize('name', sorted(console_scripts()))
@pytest.mark.parametrize('flag', ['--help', '-h', '--version'])
def test_every_console_script_answers_without_touching_anything(guarded, name, flag):
    module, function = console_scripts()[name]
    done, left = guarded(script(module, function, name), flag)
    assert done.returncode == 0, done.stderr
    assert 'GUARD' not in done.stderr and left == {}, (done.stderr, left)
    if flag == '--version':
        assert re.search(r'\b\d+\.\d+\.\d+\b', done.stdout), done.stdout
    else:
        assert 'usage' in done.stdout.lower(), done.stdout


@pytest.mark.parametrize('node', ['design_node', 'sync_node', 'monitor_node'])
def test_a_node_help_lists_its_parameters_with_their_ranges(guarded, node):
    module, function = console_scripts()[node]
    done, _ = guarded(script(module, function, node), '--help')
    expected = {'sync_node': ('can_channel', 'can_bitrate', '10000..1000000 bit/s'),
                'monitor_node': ('bag_path', 'window'),
                'design_node': ('plant_spacing', '0.05..2 m')}[node]
    for word in expected:
        assert word in done.stdout, (word, done.stdout)


def test_help_after_ros_args_belongs_to_ros_not_to_the_node():
    """`--help` after --ros-args is not the node's own: only what comes before counts."""
    sys.path.insert(0, str(REPO))
    from planter_ros.nodes.entry import own_arguments
    assert own_arguments(['--ros-args', '-p', 'x:=1', '--help']) == []
    assert own_arguments(['--help', '--ros-args']) == ['--help']


@pytest.mark.parametrize('words', planter_commands(), ids=lambda w: ' '.join(w) or 'planter')
def test_every_planter_command_answers_help_without_touching_anything(guarded, words):
    done, left = guarded(script('planter_ros.cli.main', 'main', 'planter'), *words, '--help')
    assert done.returncode == 0, done.stderr
    assert 'GUARD' not in done.stderr and left == {}, (done.stderr, left)
    assert done.stdout.startswith('usage: planter'), done.stdout


def test_planter_version(guarded):
    done, left = guarded(script('planter_ros.cli.main', 'main', 'planter'), '--version')
    assert done.returncode == 0 and left == {}, done.stderr
    assert re.fullmatch(r'planter \d+\.\d+\.\d+\S*\n', done.stdout), done.stdout


@pytest.mark.parametrize('code, what', [
    ('import rclpy', 'import rclpy'),
    ('import can', 'import can'),
    ('import socket; socket.socket()', 'socket'),
    ("open('x', 'w')", 'for writing'),
    ("import os; os.mkdir('d')", 'os.mkdir'),
])
def test_the_guard_trips_on_what_it_watches(guarded, code, what):
    done, _ = guarded(code)
    assert done.returncode == 97 and what in done.stderr, done.stderr


@pytest.mark.parametrize('node', ['sync_node', 'monitor_node'])
def test_the_guard_catches_a_node_started_for_its_help(guarded, node):
    """The nodes' main() (what the console scripts called before) starts the node even when
    asked for --help: the guard stops it."""
    done, _ = guarded(script(f'planter_ros.nodes.{node}', 'main', node), '--help')
    assert done.returncode == 97 and 'GUARD' in done.stderr, done.stderr
