"""The command process: `python -m planter_ros.command --fd N --parent PID`.

No DDS participant and no rclpy in this process (a test checks `sys.modules`): a node joining
the ROS graph stalls a publishing process for up to a second (doc/command.md), and nothing here
publishes. It owns the CAN bus, the CiA 402 masters, the heartbeats and the row loop
(`CommandEngine`) and is fed by its shell (sync_node) over the channel on fd N
(`command.channel`):

shell -> here: `settings` (first), `speed` [v, ω_z, t] (latest value), `design` text,
`section` / `reset` requests [id, row, ...] (answered by `reply` [id, ok, message, changed]),
`configure` (the law's settings), `stop`.
here -> shell: `built`, `ready`, `error` (start), `log` [level, line], `fb` (every control
period: joint feedback, commands, sections, a snapshot), `diag` (reports, every diagnostics
period), `final` (the run's figures).

It asks for SCHED_FIFO (`realtime_priority`) and locked memory, and says in one log line (and
in the `ready` message, which the shell puts in /diagnostics) what it did not get, then runs
on. Supervision: the kernel sends SIGTERM when the parent dies (PR_SET_PDEATHSIG) and the
channel reads end-of-file; either way the process is orphaned: every row ramps to 0 at its
acceleration limit, the drives are disabled (0x60FF = 0, 0x06, pre-operational) and it exits.
It never runs on without its shell. SIGINT is ignored (a terminal's Ctrl-C reaches the whole
process group; the shell decides).
"""
from __future__ import annotations

import argparse
import gc
import logging
import math
import os
import signal
import socket
import sys
import time
from typing import Any

from planter_ros.config import ConfigError
from planter_ros.control.cam_law import profile_from_data
from planter_ros.design import from_json
from planter_ros.drive.errors import DriveError

from . import realtime
from .channel import Channel, ChannelClosed
from .engine import CommandEngine
from .settings import CommandSettings, law_from_data
from planter_ros.drive.socket_bus import INTERFACE, SocketPairBus

__all__ = ['ORPHAN_RAMP_LIMIT', 'main', 'run']

ORPHAN_RAMP_LIMIT = 5.0       # s an orphaned process ramps at most before disabling anyway
SWITCH_INTERVAL = 5e-4        # s a worker thread may hold the interpreter while the loop waits
LIBRARY_LOGGERS = ('can', 'canopen', 'planter_ros.drive')


class _ChannelLog(logging.Handler):
    """python-can's, canopen's and the drive master's warnings, to the shell's log."""

    def __init__(self, channel: Channel) -> None:
        super().__init__(logging.WARNING)
        self.channel = channel

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self.channel.send('log', [record.levelno, f'{record.name}: {record.getMessage()}'])
        except (ChannelClosed, ValueError):
            pass


class _Terminated:
    """SIGTERM (the parent died: PR_SET_PDEATHSIG, or a service manager stops the group)."""

    def __init__(self) -> None:
        self.received = False
        signal.signal(signal.SIGTERM, self._on_signal)
        signal.signal(signal.SIGINT, signal.SIG_IGN)

    def _on_signal(self, _signum: int, _frame: Any) -> None:
        self.received = True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='planter_ros.command')
    parser.add_argument('--fd', type=int, required=True, help='channel socket (inherited)')
    parser.add_argument('--parent', type=int, required=True, help="the shell's pid")
    args = parser.parse_args(argv)
    terminated = _Terminated()
    death = realtime.die_with_parent(args.parent)
    channel = Channel(socket.socket(fileno=args.fd))
    try:
        return run(channel, terminated, death)
    finally:
        channel.close()


def _settings(channel: Channel, terminated: _Terminated) -> CommandSettings | None:
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and not terminated.received:
        for kind, payload in channel.receive(0.1):
            if kind == 'settings':
                return CommandSettings.from_data(payload)
    return None


