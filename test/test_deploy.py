"""doc/deploy.md walked as far as this machine allows (no CAN hardware, no ROS launch tools):
the files it names exist and parse, the systemd units name executables and files that exist and
start the graph after the CAN interfaces, the launch files' arguments are the nodes'
parameters, and the example machine file with a scene gives each node only what it declares."""
import ast
import os
import re
import shlex
import shutil
import subprocess
import sys

import pytest

from cli_helpers import REPO
from planter_ros.scene.doc_tables import node_parameter_specs
from planter_ros.scene.machine_file import MachineFileError, deployment_parameters
from planter_ros.scene.schema import node_specs

DEPLOY = (REPO / 'doc' / 'deploy.md').read_text()
MACHINE = REPO / 'config' / 'machines' / 'tomato_4row_tractor.yaml'
SCENE = REPO / 'config' / 'tomato_4row.yaml'


def console_scripts():
    return set(re.findall(r"'(\w+) = planter_ros\.", (REPO / 'setup.py').read_text()))


def unit(name):
    """A systemd unit as {section: [(key, value), ...]} (keys may repeat); fails on a line
    that is neither a section, a comment, blank nor key=value."""
    sections, current = {}, None
    for number, line in enumerate((REPO / 'systemd' / name).read_text().splitlines(), 1):
        if not line.strip() or line.lstrip().startswith('#'):
            continue
        if re.fullmatch(r'\[\w+\]', line):
            current = sections.setdefault(line[1:-1], [])
            continue
        key, sep, value = line.partition('=')
        assert sep and current is not None and re.fullmatch(r'[A-Za-z]+', key), \
            f'{name}:{number}: {line}'
        current.append((key, value))
    return sections


def values(section, key):
    return [v for k, v in section if k == key]


def test_the_files_deploy_md_names_exist():
    named = set(re.findall(r'\]\(\.\./((?:config|launch|systemd|doc)/[^)#]+)\)', DEPLOY))
    named |= set(re.findall(r'`((?:config|launch|systemd)/[\w./-]+)`', DEPLOY))
    assert {'systemd/planter.service', 'systemd/planter-can.service', 'systemd/environment',
            'launch/tractor.launch.py', 'config/machines/tomato_4row_tractor.yaml'} <= named
    for path in named:
        assert (REPO / path).is_file(), path
    for page in re.findall(r'\]\((\w+\.md)(?:#[\w-]+)?\)', DEPLOY):
        assert (REPO / 'doc' / page).is_file(), page


def test_every_executable_deploy_md_names_is_installed():
    for name in ('planter', 'design_node', 'sync_node', 'monitor_node', 'ground_speed_node'):
        assert f'`{name}`' in DEPLOY
        assert name in console_scripts()


def test_the_units_start_the_graph_after_the_can_interfaces_and_stop_it_cleanly():
    can, graph = unit('planter-can.service'), unit('planter.service')
    assert values(can['Service'], 'Type') == ['oneshot']
    assert values(can['Service'], 'RemainAfterExit') == ['yes']
    assert 'planter-can.service' in values(graph['Unit'], 'Requires')[0]
    assert 'planter-can.service' in values(graph['Unit'], 'After')[0]
    service = graph['Service']
    assert values(service, 'Restart') == ['on-failure'] and values(service, 'RestartSec')
    assert values(service, 'KillSignal') == ['SIGINT']      # our nodes' clean shutdown
    for u in (can, graph):
        assert values(u['Service'], 'EnvironmentFile') == ['/etc/planter/environment']
        assert values(u['Install'], 'WantedBy') == ['multi-user.target']


def commands(name):
    """Every shell command line of a unit's Exec* entries (inside bash -c '...')."""
    out = []
    for section in unit(name).values():
        for key, value in section:
            if key.startswith('Exec'):
                words = shlex.split(value)
                script = words[words.index('-c') + 1] if '-c' in words else value
                out += [c.strip() for c in re.split(r'[;|]|&&', script) if c.strip()]
    return out


