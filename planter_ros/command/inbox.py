"""What the command process said, as its shell's reader thread takes it (doc/command.md, "The
channel"): log lines passed on, the start messages (`built`, `held`, `ready`: `reports.Ready`),
a failed start's `error`, each control period's feedback, commands, sections and
`reports.Snapshot`, the /diagnostics reports, the answers to requests (`reports.Reply`), the
run's `reports.CommandReport` and its deliberate `reports.CommandExit`.

Every feedback sample is queued until the shell publishes it (`take_feedback`): a shell whose
DDS stalls catches up afterwards, none is lost; a queue full for FEEDBACK_QUEUE samples drops
its oldest, counted and said once per overflow. A typed message that does not read is said in
the log (one line naming the field), never a KeyError in the reader.
"""
from __future__ import annotations

from collections import deque
import logging
import math
import threading
import time
from typing import Any

from .reports import CommandExit, CommandReport, Ready, Reply, ReportError, Snapshot
from .state import Feedback, Log

__all__ = ['FEEDBACK_QUEUE', 'Inbox']

# feedback samples held for the shell: 5 s at a 10 ms SYNC period (a shell that has not
# published for that long is reported by its own diagnostics long before)
FEEDBACK_QUEUE = 500


class Inbox:
    """Everything the command process sent that its shell reads later (see the module doc)."""

    def __init__(self, log: Log) -> None:
        self.log = log
        self.info: dict[str, Any] = {}      # start messages: 'built', 'held', 'ready'
        self.error: tuple[str, str] | None = None   # a failed start: (kind, line)
        self.exit: CommandExit | None = None        # its deliberate exit, once said
        self.last_fb: dict[str, Any] = {}
        self.last_fb_time = -1.0
        self.fb_count = 0
        self._fb_queue: deque[list] = deque()
        self._fb_newest = -math.inf         # the newest stamp queued so far
        self.feedback_dropped = 0           # samples dropped because the queue was full
        self._fb_overflowing = False
        self.last_diag: list = []
        self.last_snapshot = Snapshot()
        self._snapshot_error = ''           # the last unreadable snapshot's (said once)
        self.final: CommandReport | None = None
        self.final_error = ''               # why the `final` message was unreadable
        self._replies: dict[int, Reply] = {}
        self._replied = threading.Condition(threading.Lock())

    def restart(self) -> None:
        """A new command process: nothing of its start said yet."""
        self.info = {}
        self.exit = None

    @property
    def ready(self) -> Ready | None:
        """What the command process said once its drives ran (None before)."""
        ready = self.info.get('ready')
        return ready if isinstance(ready, Ready) else None

    def handle(self, kind: str, payload: Any) -> None:
        """One message from the command process."""
        if kind == 'log':
            level, text = payload
            self.log(int(level), text)
        elif kind == 'fb':
            self.last_fb = payload
            self.last_fb_time = time.monotonic()
            self.fb_count += 1
            self._queue_feedback(payload.get('feedback', []))
            self._take_snapshot(payload.get('snapshot'))
        elif kind == 'diag':
            self.last_diag = payload
        elif kind == 'reply':
            ident, data = payload
            try:
                reply = Reply.from_data(data)
            except ReportError as exc:
                reply = Reply(False, f'the command process answered wrongly: {exc}')
            with self._replied:
                self._replies[ident] = reply
                self._replied.notify_all()
        elif kind == 'final':
            try:
                self.final = CommandReport.from_data(payload)
            except ReportError as exc:
                self.final_error = str(exc)
                self.log(logging.ERROR, f'command process: its report is unreadable: {exc}')
        elif kind == 'error':
            self.error = (payload[0], payload[1])
        elif kind == 'exit':
            try:
                self.exit = CommandExit.from_data(payload)
            except ReportError as exc:
                self.log(logging.ERROR, f'command process: {exc}')
                self.exit = CommandExit('stop')
        elif kind in ('ready', 'held'):
            try:
                self.info[kind] = Ready.from_data(payload)
            except ReportError as exc:
                self.log(logging.ERROR, f'command process: {exc}')
                self.info[kind] = Ready(0, 0, (f'unreadable {kind} message',))
        else:
            self.info[kind] = payload

    def reply(self, ident: int, deadline: float) -> Reply | None:
        """The answer to request `ident`, waiting until `deadline` (monotonic s; None: none
        came by then)."""
        with self._replied:
            while ident not in self._replies:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._replied.wait(remaining)
            return self._replies.pop(ident)

    def _take_snapshot(self, data: Any) -> None:
        if data is None:
            return
        try:
            self.last_snapshot = Snapshot.from_data(data)
        except ReportError as exc:
            if str(exc) != self._snapshot_error:
                self.log(logging.ERROR, f'command process: {exc}')
            self._snapshot_error = str(exc)

    def _queue_feedback(self, items: list) -> None:
        """Queue one message's feedback when it holds a sample not queued before (the
        command process repeats the last one when no new TPDO came)."""
        if not items:
            return
        newest = max(item[3] for item in items)
        if newest <= self._fb_newest:
            return
        self._fb_newest = newest
        if len(self._fb_queue) >= FEEDBACK_QUEUE:
            self._fb_queue.popleft()
            self.feedback_dropped += 1
            if not self._fb_overflowing:
                self._fb_overflowing = True
                self.log(logging.ERROR, f'joint feedback lost: the shell published none for '
                                        f'{FEEDBACK_QUEUE} samples; the oldest are dropped '
                                        '(counted in diagnostics)')
        else:
            self._fb_overflowing = False
        self._fb_queue.append(items)

    def feedback(self) -> list[Feedback]:
        """The last message's feedback."""
        return [Feedback(*item) for item in self.last_fb.get('feedback', [])]

    def take_feedback(self) -> list[list[Feedback]]:
        """Every feedback sample received since the last call, oldest first (one list of
        rows each)."""
        out: list[list[Feedback]] = []
        while True:
            try:
                items = self._fb_queue.popleft()
            except IndexError:
                return out
            out.append([Feedback(*item) for item in items])

    def commands(self) -> list[tuple[str, float]]:
        return [(str(joint), float(command))
                for joint, command in self.last_fb.get('commands', [])]
