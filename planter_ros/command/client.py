"""The shell's handle of its command process: start it, feed it, read what it says, and
supervise it (doc/command.md).

`CommandClient` has the surface of `CommandEngine` that sync_node uses (sample, set_design,
section, reset_fault, configure, feedback, commands, sections, reports, snapshot,
final_report, enable, shutdown), so the node is the same shell whether the engine runs in its
own process (this) or in the node's (a test handing it a bus).

Supervision: a reader thread takes every message; end-of-file means the process died. Unless
the shell is stopping, that is logged and reported as an ERROR status ('command process'), and
the process is started again (at most `command_restarts` times), given the design and the
section states again; the drives' own watchdogs (RPDO deadline, heartbeat consumer) stop the
motors meanwhile. The child dies with this process (PR_SET_PDEATHSIG and end-of-file): it is
spawned from the thread that lives as long as the shell (the kernel signals a child when the
thread that forked it ends).
"""
from __future__ import annotations

from collections.abc import Sequence
import itertools
import logging
import os
import subprocess
import sys
import threading
import time
from typing import Any

from planter_ros import diagnostics
from planter_ros.config import ConfigError
from planter_ros.design import Design
from planter_ros.drive.bus_load import BusLoad
from planter_ros.drive.errors import DriveError

from .channel import Channel, ChannelClosed
from .engine import Feedback, Log, checked_bus_load
from planter_ros.control.cam_law import plan_for_design, profile_to_data, warm_up

from .settings import CommandSettings, law_to_data
from planter_ros.drive.socket_bus import INTERFACE, socket_pair

__all__ = ['COMMAND_PROCESS', 'CommandProcessError', 'CommandClient']

COMMAND_PROCESS = 'command process'      # its status name in /diagnostics
REPLY_TIMEOUT = 2.0                      # s a section or reset request waits for its answer


class CommandProcessError(DriveError):
    """The command process did not start or is gone (one line)."""