@pytest.mark.parametrize('name', ['planter-can.service', 'planter.service'])
def test_the_units_name_executables_and_files_that_exist(name):
    seen = 0
    for command in commands(name):
        words = shlex.split(command)
        if words[:2] == ['python3', '-m']:
            module = words[2]
            assert module.startswith('planter_ros.')
            assert (REPO / (module.replace('.', '/') + '.py')).is_file(), module
            seen += 1
        elif words[:2] == ['exec', 'ros2'] or words[:1] == ['ros2']:
            words = words[1:] if words[0] == 'exec' else words
            words = [w for w in words if not w.startswith('-')]       # launch's options
            assert words[1:3] == ['launch', 'planter_ros']
            assert (REPO / 'launch' / words[3]).is_file(), words[3]
            seen += 1
    assert seen


def test_the_environment_file_is_key_value():
    text = (REPO / 'systemd' / 'environment').read_text()
    pairs = dict(line.split('=', 1) for line in text.splitlines()
                 if line.strip() and not line.startswith('#'))
    assert pairs['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST' and pairs['ROS_SETUP']


def test_the_can_unit_brings_up_the_example_machine_at_its_bit_rates():
    env = dict(os.environ, PYTHONPATH=str(REPO))
    out = subprocess.run([sys.executable, '-m', 'planter_ros.scene.machine_file', '--ip-commands',
                          str(MACHINE)], capture_output=True, text=True, env=env, timeout=60)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert 'ip link set can0 type can bitrate 500000 restart-ms 100' in lines
    assert 'ip link set can1 type can bitrate 250000 restart-ms 100' in lines
    assert lines.index('ip link set can0 up') > lines.index(
        'ip link set can0 type can bitrate 500000 restart-ms 100')
    check = subprocess.run([sys.executable, '-m', 'planter_ros.scene.machine_file', '--check',
                            str(MACHINE), '--scene', str(SCENE)], capture_output=True,
                           text=True, env=env, timeout=60)
    assert check.returncode == 0 and check.stdout.endswith(': ok\n'), check.stderr


def launch_arguments(path):
    """(declared argument names, {(executable, parameter): argument} from dict literals)."""
    tree = ast.parse(path.read_text())
    declared, passed = set(), {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, 'id', '') == 'DeclareLaunchArgument':
            declared.add(node.args[0].value)
        if isinstance(node, ast.Call) and getattr(node.func, 'id', '') == 'Node':
            kw = {k.arg: k.value for k in node.keywords}
            executable = kw['executable'].value if isinstance(kw['executable'], ast.Constant) \
                else None
            for dict_node in ast.walk(kw.get('parameters', ast.List(elts=[]))):
                if isinstance(dict_node, ast.Dict):
                    for key, value in zip(dict_node.keys, dict_node.values):
                        if isinstance(value, ast.Call) and \
                                getattr(value.func, 'id', '') == 'LaunchConfiguration':
                            passed[(executable, key.value)] = value.args[0].value
    return declared, passed


def test_the_single_row_launch_file_arguments_are_node_parameters():
    declared, passed = launch_arguments(REPO / 'launch' / 'planter.launch.py')
    assert passed and set(passed.values()) <= declared
    for executable, parameter in passed:
        assert parameter in node_parameter_specs(executable), (executable, parameter)
    assert declared - set(passed.values()) == {'scene'}      # the file every node reads


def test_the_tractor_launch_file_arguments_are_node_parameters():
    path = REPO / 'launch' / 'tractor.launch.py'
    tree = ast.parse(path.read_text())
    declared, _ = launch_arguments(path)
    constants = {t.id: ast.literal_eval(node.value) for node in tree.body
                 if isinstance(node, ast.Assign) for t in node.targets
                 if isinstance(t, ast.Name) and t.id in ('NODES', 'ARGUMENT_PARAMETERS')}
    assert set(constants['NODES']) == console_scripts() - {'planter'}
    for argument, (node, parameter) in constants['ARGUMENT_PARAMETERS'].items():
        assert argument in declared
        assert parameter in node_parameter_specs(node), (node, parameter)
    assert declared - set(constants['ARGUMENT_PARAMETERS']) == {'machine', 'scene'}
    # the launch function sets each of those parameters from its argument
    function = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == '_nodes')
    keys = {k.value for d in ast.walk(function) if isinstance(d, ast.Dict) for k in d.keys
            if isinstance(k, ast.Constant)}
    assert {parameter for _, parameter in constants['ARGUMENT_PARAMETERS'].values()} <= keys


