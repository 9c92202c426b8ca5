"""Bench cases: one function per group of rows, registered with `@bench_case`.

A case is `fn(ctx) -> iterable of Row`; its module imports what it measures at its top. CASES
names every case and its module, in table order: the runner imports only the modules of the
cases asked for (`--only`), so `planter bench --only hole` loads no rclpy. A case whose module
cannot be imported (an extra not installed) reports one honest "not available" row instead of
failing the whole bench; a case that raises reports one "FAILED" row and makes `planter bench`
exit non-zero.

Adding a row group is one function in a case module and its line in CASES:

    @bench_case('three-arm cycle')
    def three_arm_cycle(ctx):
        t = ctx.measure(lambda: ...)
        yield Row('three-arm cycle', 'exact', 1, 'cycle', t, error=..., error_of='...')
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from contextlib import AbstractContextManager, ExitStack
from dataclasses import dataclass, field
from typing import Any, TypeVar
import importlib
import sys
import time
import traceback

from planter_ros.config import ConfigError, setting

from .hogs import HOGS, QUICK_HOG_NICENESS, QUICK_HOGS
from .timing import Timing, measure

_T = TypeVar('_T')

_CASES = 'planter_ros.bench.cases.'
# every case: its name -> the module whose import registers it, in table order
CASES = {
    'five-bar reverse design': _CASES + 'five_bar',
    'hole width': _CASES + 'five_bar',
    'hole-width tolerance': _CASES + 'five_bar',
    'trajectory evaluation': _CASES + 'five_bar',
    'gear-train closure': _CASES + 'three_arm',
    'three-arm build and cycle': _CASES + 'three_arm',
    'three-arm optimiser': _CASES + 'three_arm',
    'sync loop latency': _CASES + 'sync',
    'sync loop latency per row count': _CASES + 'sync',
    'closed loop through curves': _CASES + 'sync',
    'control loop under load': _CASES + 'control_loop',
    'graph-join stall': _CASES + 'command_path',
    'command-latency': _CASES + 'command_targets',
    'demo-runs under load': _CASES + 'command_targets',
    'replay': _CASES + 'replay',
    'analyze': _CASES + 'analyze',
    'losses': _CASES + 'analyze',
    'CDR field decoding': _CASES + 'cdr',
    'CAN drive': _CASES + 'drive',
    'footprint of a minimal five-bar run': _CASES + 'footprint',
    'cam evaluation': _CASES + 'cam',
    'cam tip sweep vs brute force': _CASES + 'cam',
    'cam, one mechanism designed for 0.15 m': _CASES + 'cam',
}


@dataclass(frozen=True)
class Target:
    """A quality target and whether this run met it (measured, not asserted)."""

    text: str
    met: bool

    def __str__(self) -> str:
        return f"{self.text} {'met' if self.met else 'NOT MET'}"


@dataclass
class Row:
    """One method at one size: what it computes, how long it took, how wrong it was."""

    what: str                   # the quantity computed (groups rows in the table)
    method: str
    size: int | None            # items per timed call
    unit: str                   # what one item is: 'design', 'hole', 'point', 'run', ...
    timing: Timing | None = None    # seconds per timed call
    error: float | None = None  # max relative error vs the reference, or None if not defined
    error_of: str = ''          # how `error` is defined (printed once per group)
    targets: list[Target] = field(default_factory=list)
    note: str = ''
    series: str = ''            # non-empty: plotted on the error-vs-time trade-off chart
    extra: dict[str, object] = field(default_factory=dict)
    status: str = 'ok'          # 'ok', 'not available', 'FAILED'

    @property
    def per_item(self) -> float | None:
        if self.timing is None or not self.size:
            return None
        return self.timing.median / self.size

    @property
    def throughput(self) -> float | None:
        if self.timing is None or not self.size or self.timing.median <= 0:
            return None
        return self.size / self.timing.median

    def as_dict(self) -> dict[str, object]:
        out: dict[str, object] = {
               'what': self.what, 'method': self.method, 'size': self.size, 'unit': self.unit,
               'status': self.status, 'error': self.error, 'error_of': self.error_of,
               'per_item_s': self.per_item, 'throughput_per_s': self.throughput,
               'targets': [{'target': t.text, 'met': t.met} for t in self.targets],
               'note': self.note}
        if self.timing is not None:
            out.update(self.timing.as_dict())
        out.update(self.extra)
        return out


# a case: fn(ctx) -> its rows
CaseFunction = Callable[['BenchContext'], Iterable[Row]]


# the case functions registered so far (by the case modules imported): name -> fn
REGISTERED: dict[str, CaseFunction] = {}


def bench_case(name: str) -> Callable[[CaseFunction], CaseFunction]:
    """Register fn(ctx) as the case `name` (named in CASES with this module)."""
    def register(fn: CaseFunction) -> CaseFunction:
        REGISTERED[name] = fn
        return fn
    return register


@dataclass
class BenchContext:
    """What a case needs from the runner: size choice, timing settings, progress, and what
    cases share in one run (`shared`)."""

    quick: bool = False
    verbose: bool = True
    seed: int = 20240601
    runs: int | None = setting(None, 'how many runs a case of whole runs makes (default: its '
                               "own, e.g. the issue's 10 demo runs)", kind=int, range=(1, 1000))

    def __post_init__(self) -> None:
        self._held = ExitStack()
        self._shared: dict[str, Any] = {}

    def shared(self, key: str, make: Callable[[], AbstractContextManager[Any]]) -> Any:
        """What the context manager `make()` gives, made by the first case that asks for `key`
        and kept for the others until the run ends (`close`): the quick run's one local Dask
        cluster for the analysis cases, say."""
        if key not in self._shared:
            self._shared[key] = self._held.enter_context(make())
        return self._shared[key]

    def close(self) -> None:
        """End what the cases shared (run_cases does, after the last case)."""
        self._shared.clear()
        self._held.close()

    def n(self, full: _T, quick: _T) -> _T:
        """The size to use: `full` for a real run, `quick` for the CI smoke run."""
        return quick if self.quick else full

    @property
    def hogs(self) -> int:
        """How many CPU hogs run beside a run under load (bench.hogs)."""
        return self.n(HOGS, QUICK_HOGS)

    @property
    def hog_niceness(self) -> int:
        """The niceness the CPU hogs add to the bench's (bench.hogs: 0, --quick the lowest)."""
        return self.n(0, QUICK_HOG_NICENESS)

    def measure(self, fn: Callable[[], object], repeats: int | None = None,
                min_time: float | None = None) -> Timing:
        if self.quick:
            # the smoke run: a warm-up, then one call per repeat, at most three (fewer when the
            # case asks for fewer, e.g. one for a whole simulated run)
            return measure(fn, repeats=min(repeats or 3, 3), min_time=0.0)
        return measure(fn, repeats=repeats or 9, min_time=0.05 if min_time is None else min_time)

    def progress(self, text: str) -> None:
        if self.verbose:
            print(f'bench: {text}', file=sys.stderr, flush=True)


