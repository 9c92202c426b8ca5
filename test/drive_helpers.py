"""Shared fixtures and helpers for the CAN drive tests (python-can `virtual` bus).

Every test gets its own virtual channel (uuid) and every bus is closed in a fixture teardown:
virtual channels are process-wide and an unclosed bus queues frames forever.
"""
from __future__ import annotations

from collections.abc import Iterator
import contextlib
import os
import struct
import sys
import time
import uuid

import can
import pytest

from planter_ros.command.process import SWITCH_INTERVAL
from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.drive.cia402 import Cia402Drive, DriveConfig
from planter_ros.simdrive.drive import SimulatedDrive

NODE_ID = 1
RPDO1 = 0x200 + NODE_ID
SDO_RX = 0x600 + NODE_ID


@pytest.fixture
def channel():
    return f'planter-test-{uuid.uuid4().hex}'


@pytest.fixture
def spy(channel):
    """A separate listener on the same virtual channel: sees every frame anyone sends."""
    bus = can.Bus(interface='virtual', channel=channel)
    yield bus
    bus.shutdown()


@pytest.fixture
def sim(channel):
    drive = SimulatedDrive(channel, node_id=NODE_ID)
    drive.start()
    yield drive
    drive.stop()


@pytest.fixture
def make_drive(channel):
    """Factory for masters on the test channel; every one is shut down at teardown."""
    made = []

    def make(bus=None, **overrides) -> Cia402Drive:
        overrides.setdefault('can_interface', 'virtual')
        overrides.setdefault('can_channel', channel)
        overrides.setdefault('drive_node_id', NODE_ID)
        overrides.setdefault('step_timeout', 0.3)
        drive = Cia402Drive(DriveConfig(**overrides), bus=bus)
        made.append(drive)
        return drive

    yield make
    for drive in reversed(made):
        drive.shutdown()


@pytest.fixture
def enabled(sim, make_drive):
    """(master, simulated drive), enabled, gear ratio 12.5."""
    drive = make_drive(motor_gear_ratio=12.5)
    drive.connect_and_enable()
    return drive, sim


def drain(bus: can.BusABC) -> list[can.Message]:
    frames = []
    while (msg := bus.recv(timeout=0)) is not None:
        frames.append(msg)
    return frames


def rpdo_frames(frames):
    """(controlword, target velocity counts/s) of every RPDO1 frame, in order."""
    return [struct.unpack_from('<Hi', bytes(m.data)) for m in frames if m.arbitration_id == RPDO1]


def control_loop(drive: Cia402Drive, speed: float, until=None, timeout: float = 3.0,
                 period: float = 0.01) -> bool:
    """Run a control loop like sync_node's (command every period, heartbeat every 0.1 s)
    until `until()` is true (returns True) or `timeout` s passed (returns False)."""
    deadline = time.monotonic() + timeout
    next_heartbeat = 0.0
    while time.monotonic() < deadline:
        drive.send_velocity(speed)
        now = time.monotonic()
        if now >= next_heartbeat:
            drive.send_heartbeat()
            next_heartbeat = now + drive.config.heartbeat_period
        if until is not None and until():
            return True
        time.sleep(period)
    return until is None


def wait_until(condition, timeout: float = 3.0, period: float = 0.005) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(period)
    return condition()


def _threads() -> list[int]:
    try:
        return [int(tid) for tid in os.listdir('/proc/self/task')]
    except OSError:
        return [0]


def _schedule(policy: int, priority: int) -> None:
    for tid in _threads():
        with contextlib.suppress(ProcessLookupError):    # a thread that ended meanwhile
            os.sched_setscheduler(tid, policy, os.sched_param(priority))


@contextlib.contextmanager
def as_the_command_process() -> Iterator[None]:
    """This process's threads at the command process's SCHED_FIFO priority and interpreter
    switch interval, as the product runs its loop (command/process.py), then back to SCHED_OTHER
    and the interval before. A loop under test in the test process otherwise runs at an
    ordinary priority beside the suite's other work: a stall of it beyond ~55 ms at 1 turn/s
    leaves every CSP drive without targets, and a failed CI run tripped all five drives of
    test_drive_profiles at once. All threads: the loop waits for the interpreter whenever a
    bus reader holds it, and a reader at an ordinary priority would hold the loop back. Where
    SCHED_FIFO is refused (no CAP_SYS_NICE) the loop runs as it is."""
    interval = sys.getswitchinterval()
    try:
        _schedule(os.SCHED_FIFO, SyncLoopConfig().realtime_priority)
    except (OSError, AttributeError):
        pass                               # refused (for some threads): as it is
    sys.setswitchinterval(SWITCH_INTERVAL)
    try:
        yield
    finally:
        sys.setswitchinterval(interval)
        with contextlib.suppress(OSError, AttributeError):
            _schedule(os.SCHED_OTHER, 0)


def run_engine(engine, seconds: float, v: float | None, w: float = 0.0,
               after_step=None) -> bool:
    """The command process's loop in miniature, at its priority (`as_the_command_process`): a
    ground-speed sample (v m/s, w rad/s) every 20 ms (none while `v` is None: the speed goes
    stale), a step every SYNC period; `after_step(now)` after each step ends the loop early by
    returning True. Returns whether it ended so."""
    with as_the_command_process():
        return _run_engine(engine, seconds, v, w, after_step)


def _run_engine(engine, seconds, v, w, after_step) -> bool:
    end = time.monotonic() + seconds
    next_sample = 0.0
    next_tick = time.monotonic()
    while time.monotonic() < end:
        now = time.monotonic()
        if v is not None and now >= next_sample:
            engine.sample(v, w, now)
            next_sample = now + 0.02
        engine.step(now)
        if after_step is not None and after_step(now):
            return True
        next_tick = max(next_tick + engine.period, time.monotonic())
        time.sleep(max(next_tick - time.monotonic(), 0.0))
    return False