def test_the_machine_file_gives_each_node_only_what_it_declares():
    params, warnings = deployment_parameters(MACHINE, SCENE, {'ground_speed_node': {
        'sources': ['isobus_selected', 'gnss'], 'yaw_rate_source': 'gnss'}})
    assert warnings == []
    rows = params['sync_node']['rows']
    for node in ('design_node', 'sync_node', 'monitor_node'):
        declared = node_specs(node, 'five_bar', rows)
        assert set(params[node]) <= set(declared), (node, set(params[node]) - set(declared))
    assert params['monitor_node']['antenna_position'] == [0.0, 0.0]
    assert params['monitor_node']['left_outer.longitudinal_offset'] == -2.5
    assert params['ground_speed_node']['isobus_channel'] == 'can1'
    assert set(params['ground_speed_node']) <= set(node_parameter_specs('ground_speed_node'))


def test_a_scene_the_machine_cannot_run_or_other_rows_are_refused(tmp_path):
    other = tmp_path / 'other.yaml'
    other.write_text(SCENE.read_text().replace('left_outer', 'far_left'))
    with pytest.raises(MachineFileError, match='names the rows far_left, .* allowed the same '
                                               'rows'):
        deployment_parameters(MACHINE, other)
    slow = tmp_path / 'slow.yaml'
    slow.write_text(MACHINE.read_text().replace('max_motor_speed: 628.3 ',
                                                'max_motor_speed: 50.0 '))
    with pytest.raises(MachineFileError, match='motor_max_speed = 50 rad/s .* of row '
                                               'left_outer of the machine file'):
        deployment_parameters(slow, SCENE)


