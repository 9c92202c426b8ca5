"""The command process: `python -m planter_ros.command --fd N --parent PID`.

No DDS participant and no rclpy in this process (a test checks `sys.modules`): a node joining
the ROS graph stalls a publishing process for up to a second (doc/command.md), and nothing here
publishes. It owns the CAN bus, the CiA 402 masters, the heartbeats and the row loop
(`CommandEngine`) and is fed by its shell (sync_node) over the channel on fd N
(`command.channel`):

shell -> here: `settings` (first), `speed` [v, ω_z, t] (latest value), `design` text,
`section` / `reset` requests [id, row, ...] (answered by `reply` [id, `reports.Reply`]),
`configure` (the law's settings), `enable` [id] (an operator's, to a held process), `stop`.
here -> shell: `built`, `held` (start: waiting for an operator: `reports.Ready`), `ready`
(`reports.Ready`), `error` (start), `log` [level, line], `fb` (every control period: joint
feedback, commands, sections, a `reports.Snapshot`), `diag` (reports, every diagnostics
period), `final` (the run's figures: `reports.CommandReport`), `exit` (why it ends on purpose:
`reports.CommandExit`, last). The typed ones travel as their `to_data()`.

Held (the settings say `hold`: a restart after a crash, doc/command.md): it builds the engine and
checks the bus but does not enable a drive; the rows stay at zero until an `enable` request (an
operator's service call on the sync node) or it is stopped.

It asks for SCHED_FIFO (`realtime_priority`) and locked memory, and says in one log line (and
in the `ready` message, which the shell puts in /diagnostics) what it did not get, then runs
on. A stop is a stop however it comes: its shell's `stop`, SIGTERM or SIGINT (a service
manager or a terminal's Ctrl-C stopping the whole process group, or someone stopping this process
alone), or its shell gone (the channel reads end-of-file; the kernel sends SIGTERM when the parent
dies: PR_SET_PDEATHSIG): every row ramps to 0 at its acceleration limit, the drives are disabled
(0x60FF = 0, 0x06, pre-operational), `final` and `exit` (the reason) are sent while the shell is
there to read them, and it exits 0. A second signal changes nothing (the stop is under way). It
never runs on without its shell, and never enables a drive once a stop has come.
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

from planter_ros.host import realtime, stop_signals
from planter_ros.config import ConfigError
from planter_ros.control.cam_law import profile_from_data
from planter_ros.design import from_json
from planter_ros.drive.errors import DriveError

from .channel import Channel, ChannelClosed
from .engine import CommandEngine
from .reports import CommandExit, Ready, Reply
from .settings import CommandSettings, law_from_data
from planter_ros.drive.socket_bus import INTERFACE, SocketPairBus

__all__ = ['ORPHAN_RAMP_LIMIT', 'main', 'run']

ORPHAN_RAMP_LIMIT = 5.0       # s an orphaned process ramps at most before disabling anyway
DRAIN_TIMEOUT = 5.0           # s its last messages may wait for room in the shell's buffer
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
    """SIGTERM or SIGINT: a stop (the parent died: PR_SET_PDEATHSIG; a service manager or a
    terminal stops the group; someone stops this process). `received`: its name, '' before."""

    def __init__(self) -> None:
        self.received = ''
        signal.signal(signal.SIGTERM, self._on_signal)
        signal.signal(signal.SIGINT, self._on_signal)
        stop_signals.unblock()          # its shell started it with both held back

    def _on_signal(self, signum: int, _frame: Any) -> None:
        if not self.received:
            self.received = signal.Signals(signum).name


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
        channel.finish(DRAIN_TIMEOUT)         # `final` and `exit` reach the shell


def _settings(channel: Channel, terminated: _Terminated,
              early: list) -> CommandSettings | None:
    """The settings (None: stopped first); what the shell sent right after them (the design
    and sections a restart sends again) is put in `early`, to be applied once built."""
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and not terminated.received:
        messages = channel.receive(0.1)
        for i, (kind, payload) in enumerate(messages):
            if kind == 'settings':
                early += [m for m in messages[i + 1:] if m[0] != 'speed']
                return CommandSettings.from_data(payload)
            if kind == 'stop':
                return None
    return None


def _exit(channel: Channel, reason: str, enabled: bool) -> None:
    """The last message: why this process ends on purpose (reports.CommandExit)."""
    try:
        channel.send('exit', CommandExit(reason, enabled).to_data())
    except ChannelClosed:
        pass


def run(channel: Channel, terminated: _Terminated, death: str = '') -> int:
    """Start, loop, stop (see the module doc); the exit code."""
    def log(level: int, text: str) -> None:
        try:
            channel.send('log', [level, text])
        except ChannelClosed:
            pass

    early: list = []
    try:
        settings = _settings(channel, terminated, early)
    except ChannelClosed:
        return 1
    if settings is None:              # stopped (or never told what to run) before a start
        _exit(channel, terminated.received or 'stop', False)
        return 0 if terminated.received else 1
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
        engine = CommandEngine(settings, bus=bus, log=log)
        channel.send('built', {'bus_load': engine.bus_load.load,
                               'bitrate': engine.bus_load.bitrate, 'pid': os.getpid()})
        if any(kind == 'stop' for kind, _ in early):
            early, stopped = [], 'stop'
        elif settings.hold:
            stopped = _held(engine, channel, terminated, refused, settings, early)
        else:
            stopped = terminated.received or _pending_stop(engine, channel)
        if stopped:                         # a stop before any drive was enabled
            engine.shutdown()               # (only the bus is closed)
            _exit(channel, 'stop' if stopped == 'orphaned' else stopped, False)
            return 0
        if not settings.hold:
            engine.enable()
            for kind, payload in early:
                _handle(engine, channel, kind, payload)
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
        _exit(channel, 'start failed', False)
        return 2
    _send_ready(channel, engine, refused, settings)
    gc.freeze()       # start-up's objects out of the collector's reach: short collections
    why = _loop(engine, channel, settings, terminated)
    _ramp_down(engine, why)
    engine.shutdown()
    try:
        channel.send('final', engine.final_report().to_data())
    except ChannelClosed:
        pass
    _exit(channel, why if why != 'orphaned' else 'stop', True)
    return 0


def _send_ready(channel: Channel, engine: CommandEngine, refused: list[str],
                settings: CommandSettings) -> None:
    try:
        channel.send('ready', Ready(os.getpid(), settings.loop.realtime_priority,
                                    tuple(refused), engine.running,
                                    engine.mode_text()).to_data())
    except ChannelClosed:
        pass


def _pending_stop(engine: CommandEngine, channel: Channel) -> str:
    """'stop' if the shell asked for a stop before the drives were enabled ('' if not; what
    else it sent is handled)."""
    try:
        messages = channel.receive(0.0)
    except ChannelClosed:
        return 'orphaned'
    stop = ''
    for kind, payload in messages:
        if kind == 'stop':
            stop = 'stop'
        elif kind not in ('speed', 'enable'):
            _handle(engine, channel, kind, payload)
    return stop


def _held(engine: CommandEngine, channel: Channel, terminated: _Terminated,
          refused: list[str], settings: CommandSettings, deferred: list) -> str:
    """Held: no drive enabled until an `enable` request; '' once enabled (the loop follows),
    else why it stopped first ('stop', a signal's name, 'orphaned')."""
    channel.send('held', Ready(os.getpid(), settings.loop.realtime_priority,
                               tuple(refused)).to_data())
    # `deferred`: the design, sections, settings: applied once the drives run
    while not terminated.received:
        try:
            messages = channel.receive(0.1)
        except ChannelClosed:
            return 'orphaned'
        for kind, payload in messages:
            if kind == 'stop':
                return 'stop'
            if kind == 'enable':
                ident = payload[0]
                try:
                    engine.enable()
                except (DriveError, ConfigError, OSError) as exc:
                    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                    _reply(channel, ident, Reply(False, f'not enabled: {text}'))
                    continue
                for later in deferred:
                    _handle(engine, channel, *later)
                _reply(channel, ident, Reply(True, f'enabled ({engine.mode_text()}): the rows '
                                                   'follow the ground speed', True))
                return ''
            if kind == 'reset':
                _reply(channel, payload[0], Reply(False, 'the rows are held: enable them first'))
            elif kind == 'section':         # answered now, applied once the drives run
                ident, name, on = payload
                deferred.append(('section', [0, name, on]))
                _reply(channel, ident, Reply(True, f'row {name} {"on" if on else "off"} once the '
                                                   'rows are enabled', True))
            elif kind != 'speed':
                deferred.append((kind, payload))
    return terminated.received


def _loop(engine: CommandEngine, channel: Channel, settings: CommandSettings,
          terminated: _Terminated) -> str:
    """Until a stop: 'stop' (the shell's), 'SIGTERM' / 'SIGINT', or 'orphaned'."""
    period = engine.period
    diag_period = settings.loop.diagnostics_period
    next_tick = time.monotonic()
    next_diag = next_tick
    skipped = 0
    sampled = -math.inf         # when a sample last sent every row's frames (profile velocity)
    while True:
        if terminated.received:
            return terminated.received
        try:
            messages = channel.receive(max(next_tick - time.monotonic(), 0.0))
        except ChannelClosed:
            return 'orphaned'
        speed = None
        for kind, payload in messages:
            if kind == 'speed':
                skipped += speed is not None
                speed = payload
            elif kind == 'stop':
                return 'stop'
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
                                    'snapshot': engine.snapshot().to_data(),
                                    'skipped': skipped})
                if now >= next_diag:
                    next_diag = now + diag_period
                    channel.send('diag', [[[r.task, r.level, r.message, list(r.values)], hw]
                                          for r, hw in engine.reports(now)])
            except ChannelClosed:
                return 'orphaned'


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
            _reply(channel, ident, engine.section(name, bool(on), now))
        elif kind == 'reset':
            ident, name = payload
            _reply(channel, ident, engine.reset_fault(name))
        elif kind == 'configure':
            engine.configure(law_from_data(payload))
        elif kind == 'enable':              # enabled already: nothing to do
            _reply(channel, payload[0], Reply(False, 'the rows are enabled already'))
    except (ValueError, KeyError, TypeError, StopIteration) as exc:  # ConfigError: ValueError
        engine.log(logging.ERROR, f'{kind} ignored: {exc}')


def _reply(channel: Channel, ident: int, reply: Reply) -> None:
    """The answer to request `ident` (`reply` [id, Reply data])."""
    channel.send('reply', [ident, reply.to_data()])


def _ramp_down(engine: CommandEngine, why: str) -> None:
    """Every row to 0 at its acceleration limit (frames, SYNC and heartbeat go on) before the
    drives are disabled: asked to stop, stopped by a signal, or orphaned."""
    if why == 'orphaned':
        engine.log(logging.ERROR, 'command process orphaned (its shell died): ramping every '
                                  'row to 0, then disabling the drives')
    elif why != 'stop':
        engine.log(logging.WARNING, f'command process stopped by {why}: ramping every row to '
                                    '0, then disabling the drives')
    start = time.monotonic()
    engine.stop_ramp(start)
    while time.monotonic() - start < ORPHAN_RAMP_LIMIT:
        engine.step(time.monotonic())
        if engine.ramped_down:
            return
        time.sleep(engine.period)


if __name__ == '__main__':
    sys.exit(main())
