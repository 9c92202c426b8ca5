"""How well the control loop keeps the drive's deadline: the time between consecutive command
frames of one row.

A drive quick-stops when no command frame reaches it within its RPDO deadline (the sync node's
`command_timeout`, 0.2 s): the largest gap between two frames and the tail of their
distribution (p99.9) are the figures that say how much margin the loop keeps. `PeriodStats`
counts gaps in a fixed histogram (0.1 ms bins up to 1 s, one overflow bin above), so it runs
for hours in constant memory and costs one list increment per frame in the control loop's hot
path. Pure (numpy), times in seconds passed in explicitly.

`SyncLoopConfig` sets the loop's own timing (parameters of the sync node).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any

import numpy as np

from planter_ros.config import check, setting

__all__ = ['BIN', 'SPAN', 'SyncLoopConfig', 'PeriodStats']

BIN = 1e-4                  # s, histogram resolution
SPAN = 1.0                  # s, gaps above this share the overflow bin (their max is kept)


@dataclass(frozen=True)
class SyncLoopConfig:
    """The sync node's loop (fixed at start-up): its period, the diagnostics period, the
    ground-speed rate the CAN bus-load check budgets for, and where it runs (the command
    process, its real-time priority and restarts)."""

    control_period: float = setting(0.02, 'control loop period: heartbeat, stale handling, '
                                    'joint_states', unit='s', range=(0.002, 0.1), read_only=True)
    diagnostics_period: float = setting(1.0, '/diagnostics period', unit='s', range=(0.1, 10.0),
                                        read_only=True)
    ground_speed_rate: float = setting(50.0, 'the fastest ground-speed sample rate the CAN '
                                       'bus-load check budgets for (each sample sends one RPDO '
                                       'per row)', unit='Hz', range=(1.0, 1000.0),
                                       read_only=True)
    command_process: bool = setting(True, 'true: the CAN bus, the drives and the row loop run '
                                    'in a command process of their own (no DDS, no rclpy), '
                                    'which no ROS graph event can stall; false: in this '
                                    'node\'s process', read_only=True)
    realtime_priority: int = setting(40, 'SCHED_FIFO priority the command process asks for '
                                     '(0 = ask for none); refused = said in the log and in '
                                     '/diagnostics, it runs on', range=(0, 99), read_only=True)
    shell_nice: int = setting(-10, "nice value this node asks for when a command process runs "
                              'the drives (its ground-speed path competes for the CPU with '
                              'other processes; 0 = ask for none); refused = said in the log',
                              range=(-20, 0), read_only=True)
    command_restarts: int = setting(3, 'times the node restarts a command process that died '
                                    "(the drives' own watchdogs stop the motors meanwhile); "
                                    'then it reports ERROR', range=(0, 100), read_only=True)
    enable_after_restart: bool = setting(False, 'true (a fenced machine only): after an '
                                         'automatic restart of the command process or of the '
                                         'service the rows run again by themselves; false: '
                                         'they wait at zero until an operator calls '
                                         'enable_rows', read_only=True)
    last_stop_file: str = setting('', 'where the service manager notes how the last run of '
                                  'the graph ended (systemd/planter.service: '
                                  '/run/planter/last-stop); a start after a run that did not '
                                  'end with success is an automatic restart ("" = none)',
                                  read_only=True)

    def __post_init__(self) -> None:
        check(self)


class PeriodStats:
    """Gaps between consecutive events (frames) of one row, from `event(now)` calls."""

    def __init__(self, bin_width: float = BIN, span: float = SPAN) -> None:
        self.bin_width = float(bin_width)
        self.counts = np.zeros(int(round(span / bin_width)) + 1, dtype=np.int64)
        self.gaps = 0
        self.max_gap = 0.0
        self.total = 0.0
        self._last: float | None = None

    def event(self, now: float) -> None:
        """One frame sent at `now` (monotonic s)."""
        last, self._last = self._last, now
        if last is not None:
            self.add(now - last)

    def restart(self) -> None:
        """The next event starts a new series (the row stopped sending on purpose: shut
        down, left out): the pause is no gap of the loop."""
        self._last = None

    def add(self, gap: float) -> None:
        gap = max(float(gap), 0.0)
        self.counts[min(int(gap / self.bin_width), self.counts.size - 1)] += 1
        self.gaps += 1
        self.total += gap
        if gap > self.max_gap:
            self.max_gap = gap

    def quantile(self, q: float) -> float:
        """The gap (s) that a fraction `q` of all gaps do not exceed, to one bin (the upper
        edge of its bin, never more than the largest gap; the largest gap in the overflow
        bin); NaN before two events."""
        if not self.gaps:
            return math.nan
        rank = max(1, math.ceil(q * self.gaps))
        i = int(np.searchsorted(np.cumsum(self.counts), rank))
        if i >= self.counts.size - 1:            # the overflow bin: only its max is known
            return self.max_gap
        return min((i + 1) * self.bin_width, self.max_gap)

    @property
    def mean(self) -> float:
        return self.total / self.gaps if self.gaps else math.nan

    def merge(self, other: PeriodStats) -> PeriodStats:
        """Add another series' gaps (e.g. every row's, for one figure of the machine)."""
        if other.counts.size != self.counts.size or other.bin_width != self.bin_width:
            raise ValueError('PeriodStats.merge: different histograms')
        self.counts = self.counts + other.counts
        self.gaps += other.gaps
        self.total += other.total
        self.max_gap = max(self.max_gap, other.max_gap)
        return self

    def histogram(self) -> dict[str, Any]:
        """The counts as plain data (the nonzero bins), e.g. to send to another process."""
        return {'bin': self.bin_width, 'size': int(self.counts.size), 'max': self.max_gap,
                'total': self.total,
                'counts': {int(i): int(self.counts[i]) for i in self.counts.nonzero()[0]}}

    @classmethod
    def from_histogram(cls, data: dict[str, Any]) -> PeriodStats:
        """The PeriodStats `histogram()` describes (without its last event)."""
        stats = cls(data['bin'], data['bin'] * (data['size'] - 1))
        for i, count in data['counts'].items():
            stats.counts[int(i)] = count
        stats.gaps = int(stats.counts.sum())
        stats.max_gap, stats.total = data['max'], data['total']
        return stats

    def summary(self) -> dict[str, int | float | None]:
        """JSON-ready figures (s): frames' gaps counted, mean, p99, p99.9, max."""
        def finite(x: float) -> float | None:

            return None if math.isnan(x) else x
        return {'gaps': self.gaps, 'mean': finite(self.mean),
                'p99': finite(self.quantile(0.99)), 'p999': finite(self.quantile(0.999)),
                'max': self.max_gap if self.gaps else None}