class CommandClient:
    """The command process of a sync node (see the module doc)."""

    def __init__(self, settings: CommandSettings, log: Log,
                 extra_fds: Sequence[int] = ()) -> None:
        self.settings = settings
        self.log = log
        cfg = settings.drive
        self.bus_load: BusLoad = checked_bus_load(cfg, settings.loop,
                                                  [row for row in settings.rows if row.enabled])
        self.extra_fds = tuple(extra_fds)
        if cfg.can_interface == INTERFACE:
            self.extra_fds += (int(cfg.can_channel),)
        self.process: subprocess.Popen | None = None
        self.channel: Channel | None = None
        self._lock = threading.Lock()
        self._ids = itertools.count(1)
        self._replies: dict[int, list] = {}
        self._replied = threading.Condition(self._lock)
        self.info: dict[str, Any] = {}
        self.last_fb: dict[str, Any] = {}
        self.last_fb_time = -1.0
        self.fb_count = 0
        self.last_diag: list = []
        self.final: dict | None = None
        self.error: tuple[str, str] | None = None
        self.deaths: list[str] = []          # why each command process ended unasked
        self.restarts = 0
        self.stopping = False
        self.dead = False                   # gone and not restarted
        self._design: str | None = None
        # the last design as sent ([kind, payload]); with a cam, once planned
        self._design_message: tuple[str, Any] | None = None
        self._cam = settings.law[0].speed_profile == 'cam'
        self._profile = None                # the cam profile sent last
        if self._cam:           # the first plan imports and sets up the LP solver (~0.4 s)
            threading.Thread(target=warm_up, daemon=True, name='cam-warm-up').start()
        self._sections: dict[str, bool] = {row.name: True for row in settings.rows
                                           if row.enabled}
        self._reader: threading.Thread | None = None

    # ---------------------------------------------------------------- start / stop
    def _spawn(self) -> None:
        ours, theirs = socket_pair()
        fds = (theirs.fileno(),) + self.extra_fds
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'planter_ros.command', '--fd', str(theirs.fileno()),
             '--parent', str(os.getpid())], pass_fds=fds, stdin=subprocess.DEVNULL)
        theirs.close()
        self.channel = Channel(ours)
        self.info = {}
        self.channel.send('settings', self.settings.data())

    def enable(self, timeout: float = 60.0) -> None:
        """Start the command process and wait until its drives are enabled (BLOCKING, start-up
        only). Raises DriveError (or ConfigError) with the process's own line."""
        self._spawn()
        deadline = time.monotonic() + timeout
        while 'ready' not in self.info:
            if self.error is not None:
                kind, text = self.error
                self._reap()
                raise (ConfigError if kind == 'config' else DriveError)(text)
            if time.monotonic() > deadline:
                self._reap()
                raise CommandProcessError(f'the command process was not ready within '
                                          f'{timeout:g} s')
            try:
                for kind, payload in self.channel.receive(0.1):
                    self._handle(kind, payload)
            except ChannelClosed:
                code = self._reap()
                if self.error is not None:
                    continue
                raise CommandProcessError(f'the command process ended (exit code {code}) '
                                          'before its drives were enabled') from None
        self._reader = threading.Thread(target=self._read, daemon=True,
                                        name='command-process-reader')
        self._reader.start()

    def _reap(self, timeout: float = 5.0) -> int | None:
        process = self.process
        if process is None:
            return None
        try:
            return process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            return process.wait()

    def shutdown(self, timeout: float = 30.0) -> None:
        """Ask the command process to shut its drives down and wait for its report
        (BLOCKING, idempotent)."""
        self.stopping = True
        channel = self.channel
        if channel is None or self.process is None:
            return
        try:
            channel.send('stop')
        except ChannelClosed:
            pass
        deadline = time.monotonic() + timeout
        while self.process.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        if self._reader is not None:
            self._reader.join(max(deadline - time.monotonic(), 0.1))
        self._reap(max(deadline - time.monotonic(), 0.1))
        channel.close()

    # ---------------------------------------------------------------- the reader
    def _read(self) -> None:
        while True:
            channel = self.channel
            try:
                for kind, payload in channel.receive(0.5):
                    self._handle(kind, payload)
            except ChannelClosed:
                if self.stopping:
                    return
                if not self._died():
                    return

    def _died(self) -> bool:
        """The command process ended unasked: report; restart it if allowed (True)."""
        code = self._reap()
        why = f'command process died (exit code {code})'
        self.deaths.append(why)
        limit = self.settings.loop.command_restarts
        if self.restarts >= limit:
            self.dead = True
            self.log(logging.ERROR, f'{why}; not restarted ({limit} restart(s) used): the '
                                    "drives' watchdogs have stopped the motors")
            return False
        self.info = {}
        self.restarts += 1
        self.log(logging.ERROR, f'{why}: restarting it ({self.restarts} of {limit}); the '
                                "drives' watchdogs stop the motors meanwhile")
        try:
            self._spawn()
            if self._design is not None:
                if self._design_message is not None:
                    self.channel.send(*self._design_message)
                elif not self._cam:
                    self.channel.send('design', self._design)
            for name, on in self._sections.items():
                if not on:
                    self.channel.send('section', [0, name, False])
        except (OSError, ChannelClosed) as exc:
            self.dead = True
            self.log(logging.ERROR, f'command process restart failed: {exc}')
            return False
        return True

    def _handle(self, kind: str, payload: Any) -> None:
        if kind == 'log':
            level, text = payload
            self.log(int(level), text)
        elif kind == 'fb':
            self.last_fb = payload
            self.last_fb_time = time.monotonic()
            self.fb_count += 1
        elif kind == 'diag':
            self.last_diag = payload
        elif kind == 'reply':
            ident, ok, message, changed = payload
            with self._replied:
                self._replies[ident] = [ok, message, changed]
                self._replied.notify_all()
        elif kind == 'final':
            self.final = payload
        elif kind == 'error':
            self.error = (payload[0], payload[1])
        else:
            self.info[kind] = payload
            if kind == 'ready' and payload.get('realtime'):
                pass                                      # said in its own log line

    # ---------------------------------------------------------------- inputs
    def _send(self, kind: str, payload: Any = None, latest: bool = False) -> bool:
        channel = self.channel
        if channel is None:
            return False
        try:
            return channel.send(kind, payload, latest=latest)
        except ChannelClosed:
            return False                  # the reader sees it and reports / restarts

    def sample(self, v: float, yaw_rate: float, now: float) -> None:
        self._send('speed', [v, yaw_rate, now], latest=True)

    def step(self, now: float) -> None:
        """The command process runs its own loop: nothing to do here."""
        if self.channel is not None:
            try:
                self.channel.flush()
            except ChannelClosed:
                pass

    def set_design(self, design: Design, text: str, now: float) -> bool:
        if text == self._design:
            return False
        self._design = text
        if self._cam:
            # planned here, in the shell, not in the command process (a plan holds the
            # interpreter for up to tens of ms: the SYNC loop must not wait for it)
            self._design_message = None
            threading.Thread(target=self._plan_cam, args=(design, text, now), daemon=True,
                             name='cam-plan').start()
            return True
        self._design_message = ('design', text)
        self._send('design', text)
        return True

    def _plan_cam(self, design: Design, text: str, arrived: float) -> None:
        """Plan the cam and the change from the one sent last (planter_ros.control.cam_law);
        one over the drive's limits is refused here, before it reaches the command process."""
        from planter_ros.cam import CamError
        previous = self._profile
        try:
            profile, why = plan_for_design(design, self.settings.law[0].cam_rule, previous)
            data = None if profile is None else profile_to_data(profile, previous)
        except CamError as exc:
            self.log(logging.ERROR, f'design refused, the rows keep theirs: {exc}')
            return
        if text != self._design:            # a newer design came meanwhile
            return
        self._profile = profile
        message = ('design_cam', [text, data, why, arrived])
        self._design_message = message
        self._send(*message)

    def configure(self, law_values: Sequence[Any]) -> None:
        self._send('configure', law_to_data(tuple(law_values)))

    def _request(self, kind: str, *args: Any) -> list:
        ident = next(self._ids)
        if not self._send(kind, [ident, *args]):
            return [False, 'the command process is not running', False]
        deadline = time.monotonic() + REPLY_TIMEOUT
        with self._replied:
            while ident not in self._replies:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return [False, f'the command process did not answer within '
                                   f'{REPLY_TIMEOUT:g} s', False]
                self._replied.wait(remaining)
            return self._replies.pop(ident)

    def section(self, name: str, on: bool, now: float) -> tuple[bool, str, bool]:
        ok, message, changed = self._request('section', name, bool(on))
        if ok:
            self._sections[name] = bool(on)
        return bool(ok), str(message), bool(changed)

    def reset_fault(self, name: str) -> tuple[bool, str]:
        ok, message, _ = self._request('reset', name)
        return bool(ok), str(message)

    # ---------------------------------------------------------------- outputs
    @property
    def running(self) -> int:
        """Rows whose drives run (as the command process said when ready)."""
        return int(self.info.get('ready', {}).get('running', 0))

    def mode_text(self) -> str:
        """The CiA 402 mode the command process's drives run, in words."""
        return str(self.info.get('ready', {}).get('mode', ''))

    def feedback(self) -> list[Feedback]:
        return [Feedback(*item) for item in self.last_fb.get('feedback', [])]

    def commands(self) -> list[tuple[str, float]]:
        return [tuple(item) for item in self.last_fb.get('commands', [])]

    def sections(self) -> dict[str, bool]:
        return dict(self.last_fb.get('sections', self._sections))

    def snapshot(self) -> dict:
        return self.last_fb.get('snapshot', {'rows': [], 'spacing': None})

    def final_report(self) -> dict:
        return self.final or {}

    def process_report(self, now: float) -> diagnostics.Report:
        """The command process's own status: alive, its pid, real time granted or not."""
        values = [('restarts', self.restarts), ('deaths', len(self.deaths))]
        ready = self.info.get('ready', {})
        if ready:
            values += [('pid', ready.get('pid')),
                       ('SCHED_FIFO priority asked', ready.get('priority'))]
        refused = ready.get('realtime') or []
        if refused:
            values.append(('real time refused', '; '.join(refused)))
        age = now - self.last_fb_time if self.last_fb_time >= 0 else None
        if age is not None:
            values.append(('last feedback age', f'{age:.3f} s'))
        if self.dead:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.ERROR,
                                      f'{self.deaths[-1]}; not restarted', tuple(values))
        if self.process is not None and self.process.poll() is not None and not self.stopping:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.ERROR,
                                      'command process died: restarting', tuple(values))
        if self.deaths:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.WARN,
                                      f'restarted after: {self.deaths[-1]}', tuple(values))
        if age is None or age > 1.0:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.STALE,
                                      'no feedback from the command process', tuple(values))
        if refused:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.WARN,
                                      'running without real-time guarantees', tuple(values))
        return diagnostics.Report(COMMAND_PROCESS, diagnostics.OK, 'running (SCHED_FIFO, '
                                  'memory locked)', tuple(values))

    def reports(self, now: float,
                shared: Sequence[diagnostics.Report] = ()) -> list[tuple[diagnostics.Report, str]]:
        """The command process's last reports, then the shell's (`shared` and its own)."""
        out = [(diagnostics.Report(task, level, message, tuple(tuple(v) for v in values)), hw)
               for (task, level, message, values), hw in self.last_diag]
        bus_id = f'{self.settings.drive.can_interface}:{self.settings.drive.can_channel}'
        return out + [(report, bus_id) for report in shared] + [
            (self.process_report(now), bus_id)]
