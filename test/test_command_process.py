"""The command process (planter_ros.command): no rclpy in it; fed over its channel it drives the
simulated drives (in another process, over a CAN socket pair); orphaned (its shell SIGKILLed) it
ramps to zero, disables the drives and exits; killed itself, its shell reports and restarts it."""
import json
import logging
import os
from pathlib import Path
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from drive_helpers import wait_until
from planter_ros.command.client import CommandClient
from planter_ros.command.reports import Reply
from planter_ros.command.settings import CommandSettings
from planter_ros.drive.socket_bus import INTERFACE, SocketPairBus, socket_pair
from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.control.machine_law import TurnConfig
from planter_ros.control.phase_lock import PhaseLockConfig
from planter_ros.design import from_json, to_json
from planter_ros.drive.config import DriveConfig
from planter_ros.simdrive.bus import SimulatedBus
from planter_ros.drive.state_names import (OPERATION_ENABLED, READY_TO_SWITCH_ON,
                                           SWITCH_ON_DISABLED)
from planter_ros.rows import Row
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
from planter_ros.sensing.row_speed import YawRateLimits
from planter_ros.sim.runs import five_bar_design_message

pytestmark = pytest.mark.realtime          # (test/conftest.py)

REPO = Path(__file__).resolve().parents[1]
ROWS = [Row(0, 'left', 0.5, 1), Row(1, 'right', -0.5, 2)]
DESIGN = to_json(five_bar_design_message(spacing=0.2))


def settings(can_fd, **loop):
    loop.setdefault('realtime_priority', 0)       # tests share the machine: ask for none
    return CommandSettings(
        DriveConfig(can_interface=INTERFACE, can_channel=str(can_fd), step_timeout=0.5),
        SyncLoopConfig(**loop), ROWS,
        (PhaseLockConfig(), GroundSpeedLimits(), YawRateLimits(), TurnConfig()))


@pytest.fixture
def drives_and_fd():
    """The simulated drives on one end of a CAN socket pair (here), the other end's fd (for
    the command process to inherit)."""
    ours, theirs = socket_pair()
    sims = SimulatedBus(SocketPairBus(ours), [row.drive_node_id for row in ROWS])
    sims.start()
    yield sims, theirs.fileno()
    sims.stop()
    theirs.close()


