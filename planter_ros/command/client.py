"""The shell's handle of its command process: start it, feed it, read what it says, and
supervise it (doc/command.md).

`CommandClient` has the surface of `CommandEngine` that sync_node uses (sample, set_design,
section, reset_fault, configure, feedback, commands, sections, reports, snapshot,
final_report, enable, shutdown), so the node is the same shell whether the engine runs in its
own process (this) or in the node's (a test handing it a bus).

Supervision: a reader thread takes every message; end-of-file without the process's `exit`
message means it died. Unless a stop has been asked for (the shell's `shutdown()` or
`request_stop()`, or `stop_asked()` true: the shell's stop signal), that is logged and reported
as an ERROR status ('command process'), and the process is started again (at most
`command_restarts` times), given the design and the section states again, **held**: it enables
no drive until an operator asks (`operator_enable()`, the sync node's `enable_rows` service),
unless `enable_after_restart` (a fenced machine); the drives' own watchdogs (RPDO deadline,
heartbeat consumer) have stopped the motors meanwhile. A deliberate exit (its `exit` message: a
stop signal reached it, its drives ramped to zero and disabled) is never taken for a crash:
nothing restarts it, and `on_exit(reason)` tells the shell, which stops too. Once a stop has
been asked for, nothing here starts a process or enables a drive. The child dies with this
process (PR_SET_PDEATHSIG and end-of-file): it is spawned from the thread that lives as long as
the shell (the kernel signals a child when the thread that forked it ends).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
import itertools
import logging
import os
import subprocess
import sys
import threading
import time
from typing import Any

from planter_ros import diagnostics
from planter_ros.host import stop_signals
from planter_ros.config import ConfigError
from planter_ros.design import Design
from planter_ros.drive.bus_load import BusLoad
from planter_ros.drive.errors import DriveError

from .channel import Channel, ChannelClosed
from .inbox import Inbox
from .lifecycle import checked_bus_load
from .orders import Orders
from .reports import CommandExit, CommandReport, Ready, Reply, Snapshot

from .settings import CommandSettings, law_to_data
from .state import Feedback, Log
from planter_ros.drive.socket_bus import INTERFACE, socket_pair

__all__ = ['COMMAND_PROCESS', 'CommandProcessError', 'CommandClient', 'ENABLE_TIMEOUT']

COMMAND_PROCESS = 'command process'      # its status name in /diagnostics
REPLY_TIMEOUT = 2.0                      # s a section or reset request waits for its answer
ENABLE_TIMEOUT = 30.0                    # s an operator's enable waits for the drives


class CommandProcessError(DriveError):
    """The command process did not start or is gone (one line)."""


class CommandClient:
    """The command process of a sync node (see the module doc)."""

    def __init__(self, settings: CommandSettings, log: Log,
                 extra_fds: Sequence[int] = (),
                 stop_asked: Callable[[], bool] = lambda: False,
                 on_exit: Callable[[str], None] = lambda reason: None,
                 enable_service: str = 'enable_rows') -> None:
        self.settings = settings
        self.log = log
        self.stop_asked = stop_asked          # the shell's own stop (its signal handler)
        self.on_exit = on_exit                # the process ended on purpose (a signal to it)
        self.enable_service = enable_service  # named in the held status
        cfg = settings.drive
        self.bus_load: BusLoad = checked_bus_load(cfg, settings.loop,
                                                  [row for row in settings.rows if row.enabled])
        self.extra_fds = tuple(extra_fds)
        if cfg.can_interface == INTERFACE:
            self.extra_fds += (int(cfg.can_channel),)
        self.process: subprocess.Popen | None = None
        self.channel: Channel | None = None
        self._ids = itertools.count(1)
        self.inbox = Inbox(log)             # what the command process said
        self.deaths: list[str] = []          # why each command process ended unasked
        self.restarts = 0
        self.stopping = False
        self.stop_requested = False         # no restart, no enable from now on
        self.held_reason = ''               # why the rows wait for an operator ('' = they don't)
        self._life = threading.RLock()      # a restart and a stop, one at a time
        self.dead = False                   # gone and not restarted
        self.orders = Orders(settings.law[0], [row.name for row in settings.rows if row.enabled],
                             log, self._send)
        self._reader: threading.Thread | None = None

    # ---------------------------------------------------------------- start / stop
    def _stop_asked(self) -> bool:
        return self.stop_requested or self.stopping or bool(self.stop_asked())

    def request_stop(self) -> None:
        """A stop has been asked for (the shell's signal): from now on nothing restarts the
        command process or enables a drive; `shutdown()` does the stop itself."""
        with self._life:
            self.stop_requested = True

    def _spawn(self, hold: bool = False) -> None:
        ours, theirs = socket_pair()
        fds = (theirs.fileno(),) + self.extra_fds
        with stop_signals.held_for_child():     # its handlers first, then a stop signal
            self.process = subprocess.Popen(
                [sys.executable, '-m', 'planter_ros.command', '--fd', str(theirs.fileno()),
                 '--parent', str(os.getpid())], pass_fds=fds, stdin=subprocess.DEVNULL)
        theirs.close()
        self.channel = Channel(ours)
        self.inbox.restart()
        self.channel.send('settings', self.settings.held(hold).data())

    def enable(self, timeout: float = 60.0, hold_reason: str = '') -> None:
        """Start the command process and wait until its drives are enabled (BLOCKING, start-up
        only); with `hold_reason` (why the rows wait for an operator), until it is built and
        held instead. Raises DriveError (or ConfigError) with the process's own line."""
        with self._life:
            if self._stop_asked():
                raise CommandProcessError('stopped before the command process started')
            self.held_reason = hold_reason
            self._spawn(hold=bool(hold_reason))
        deadline = time.monotonic() + timeout
        stop_sent = False
        while 'ready' not in self.info and 'held' not in self.info:
            if not stop_sent and self._stop_asked():
                stop_sent = self._send('stop')   # it enables nothing it has not yet enabled
            if self.inbox.error is not None:
                kind, text = self.inbox.error
                self._reap()
                raise (ConfigError if kind == 'config' else DriveError)(text)
            if time.monotonic() > deadline:
                self._reap()
                raise CommandProcessError(f'the command process was not ready within '
                                          f'{timeout:g} s')
            try:
                for kind, payload in self._live_channel().receive(0.1):
                    self._handle(kind, payload)
            except ChannelClosed:
                code = self._reap()
                if self.inbox.error is not None:
                    continue
                if self.exit is not None:
                    raise CommandProcessError(f'the command process stopped ({self.exit.reason}) '
                                              'before its drives were enabled') from None
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
        with self._life:                  # not while a restart is being made
            self.stopping = self.stop_requested = True
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
            try:
                for kind, payload in self._live_channel().receive(0.5):
                    self._handle(kind, payload)
            except ChannelClosed:
                if self.stopping:
                    return
                if self.exit is not None:
                    self._stopped_itself(self.exit)
                    return
                if not self._died():
                    return

    def _live_channel(self) -> Channel:
        """The channel to the command process (ChannelClosed when there is none)."""
        channel = self.channel
        if channel is None:
            raise ChannelClosed('no command process')
        return channel

    def _stopped_itself(self, exit_: CommandExit) -> None:
        """The command process ended on purpose (a stop signal reached it): its rows ramped to
        zero and its drives are disabled. Never restarted; the shell is told."""
        self._reap()
        with self._life:
            self.stop_requested = True
            self.dead = True
        reason = exit_.reason
        self.log(logging.WARNING, f'command process stopped by {reason}: rows ramped to 0, '
                                  'drives disabled; not restarted (a stop is a stop)')
        self.on_exit(reason)

    def _died(self) -> bool:
        """The command process ended unasked: report; restart it, held, if allowed (True)."""
        code = self._reap()
        why = f'command process died (exit code {code})'
        with self._life:
            if self._stop_asked():
                self.dead = True
                self.log(logging.WARNING, f'{why} while stopping: not restarted')
                return False
            self.deaths.append(why)
            limit = self.settings.loop.command_restarts
            if self.restarts >= limit:
                self.dead = True
                self.log(logging.ERROR, f'{why}; not restarted ({limit} restart(s) used): the '
                                        "drives' watchdogs have stopped the motors")
                return False
            self.inbox.restart()
            self.restarts += 1
            automatic = self.settings.loop.enable_after_restart
            self.held_reason = '' if automatic else f'restarted after: {why}'
            self.log(logging.ERROR, f'{why}: restarting it ({self.restarts} of {limit}); the '
                                    "drives' watchdogs stop the motors meanwhile; " + (
                                        'the rows run again once it is ready '
                                        '(enable_after_restart)' if automatic else
                                        'the rows stay at zero until an operator enables them '
                                        f'(service {self.enable_service})'))
            return self._respawn(hold=not automatic)

    def _respawn(self, hold: bool) -> bool:
        try:
            self._spawn(hold=hold)
            self.orders.tell_again(self._live_channel())
        except (OSError, ChannelClosed) as exc:
            self.dead = True
            self.log(logging.ERROR, f'command process restart failed: {exc}')
            return False
        return True

    def _handle(self, kind: str, payload: Any) -> None:
        self.inbox.handle(kind, payload)
        if kind == 'ready':
            self.held_reason = ''

    # ---------------------------------------------------------------- what it said
    @property
    def info(self) -> dict[str, Any]:
        """Its start messages so far ('built', 'held', 'ready')."""
        return self.inbox.info

    @property
    def exit(self) -> CommandExit | None:
        """Its deliberate exit, once said."""
        return self.inbox.exit

    @property
    def final_error(self) -> str:
        """Why its `final` message was unreadable ('' = it was not)."""
        return self.inbox.final_error

    @property
    def fb_count(self) -> int:
        """Feedback messages received so far."""
        return self.inbox.fb_count

    @property
    def feedback_dropped(self) -> int:
        """Feedback samples dropped because the shell did not publish them in time."""
        return self.inbox.feedback_dropped

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
        """A design for the command process (with a cam: planned here first, orders)."""
        return self.orders.set_design(design, text, now)

    def configure(self, law_values: Sequence[Any]) -> None:
        self._send('configure', law_to_data(tuple(law_values)))

    def _request(self, kind: str, *args: Any) -> Reply:
        ident = next(self._ids)
        if not self._send(kind, [ident, *args]):
            return Reply(False, 'the command process is not running')
        reply = self.inbox.reply(ident, time.monotonic() + REPLY_TIMEOUT)
        if reply is None:
            return Reply(False, f'the command process did not answer within '
                                f'{REPLY_TIMEOUT:g} s')
        return reply

    def operator_enable(self, timeout: float = ENABLE_TIMEOUT) -> Reply:
        """An operator enables the held rows (BLOCKING up to `timeout`)."""
        with self._life:
            if self._stop_asked():
                return Reply(False, 'stopping: nothing is enabled any more')
            if self.dead:
                return Reply(False, 'the command process is not running')
            if 'ready' in self.info:
                return Reply(False, 'the rows are enabled already')
            if 'held' not in self.info:
                return Reply(False, 'the command process is starting: try again in a moment')
            ident = next(self._ids)
            if not self._send('enable', [ident]):
                return Reply(False, 'the command process is not running')
        reply = self.inbox.reply(ident, time.monotonic() + timeout)
        if reply is None:
            return Reply(False, f'the drives were not enabled within {timeout:g} s')
        if reply.ok:
            self.log(logging.WARNING, f'rows enabled by an operator: {reply.message}')
        return reply

    @property
    def held(self) -> bool:
        """The rows wait at zero for an operator (`operator_enable`)."""
        return bool(self.held_reason) and 'ready' not in self.info and not self.dead

    def section(self, name: str, on: bool, now: float) -> Reply:
        reply = self._request('section', name, bool(on))
        if reply.ok:
            self.orders.sections[name] = bool(on)
        return reply

    def reset_fault(self, name: str) -> Reply:
        return self._request('reset', name)

    # ---------------------------------------------------------------- outputs
    @property
    def ready(self) -> Ready | None:
        """What the command process said once its drives ran (None before)."""
        return self.inbox.ready

    @property
    def running(self) -> int:
        """Rows whose drives run (as the command process said when ready)."""
        return self.ready.running if self.ready is not None else 0

    def mode_text(self) -> str:
        """The CiA 402 mode the command process's drives run, in words."""
        return self.ready.mode if self.ready is not None else ''

    def feedback(self) -> list[Feedback]:
        return self.inbox.feedback()

    def take_feedback(self) -> list[list[Feedback]]:
        """Every feedback sample received since the last call, oldest first (one list of
        rows each): what the shell publishes, one joint_states message per sample."""
        return self.inbox.take_feedback()

    def commands(self) -> list[tuple[str, float]]:
        return self.inbox.commands()

    def sections(self) -> dict[str, bool]:
        return dict(self.inbox.last_fb.get('sections', self.orders.sections))

    def snapshot(self) -> Snapshot:
        return self.inbox.last_snapshot

    def final_report(self) -> CommandReport | None:
        """The run's figures (None before the command process sent them, or unreadable:
        `final_error`)."""
        return self.inbox.final

    def process_report(self, now: float) -> diagnostics.Report:
        """The command process's own status: alive, its pid, real time granted or not."""
        values: list[tuple[str, Any]] = [('restarts', self.restarts),
                                         ('deaths', len(self.deaths))]
        ready = self.ready
        if ready is not None:
            values += [('pid', ready.pid), ('SCHED_FIFO priority asked', ready.priority)]
        refused = ready.realtime if ready is not None else ()
        if refused:
            values.append(('real time refused', '; '.join(refused)))
        last = self.inbox.last_fb_time
        age = now - last if last >= 0 else None
        if age is not None:
            values.append(('last feedback age', f'{age:.3f} s'))
        values.append(('feedback samples dropped', self.feedback_dropped))
        if self.exit is not None and self.dead:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.ERROR,
                                      f'stopped by {self.exit.reason}: rows at 0, drives '
                                      'disabled; not restarted', tuple(values))
        if self.dead:
            why = self.deaths[-1] if self.deaths else 'command process ended while stopping'
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.ERROR,
                                      f'{why}; not restarted', tuple(values))
        if self.held:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.WARN,
                                      f'rows held at zero ({self.held_reason}): an operator '
                                      f'enables them (service {self.enable_service})',
                                      tuple(values))
        if self.process is not None and self.process.poll() is not None and not self.stopping:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.ERROR,
                                      'command process died: restarting', tuple(values))
        if self.deaths:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.WARN,
                                      f'restarted after: {self.deaths[-1]}', tuple(values))
        if age is None or age > 1.0:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.STALE,
                                      'no feedback from the command process', tuple(values))
        if self.feedback_dropped:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.WARN,
                                      f'{self.feedback_dropped} feedback sample(s) dropped: '
                                      'the shell did not publish them in time', tuple(values))
        if refused:
            return diagnostics.Report(COMMAND_PROCESS, diagnostics.WARN,
                                      'running without real-time guarantees', tuple(values))
        return diagnostics.Report(COMMAND_PROCESS, diagnostics.OK, 'running (SCHED_FIFO, '
                                  'memory locked)', tuple(values))

    def reports(self, now: float,
                shared: Sequence[diagnostics.Report] = ()) -> list[tuple[diagnostics.Report, str]]:
        """The command process's last reports, then the shell's (`shared` and its own)."""
        out = [(diagnostics.Report(task, level, message, tuple(tuple(v) for v in values)), hw)
               for (task, level, message, values), hw in self.inbox.last_diag]
        bus_id = f'{self.settings.drive.can_interface}:{self.settings.drive.can_channel}'
        return out + [(report, bus_id) for report in shared] + [
            (self.process_report(now), bus_id)]
