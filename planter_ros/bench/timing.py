"""Run time of a callable: median of repeats with the 10th-90th percentile spread (and the
99th percentile for latencies measured event by event, see `from_samples`).

Each repeat runs the callable `loops` times (calibrated so one repeat lasts at least
`min_time`), so sub-microsecond calls are not swamped by the timer's own resolution. The
garbage collector is off while timing, as in `timeit`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
import gc
import time


@dataclass(frozen=True)
class Timing:
    """Seconds per call of the timed callable."""

    median: float
    p10: float
    p90: float
    repeats: int
    loops: int
    p99: float | None = None    # tail of a latency (many single events), else None

    @property
    def tail(self) -> float:
        """p99 of a latency timing (`from_samples(..., tail=True)`)."""
        if self.p99 is None:
            raise ValueError('this timing has no tail: time it with from_samples(tail=True)')
        return self.p99

    def per(self, n: int) -> Timing:
        """The same timing divided over n calls made inside each timed call."""
        return Timing(self.median / n, self.p10 / n, self.p90 / n, self.repeats, self.loops * n,
                      None if self.p99 is None else self.p99 / n)

    def as_dict(self) -> dict[str, float]:
        out: dict[str, float] = {'median_s': self.median, 'p10_s': self.p10, 'p90_s': self.p90,
               'repeats': self.repeats, 'loops': self.loops}
        if self.p99 is not None:
            out['p99_s'] = self.p99
        return out


def percentile(sorted_values: Sequence[float], q: float) -> float:
    """Linear-interpolation percentile (q in [0, 100]) of an ascending list."""
    n = len(sorted_values)
    if n == 1:
        return sorted_values[0]
    pos = (n - 1) * q / 100.0
    lo = int(pos)
    hi = min(lo + 1, n - 1)
    return sorted_values[lo] + (sorted_values[hi] - sorted_values[lo]) * (pos - lo)


def _run(fn: Callable[[], object], loops: int) -> float:
    t0 = time.perf_counter()
    for _ in range(loops):
        fn()
    return time.perf_counter() - t0


def measure(fn: Callable[[], object], repeats: int = 7, min_time: float = 0.05,
            max_loops: int = 1 << 20) -> Timing:
    """Time fn(): per-call seconds as median and p10/p90 over `repeats` repeats."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        fn()                                   # warm-up (caches, lazy imports)
        loops = 1
        while min_time > 0:                    # (min_time 0: one call per repeat, no probe)
            t = _run(fn, loops)
            if t >= min_time or loops >= max_loops:
                break
            grow = min_time / t if t > 0 else 10.0
            loops = min(max_loops, max(loops * 2, int(loops * min(grow * 1.2, 10.0)) + 1))
        samples = sorted(_run(fn, loops) / loops for _ in range(repeats))
    finally:
        if enabled:
            gc.enable()
    return Timing(percentile(samples, 50), percentile(samples, 10), percentile(samples, 90),
                  repeats, loops)


def from_samples(samples: Sequence[float], tail: bool = False) -> Timing:
    """Timing of already measured per-event seconds (e.g. one subprocess each); `tail` adds
    the 99th percentile (latencies: many events, the tail is the figure that matters)."""
    s = sorted(samples)
    if not s:
        raise ValueError('no samples to summarise')
    return Timing(percentile(s, 50), percentile(s, 10), percentile(s, 90), len(s), 1,
                  percentile(s, 99) if tail else None)