def test_the_command_process_imports_no_rclpy_and_no_dds():
    code = ('import sys, planter_ros.command.process, planter_ros.command.engine; '
            'bad = [m for m in sys.modules if m.split(".")[0] in ("rclpy", "rmw", "rosidl_parser",'
            ' "fastdds", "rpyutils")]; print(bad); sys.exit(1 if bad else 0)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, cwd=REPO,
                         timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr


def test_fed_over_its_channel_it_drives_every_row_and_stops_on_request(drives_and_fd):
    sims, fd = drives_and_fd
    lines = []
    client = CommandClient(settings(fd), log=lambda level, text: lines.append((level, text)))
    client.enable()
    try:
        assert client.ready is not None and client.ready.running == 2 == client.running
        client.set_design(from_json(DESIGN), DESIGN, time.monotonic())

        def fed(seconds):
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                client.sample(0.4, 0.0, time.monotonic())
                time.sleep(0.02)
        fed(1.5)
        assert all(d.state == OPERATION_ENABLED for d in sims.drives)
        assert all(d.target_velocity > 0 for d in sims.drives)
        joints = [f.joint for f in client.feedback()]
        assert joints == ['left/sun_bar', 'right/sun_bar']
        reply = client.section('right', False, time.monotonic())
        assert reply.ok and reply.changed and 'right off' in reply.message
        assert client.sections() == {'left': True, 'right': False} or wait_until(
            lambda: client.sections() == {'left': True, 'right': False}, 1.0)
        reply = client.reset_fault('left')
        assert not reply.ok and 'no drive fault to reset' in reply.message
        levels = {report.task: report.level for report, _ in client.reports(time.monotonic())}
        assert levels['command process'] in (0, 1)          # OK (or WARN: no real time)
        assert 'left' in levels and 'bus' in levels
    finally:
        client.shutdown()
    assert client.process.returncode == 0
    assert all(d.state in (READY_TO_SWITCH_ON, SWITCH_ON_DISABLED) for d in sims.drives)
    assert sims.watchdog_trips == []                         # a clean stop, not the watchdog
    assert client.final_report().rows[0].label == 'left'
    assert not [t for level, t in lines if level >= logging.ERROR], lines


SHELL = textwrap.dedent('''
    import sys, time
    sys.path.insert(0, {test_dir!r})
    from test_command_process import settings, DESIGN
    from planter_ros.command.client import CommandClient
    from planter_ros.design import from_json
    client = CommandClient(settings(int(sys.argv[1])), log=lambda level, text: None)
    client.enable()
    client.set_design(from_json(DESIGN), DESIGN, time.monotonic())
    print(client.process.pid, flush=True)
    while True:
        client.sample(0.4, 0.0, time.monotonic())
        time.sleep(0.02)
''')


def alive(pid):
    try:
        state = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state != 'Z'


def test_a_shell_killed_with_sigkill_leaves_no_motor_running_and_no_process(drives_and_fd):
    sims, fd = drives_and_fd
    code = SHELL.format(test_dir=str(Path(__file__).parent))
    shell = subprocess.Popen([sys.executable, '-c', code, str(fd)], pass_fds=(fd,),
                             stdout=subprocess.PIPE, text=True, cwd=REPO)
    command_pid = None
    try:
        command_pid = int(shell.stdout.readline())
        assert wait_until(lambda: all(d.motor_velocity > 5.0 for d in sims.drives), 10.0)
        shell.send_signal(signal.SIGKILL)
        shell.wait(5)
        killed_at = time.monotonic()
        # the command process ramps down, disables the drives and exits by itself
        assert wait_until(lambda: not alive(command_pid), 15.0), 'command process runs on'
        stopped_after = time.monotonic() - killed_at
        assert all(d.state in (READY_TO_SWITCH_ON, SWITCH_ON_DISABLED) for d in sims.drives)
        assert all(abs(d.motor_velocity) < 1.0 for d in sims.drives)
        assert all(d.nmt_state == 'PRE-OPERATIONAL' for d in sims.drives)
        # stopped by the command process itself, not by the drives' watchdogs
        assert sims.watchdog_trips == [], sims.watchdog_trips
        assert stopped_after < 10.0
    finally:
        if shell.poll() is None:
            shell.kill()
            shell.wait()
        if command_pid is not None and alive(command_pid):
            os.kill(command_pid, signal.SIGKILL)


def test_a_command_process_that_dies_is_restarted_held_until_an_operator_enables_it(
        drives_and_fd):
    sims, fd = drives_and_fd
    lines = []
    client = CommandClient(settings(fd, command_restarts=1),
                           log=lambda level, text: lines.append((level, text)))
    client.enable()
    try:
        first = client.process.pid
        client.set_design(from_json(DESIGN), DESIGN, time.monotonic())
        for _ in range(50):
            client.sample(0.4, 0.0, time.monotonic())
            time.sleep(0.02)
        os.kill(first, signal.SIGKILL)
        assert wait_until(lambda: client.restarts == 1 and 'held' in client.info, 20.0)
        assert client.process.pid != first
        assert any(level == logging.ERROR and 'command process died' in text
                   and 'until an operator enables them' in text for level, text in lines)
        # held: the ground speed goes on, yet no drive is enabled and the rows stay at zero
        for _ in range(50):
            client.sample(0.4, 0.0, time.monotonic())
            time.sleep(0.02)
        assert client.held and 'ready' not in client.info
        assert all(d.state != OPERATION_ENABLED for d in sims.drives)
        report = client.process_report(time.monotonic())
        assert report.level == 1 and 'rows held at zero' in report.message
        assert 'enable_rows' in report.message
        assert client.reset_fault('left').ok is False
        reply = client.operator_enable()
        assert reply.ok, reply.message
        assert wait_until(lambda: all(d.state == OPERATION_ENABLED for d in sims.drives), 5.0)
        assert client.operator_enable() == Reply(False, 'the rows are enabled already')

        def fed():
            client.sample(0.4, 0.0, time.monotonic())
            return all(d.target_velocity > 0 for d in sims.drives)
        assert wait_until(fed, 5.0)
        report = client.process_report(time.monotonic())
        assert report.level in (1, 2) and 'died' in report.message  # WARN once running again
        # no restart left: the next death is an ERROR that stays
        os.kill(client.process.pid, signal.SIGKILL)
        assert wait_until(lambda: client.dead, 10.0)
        report = client.process_report(time.monotonic())
        assert report.level == 2 and 'not restarted' in report.message
    finally:
        client.shutdown()


def test_the_shell_asks_for_a_larger_cpu_share_for_every_thread_or_says_why_not():
    # in a child process (this one keeps its priority): threads running before the request and
    # those started after it all get the nice value, or the refusal names the limit to raise
    script = textwrap.dedent('''
        import json, os, threading, time
        from planter_ros.host import realtime
        stop = threading.Event()
        before = threading.Thread(target=stop.wait); before.start()
        refused = realtime.request_nice(-3)
        after = threading.Thread(target=stop.wait); after.start()
        time.sleep(0.1)
        tids = [int(t) for t in os.listdir('/proc/self/task')]
        nices = sorted({os.getpriority(os.PRIO_PROCESS, t) for t in tids})
        print(json.dumps([refused, len(tids), nices, realtime.request_nice(0)]))
        stop.set()
    ''')
    out = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                         timeout=60, cwd=REPO)
    assert out.returncode == 0, out.stderr
    refused, threads, nices, nothing = json.loads(out.stdout)
    assert threads >= 3
    if not refused:
        assert nices == [-3]
    else:
        assert 'nice -3 refused' in refused and 'CAP_SYS_NICE' in refused
    assert nothing == ''                        # 0 asks for nothing