@pytest.mark.skipif(shutil.which('systemd-analyze') is None, reason='no systemd-analyze here')
def test_systemd_analyze_verifies_the_units_without_a_word(tmp_path):
    """systemd's own reading of the units (a reference we did not write): every key known,
    every value parsed, the executables there. It warns but exits 0 on a bad key: silence is
    the pass."""
    for name in ('planter.service', 'planter-can.service'):
        shutil.copy(REPO / 'systemd' / name, tmp_path / name)
    out = subprocess.run(['systemd-analyze', 'verify', str(tmp_path / 'planter.service'),
                          str(tmp_path / 'planter-can.service')], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0 and out.stdout == '' and out.stderr == '', out.stderr
    # and it is not silent about a mistake
    (tmp_path / 'planter.service').write_text(
        (REPO / 'systemd' / 'planter.service').read_text().replace('KillMode=mixed',
                                                                   'KillMode=gently'))
    out = subprocess.run(['systemd-analyze', 'verify', str(tmp_path / 'planter.service')],
                         capture_output=True, text=True, timeout=60)
    assert 'Failed to parse kill mode' in out.stderr


def test_the_graph_unit_stops_the_main_process_first_and_runs_with_only_what_it_needs():
    from planter_ros.control.loop_timing import SyncLoopConfig
    service = unit('planter.service')['Service']
    # SIGINT to `ros2 launch` alone, which stops every node; SIGKILL only after the timeout
    assert values(service, 'KillMode') == ['mixed'] and values(service, 'KillSignal') == ['SIGINT']
    assert int(values(service, 'TimeoutStopSec')[0]) >= 20
    # SCHED_FIFO at the command process's priority, memory locked, the shell's nice value
    assert int(values(service, 'LimitRTPRIO')[0]) > SyncLoopConfig().realtime_priority
    assert values(service, 'LimitMEMLOCK') == ['infinity']
    assert int(values(service, 'LimitNICE')[0]) <= SyncLoopConfig().shell_nice
    # a dedicated user, no capability at all
    assert values(service, 'User') == ['planter'] and values(service, 'Group') == ['planter']
    assert values(service, 'CapabilityBoundingSet') == [''] and \
        values(service, 'AmbientCapabilities') == ['']
    assert values(service, 'NoNewPrivileges') == ['yes']
    assert 'AF_CAN' in values(service, 'RestrictAddressFamilies')[0]
    can = unit('planter-can.service')['Service']
    assert values(can, 'CapabilityBoundingSet') == ['CAP_NET_ADMIN']


def stop_timeouts(path):
    """(STOP_TIMEOUTS of a launch file, whether every Node(...) of it passes **STOP_TIMEOUTS)."""
    tree = ast.parse(path.read_text())
    timeouts = next(ast.literal_eval(node.value) for node in tree.body
                    if isinstance(node, ast.Assign) and
                    getattr(node.targets[0], 'id', '') == 'STOP_TIMEOUTS')
    nodes = [node for node in ast.walk(tree) if isinstance(node, ast.Call) and
             getattr(node.func, 'id', '') == 'Node']
    passed = [any(k.arg is None and getattr(k.value, 'id', '') == 'STOP_TIMEOUTS'
                  for k in node.keywords) for node in nodes]
    return timeouts, bool(nodes) and all(passed)


@pytest.mark.parametrize('name', ['planter.launch.py', 'tractor.launch.py'])
def test_launch_escalates_a_stop_only_after_the_graph_had_time_to_stop_and_before_systemd(name):
    """launch's own escalation (SIGTERM after `sigterm_timeout`, SIGKILL `sigkill_timeout`
    later; 5 s each by default) must not cut a clean stop short, and must come before the
    unit's TimeoutStopSec; the unit's SIGINT must reach the nodes (`--noninteractive`: launch
    then passes SIGINT on; interactive, it assumes the terminal sent it to every node)."""
    timeouts, every_node = stop_timeouts(REPO / 'launch' / name)
    assert every_node, f'a Node of {name} does not pass **STOP_TIMEOUTS'
    sigterm, sigkill = float(timeouts['sigterm_timeout']), float(timeouts['sigkill_timeout'])
    service = unit('planter.service')['Service']
    assert 5.0 < sigterm and sigterm + sigkill < float(values(service, 'TimeoutStopSec')[0])
    assert 'ros2 launch --noninteractive ' in values(service, 'ExecStart')[0]


def test_after_an_automatic_restart_the_sync_node_holds_the_rows_and_not_after_a_clean_stop(
        tmp_path):
    """The note ExecStopPost writes (kept across restarts only) is the one launch hands the
    sync node; what it says decides whether the rows wait for an operator."""
    from planter_ros.control.loop_timing import SyncLoopConfig
    from planter_ros.nodes.sync_node import restart_hold_reason
    service = unit('planter.service')['Service']
    note = '/run/planter/last-stop'
    assert note in values(service, 'ExecStopPost')[0] and '$SERVICE_RESULT' in \
        values(service, 'ExecStopPost')[0]
    assert f'last_stop_file:={note}' in values(service, 'ExecStart')[0]
    assert values(service, 'RuntimeDirectory') == ['planter']
    assert values(service, 'RuntimeDirectoryPreserve') == ['restart']
    path = tmp_path / 'last-stop'
    loop = SyncLoopConfig(last_stop_file=str(path))
    assert restart_hold_reason(loop) == ''                        # a boot: no note
    for text, held in (('success exited 0', False), ('exit-code exited 1', True),
                       ('signal killed 9', True), ('timeout killed 9', True)):
        path.write_text(text + '\n')
        assert bool(restart_hold_reason(loop)) is held, text
        assert bool(restart_hold_reason(SyncLoopConfig(last_stop_file=str(path),
                                                       enable_after_restart=True))) is False
