"""A progress line on stderr for long runs: items done / total, rate, × real time, ETA.

On a terminal the line is redrawn in place (about 5 times a second); otherwise (a log file, a
pipe, a test) a line is written at most every `period` seconds, and the last one always.
"""

import sys
import time


def duration_text(seconds):
    seconds = max(0, int(round(seconds)))
    if seconds < 60:
        return f'{seconds} s'
    if seconds < 3600:
        return f'{seconds // 60} min {seconds % 60:02d} s'
    return f'{seconds // 3600} h {seconds % 3600 // 60:02d} min'


class Progress:
    """`update(done, data_seconds, failed)` as items complete; `close()` writes the last line."""

    def __init__(self, total, what='bags', label='planter', stream=None, period=5.0,
                 clock=time.monotonic):
        self.total, self.what, self.label = total, what, label
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, 'isatty', lambda: False)())
        self.period = 0.2 if self.tty else period
        self.clock = clock
        self.started = clock()
        self._shown = None
        self._written = None       # `done` of the last line written
        self.done = self.failed = 0
        self.data_seconds = 0.0

    def update(self, done, data_seconds=0.0, failed=0):
        self.done, self.data_seconds, self.failed = done, data_seconds, failed
        now = self.clock()
        if self._shown is None or now - self._shown >= self.period or done >= self.total:
            self._write(self.line(now))
            self._shown = now

    def line(self, now=None):
        elapsed = (self.clock() if now is None else now) - self.started
        parts = [f'{self.label}: {self.done}/{self.total} {self.what}']
        if elapsed > 0 and self.done:
            rate = self.done / elapsed
            parts.append(f'{rate:.3g} {self.what}/s')
            if self.data_seconds:
                parts.append(f'{self.data_seconds / elapsed:.0f}× real time')
            if self.done < self.total:
                parts.append(f'ETA {duration_text((self.total - self.done) / rate)}')
        if self.failed:
            parts.append(f'{self.failed} failed')
        if self.done >= self.total:
            parts.append(f'in {duration_text(elapsed)}')
        return ', '.join(parts)

    def _write(self, text):
        self._written = self.done
        if self.tty:
            self.stream.write('\r' + text + '\x1b[K')
        else:
            self.stream.write(text + '\n')
        self.stream.flush()

    def close(self):
        """The last line (and a newline after an in-place line)."""
        line = self.line()
        if self.tty:
            self.stream.write('\r' + line + '\x1b[K\n')
        elif self._written != self.done:
            self.stream.write(line + '\n')
        self.stream.flush()
