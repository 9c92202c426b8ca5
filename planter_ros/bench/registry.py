"""Bench cases: one function per group of rows, registered with `@bench_case`.

A case is `fn(ctx) -> iterable of Row`. It imports what it measures inside the function, so a
case whose module is not installed (another branch not merged yet) reports one honest
"not available" row instead of failing the whole bench; a case that raises reports one
"FAILED" row and makes `planter bench` exit non-zero.

Adding a row group is one function in a module listed in CASE_MODULES:

    @bench_case('three-arm cycle', requires=('planter_ros.kinematics.three_arm',))
    def three_arm_cycle(ctx):
        from planter_ros.kinematics.three_arm import ...
        t = ctx.measure(lambda: ...)
        yield Row('three-arm cycle', 'exact', 1, 'cycle', t, error=..., error_of='...')
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TypeVar
import importlib
import importlib.util
import sys
import time
import traceback

from planter_ros.config import setting

from .timing import Timing, measure

_T = TypeVar('_T')

# modules whose import registers cases, in table order
CASE_MODULES = (
    'planter_ros.bench.cases.five_bar',
    'planter_ros.bench.cases.three_arm',
    'planter_ros.bench.cases.sync',
    'planter_ros.bench.cases.control_loop',
    'planter_ros.bench.cases.command_path',
    'planter_ros.bench.cases.command_targets',
    'planter_ros.bench.cases.replay',
    'planter_ros.bench.cases.analyze',
    'planter_ros.bench.cases.cdr',
    'planter_ros.bench.cases.drive',
    'planter_ros.bench.cases.footprint',
    'planter_ros.bench.cases.cam',
)


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


@dataclass(frozen=True)
class Case:
    name: str
    fn: CaseFunction
    requires: tuple[str, ...]


CASES: list[Case] = []


def bench_case(name: str, requires: Iterable[str] = ()
               ) -> Callable[[CaseFunction], CaseFunction]:
    """Register fn(ctx) as the case `name`; `requires` are modules it cannot run without."""
    def register(fn: CaseFunction) -> CaseFunction:
        CASES.append(Case(name, fn, tuple(requires)))
        return fn
    return register


@dataclass
class BenchContext:
    """What a case needs from the runner: size choice, timing settings, progress."""

    quick: bool = False
    verbose: bool = True
    seed: int = 20240601
    runs: int | None = setting(None, 'how many runs a case of whole runs makes (default: its '
                               "own, e.g. the issue's 10 demo runs)", kind=int, range=(1, 1000))

    def n(self, full: _T, quick: _T) -> _T:
        """The size to use: `full` for a real run, `quick` for the CI smoke run."""
        return quick if self.quick else full

    def measure(self, fn: Callable[[], object], repeats: int | None = None,
                min_time: float | None = None) -> Timing:
        if self.quick:
            return measure(fn, repeats=3, min_time=0.0)
        return measure(fn, repeats=repeats or 9, min_time=0.05 if min_time is None else min_time)

    def progress(self, text: str) -> None:
        if self.verbose:
            print(f'bench: {text}', file=sys.stderr, flush=True)


def load_cases() -> list[Case]:
    for name in CASE_MODULES:
        importlib.import_module(name)
    return list(CASES)


def _check_only(only: str, names: list[str]) -> None:
    from planter_ros.config import ConfigError
    shown = repr(only) if len(only) <= 40 else repr(only[:37] + '...')
    if not only.strip():
        raise ConfigError(f'--only = {shown} is empty: allowed text a case name contains '
                          f'(e.g. "hole"; leave --only out for every case)')
    if not any(only.lower() in name.lower() for name in names):
        raise ConfigError(f'--only = {shown} matches no bench case: allowed text one of '
                          f'{len(names)} case names contains, e.g. "{names[0]}"')


def _missing(modules: Iterable[str]) -> list[str]:
    out = []
    for name in modules:
        try:
            if importlib.util.find_spec(name) is None:
                out.append(name)
        except ModuleNotFoundError:
            out.append(name)
    return out


def run_cases(ctx: BenchContext, only: str | None = None) -> list[Row]:
    """Run every registered case (or those whose name contains `only`); returns the rows.
    ConfigError (one line, before any case runs) for an `only` that is empty or blank, or
    that no case's name contains."""
    cases = load_cases()
    if only is not None:
        _check_only(only, [case.name for case in cases])
    rows: list[Row] = []
    for case in cases:
        if only and only.lower() not in case.name.lower():
            continue
        missing = _missing(case.requires)
        if missing:
            rows.append(Row(case.name, '—', None, '', status='not available',
                            note=f"not available: {', '.join(missing)} not on this branch"))
            ctx.progress(f'{case.name}: not available ({", ".join(missing)})')
            continue
        t0 = time.perf_counter()
        ctx.progress(f'{case.name} ...')
        try:
            rows.extend(case.fn(ctx))
        except Exception as exc:   # one broken case must not hide the others' figures
            rows.append(Row(case.name, '—', None, '', status='FAILED',
                            note=f'FAILED: {type(exc).__name__}: {exc}'))
            if ctx.verbose:
                traceback.print_exc(file=sys.stderr)
        ctx.progress(f'{case.name} done in {time.perf_counter() - t0:.1f} s')
    return rows