def run(channel: Channel, terminated: _Terminated, death: str = '') -> int:
    """Start, loop, stop (see the module doc); the exit code."""
    def log(level: int, text: str) -> None:
        try:
            channel.send('log', [level, text])
        except ChannelClosed:
            pass

    try:
        settings = _settings(channel, terminated)
    except ChannelClosed:
        return 1
    if settings is None:
        return 1
    handler = _ChannelLog(channel)
    for name in LIBRARY_LOGGERS:
        logging.getLogger(name).addHandler(handler)
        logging.getLogger(name).propagate = False
    refused = [why for why in (realtime.request_fifo(settings.loop.realtime_priority),
                               realtime.lock_memory(), death) if why]
    # the loop waits for the interpreter whenever a worker thread holds it (the bus listener
    # decoding a burst of TPDOs, the planting angles of a new design): ask such a thread to
    # hand it over after 0.5 ms instead of Python's default 5 ms
    sys.setswitchinterval(SWITCH_INTERVAL)
    if refused:
        log(logging.WARNING, 'command process runs without real-time guarantees: '
                             + '; '.join(refused))
    cfg = settings.drive
    engine = None
    try:
        bus = SocketPairBus(cfg.can_channel) if cfg.can_interface == INTERFACE else None
        engine = CommandEngine(cfg, settings.loop, settings.rows, settings.law, bus=bus, log=log,
                               setups=settings.setups)
        channel.send('built', {'bus_load': engine.bus_load.load,
                               'bitrate': engine.bus_load.bitrate, 'pid': os.getpid()})
        engine.enable()
    except (DriveError, ConfigError, OSError) as exc:
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        kind = 'config' if isinstance(exc, ConfigError) and not isinstance(exc, DriveError) \
            else 'drive'
        try:
            channel.send('error', [kind, text])
        except ChannelClosed:
            pass
        if engine is not None:
            engine.shutdown()
        return 2
    try:
        channel.send('ready', {'running': sum(unit.running for unit in engine.units),
                               'mode': engine.mode_text(),
                               'realtime': refused, 'pid': os.getpid(),
                               'priority': settings.loop.realtime_priority})
    except ChannelClosed:
        pass
    gc.freeze()       # start-up's objects out of the collector's reach: short collections
    orphaned = _loop(engine, channel, settings, terminated)
    _ramp_down(engine, orphaned)
    engine.shutdown()
    try:
        channel.send('final', engine.final_report())
    except ChannelClosed:
        pass
    return 0


def _loop(engine: CommandEngine, channel: Channel, settings: CommandSettings,
          terminated: _Terminated) -> bool:
    """Until `stop` (False) or orphaned (True)."""
    period = engine.period
    diag_period = settings.loop.diagnostics_period
    next_tick = time.monotonic()
    next_diag = next_tick
    skipped = 0
    sampled = -math.inf         # when a sample last sent every row's frames (profile velocity)
    while True:
        if terminated.received:
            return True
        try:
            messages = channel.receive(max(next_tick - time.monotonic(), 0.0))
        except ChannelClosed:
            return True
        speed = None
        for kind, payload in messages:
            if kind == 'speed':
                skipped += speed is not None
                speed = payload
            elif kind == 'stop':
                return False
            else:
                _handle(engine, channel, kind, payload)
        if speed is not None:
            v, w, stamp = speed
            engine.sample(v, w, stamp)
            sampled = time.monotonic()
        now = time.monotonic()
        if now >= next_tick:
            # in profile velocity a sample sends every row's frames itself: the periodic step
            # (the drives' keep-alive, the law's ramps without samples) only when none did
            # within a period, so it does not hold up the next sample's frames
            if engine.csp or now - sampled >= period:
                engine.step(now)
            next_tick = max(next_tick + period, now)     # behind: take up the pace from now
            try:
                channel.send('fb', {'feedback': [[f.joint, f.position, f.velocity, f.stamp]
                                                 for f in engine.feedback()],
                                    'commands': engine.commands(),
                                    'sections': engine.sections(),
                                    'snapshot': engine.snapshot(), 'skipped': skipped})
                if now >= next_diag:
                    next_diag = now + diag_period
                    channel.send('diag', [[[r.task, r.level, r.message, list(r.values)], hw]
                                          for r, hw in engine.reports(now)])
            except ChannelClosed:
                return True


def _handle(engine: CommandEngine, channel: Channel, kind: str, payload: Any) -> None:
    now = time.monotonic()
    try:
        if kind == 'design':
            engine.set_design(from_json(payload), payload, now)
        elif kind == 'design_cam':          # the shell planned the cam (speed_profile: cam)
            text, cam, why, arrived = payload
            profile = None if cam is None else profile_from_data(cam)
            engine.set_design(from_json(text), text, now, planned=(profile, why),
                              arrived=float(arrived))
        elif kind == 'section':
            ident, name, on = payload
            ok, message, changed = engine.section(name, bool(on), now)
            channel.send('reply', [ident, ok, message, changed])
        elif kind == 'reset':
            ident, name = payload
            ok, message = engine.reset_fault(name)
            channel.send('reply', [ident, ok, message, False])
        elif kind == 'configure':
            engine.configure(law_from_data(payload))
    except (ValueError, KeyError, TypeError, ConfigError, StopIteration) as exc:
        engine.log(logging.ERROR, f'{kind} ignored: {exc}')


def _ramp_down(engine: CommandEngine, orphaned: bool) -> None:
    """Every row to 0 at its acceleration limit (frames, SYNC and heartbeat go on) before the
    drives are disabled: asked to stop, or orphaned."""
    if orphaned:
        engine.log(logging.ERROR, 'command process orphaned (its shell died): ramping every '
                                  'row to 0, then disabling the drives')
    start = time.monotonic()
    engine.stop_ramp(start)
    while time.monotonic() - start < ORPHAN_RAMP_LIMIT:
        engine.step(time.monotonic())
        if engine.ramped_down:
            return
        time.sleep(engine.period)


if __name__ == '__main__':
    sys.exit(main())