def load_case(name: str) -> CaseFunction:
    """The function of case `name`, its module imported (ModuleNotFoundError: an extra of it
    is not installed)."""
    # lazy: the one late import of the bench: only the modules of the cases asked for (rclpy,
    # Dask or canopen only for the cases that use them; `--only hole` takes 1 s, not 10)
    importlib.import_module(CASES[name])
    return REGISTERED[name]


def _check_only(only: str, names: list[str]) -> None:
    shown = repr(only) if len(only) <= 40 else repr(only[:37] + '...')
    if not only.strip():
        raise ConfigError(f'--only = {shown} is empty: allowed text a case name contains '
                          f'(e.g. "hole"; leave --only out for every case)')
    if not any(only.lower() in name.lower() for name in names):
        raise ConfigError(f'--only = {shown} matches no bench case: allowed text one of '
                          f'{len(names)} case names contains, e.g. "{names[0]}"')


def run_cases(ctx: BenchContext, only: str | Sequence[str] | None = None) -> list[Row]:
    """Run every case (or those whose name contains `only`, or any text of it); returns the
    rows. ConfigError (one line, before any case runs) for a text that is empty or blank, or
    that no case's name contains."""
    names = list(CASES)
    texts = [only] if isinstance(only, str) else list(only or ())
    for text in texts:
        _check_only(text, names)
    rows: list[Row] = []
    try:
        for name in names:
            if texts and not any(text.lower() in name.lower() for text in texts):
                continue
            rows.extend(_run_case(ctx, name))
    finally:
        ctx.close()
    return rows


def _run_case(ctx: BenchContext, name: str) -> list[Row]:
    try:
        fn = load_case(name)
    except ModuleNotFoundError as exc:
        ctx.progress(f'{name}: not available ({exc.name} is not installed)')
        return [Row(name, '—', None, '', status='not available',
                    note=f'not available: {exc.name} is not installed')]
    t0 = time.perf_counter()
    ctx.progress(f'{name} ...')
    rows: list[Row] = []
    try:
        rows.extend(fn(ctx))
    except Exception as exc:   # one broken case must not hide the others' figures
        rows.append(Row(name, '—', None, '', status='FAILED',
                        note=f'FAILED: {type(exc).__name__}: {exc}'))
        if ctx.verbose:
            traceback.print_exc(file=sys.stderr)
    ctx.progress(f'{name} done in {time.perf_counter() - t0:.1f} s')
    return rows