def test_a_deliberate_exit_is_never_taken_for_a_crash_and_nothing_restarts_after_a_stop(
        drives_and_fd):
    """SIGTERM to the command process alone: it ramps to zero, disables the drives and says
    why it ends; the client does not restart it (restarts left), and tells its shell."""
    sims, fd = drives_and_fd
    lines, exits = [], []
    client = CommandClient(settings(fd, command_restarts=3),
                           log=lambda level, text: lines.append((level, text)),
                           on_exit=exits.append)
    client.enable()
    try:
        client.set_design(from_json(DESIGN), DESIGN, time.monotonic())
        for _ in range(50):
            client.sample(0.4, 0.0, time.monotonic())
            time.sleep(0.02)
        assert all(d.motor_velocity > 5.0 for d in sims.drives)
        os.kill(client.process.pid, signal.SIGTERM)
        assert wait_until(lambda: client.dead, 15.0)
        assert exits == ['SIGTERM'] and client.restarts == 0
        assert client.process.returncode == 0
        assert all(d.state in (READY_TO_SWITCH_ON, SWITCH_ON_DISABLED) for d in sims.drives)
        assert all(abs(d.motor_velocity) < 1.0 for d in sims.drives)
        assert sims.watchdog_trips == []                 # the process stopped them itself
        assert client.final_report().accepted > 0        # its report came (not lost at close)
        report = client.process_report(time.monotonic())
        assert report.level == 2 and 'stopped by SIGTERM' in report.message
        assert client.operator_enable().ok is False
    finally:
        client.shutdown()
    assert not any('restarting' in text for _, text in lines), lines


def test_a_stop_asked_for_during_a_crash_restarts_nothing(drives_and_fd):
    sims, fd = drives_and_fd
    stop = []
    client = CommandClient(settings(fd, command_restarts=3), log=lambda level, text: None,
                           stop_asked=lambda: bool(stop))
    client.enable()
    try:
        stop.append('SIGTERM')                 # the shell's own stop signal came
        pid = client.process.pid
        os.kill(pid, signal.SIGKILL)
        assert wait_until(lambda: client.dead, 15.0)
        assert client.restarts == 0 and client.process.pid == pid
    finally:
        client.shutdown()
