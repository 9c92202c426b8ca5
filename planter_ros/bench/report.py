"""The bench table for people, the JSON for machines and the markdown page for the docs."""

from collections.abc import Iterable, Sequence
import shlex

from .host import MachineInfo, machine_line
from .registry import Row

# The quality targets: (quantity, target, row group that measures it, text its rows' Target
# starts with). Group None: no bench row measures it (the command named reports it itself).
QUALITY_TARGETS = (
    ('five-bar reverse design, scalar', '≤ 20 µs per design',
     'five-bar reverse design', '≤ 20 µs'),
    ('five-bar reverse design, batched', '≥ 1e6 designs/s',
     'five-bar reverse design', '≥ 1e6/s'),
    ('exact five-bar design: hole of the computed bars', '≤ 1e-9 relative vs the mpmath reference',
     'five-bar reverse design', 'err ≤ 1e-9'),
    ('hole width (closed form)', '≤ 1e-9 relative vs the mpmath reference',
     'hole width', 'err ≤ 1e-9'),
    ('gear-closure integral (three-arm centre distance)', '≤ 1e-9 relative',
     'gear-train closure', 'err ≤ 1e-9'),
    ('a full three-arm cycle (3 arms, 360 angles each)', '≤ 1 ms',
     'three-arm cycle', '≤ 1 ms'),
    ('sync loop: ground-speed message → CAN frame', 'p99 ≤ 2 ms',
     'sync loop', 'p99 ≤ 2 ms'),
    ("sync loop, 8 rows on one bus: ground-speed message → the last row's CAN frame",
     'p99 ≤ 2 ms', 'sync loop, rows on one bus', '8 rows: p99 ≤ 2 ms'),
    ('control loop under load (10 demo runs of 30 s, 2 CPU hogs beside each): drive watchdog',
     '0 trips', 'control loop under load', '0 watchdog trips'),
    ('control loop under load: gap between consecutive command frames of a row',
     'p99.9 ≤ 50 ms (a quarter of the 0.2 s RPDO deadline)', 'control loop under load',
     'p99.9 gap ≤ 50 ms'),
    ("command path, 8 rows, two CPU hogs beside it: ground-speed sample (the shell's receipt) "
     "→ the last row's CAN frame", 'p99 ≤ 1 ms', 'command path, 8 rows', 'p99 ≤ 1 ms'),
    ('4-row demo in CSP at 10 ms SYNC, two CPU hogs beside it: spacing error per row through '
     'its profile and turns, from the replay of its bag', 'RMS ≤ 0.5 % of d', '4-row demo in CSP',
     'spacing RMS ≤ 0.5 % of d per row'),
    ('… the same: interval between SYNCs', 'p99 within ±1 ms of the period',
     '4-row demo in CSP', 'SYNC interval p99 within ±1 ms'),
    ('10 such demo runs: drive watchdog trips, verdicts', '0 trips, every run PASS',
     '4-row demo in CSP', '0 watchdog trips'),
    ('4 rows through 10 m turns with turn compensation: spacing error per row',
     'RMS ≤ 2 % of d', 'closed loop, 4 rows', 'RMS ≤ 2 % of d'),
    ('4 rows through 10 m turns: measured mechanism speed over 2πv_i/(n·d)',
     'median within 3 %', 'closed loop, 4 rows', 'speed ratio within 3 %'),
    ('replay of a recording', '≥ 1000× real time per core',
     'replay', '≥ 1000× real time'),
    ('refusing a file with no valid MCAP record', '≤ 1 s whatever its size',
     'replay', '≤ 1 s'),
    ('season analysis (`planter analyze`, 200 one-minute bags)', '≥ 1000× real time per worker',
     'season analysis', '≥ 1000× real time per worker'),
    ('season analysis: 1 → 2 local workers', '≥ 80 % scaling efficiency',
     'season analysis', '≥ 80 % efficiency'),
    ('three-arm optimiser (`planter optimize three-arm --seed 1`)',
     'meets all eight goals in ≤ 15 s of search on 2 cores', 'three-arm optimiser (search)',
     '≤ 15 s'),
    ("cam evaluation: θ, θ′, θ″ at a row's travelled distance (scalar)",
     '≤ 20 µs per row per SYNC cycle', 'cam evaluation', '≤ 20 µs'),
    ('planned cam tip sweep against a brute-force sampled tip path (10⁶ points per revolution)',
     '≤ 1e-6 m', 'cam tip sweep vs brute force', 'err ≤ 1e-6 m'),
    ('one five-bar designed for d = 0.15 m, cam at d = 0.15–0.5 m and 0.3 m/s: tip sweep',
     'within 0.1 mm of the design hole', 'cam, one mechanism', 'sweep within 0.1 mm'),
    ('… the same: seedling tilt', '≤ 1°', 'cam, one mechanism', 'tilt ≤ 1°'),
    ('… the same: drive loads', 'within the default limits (750 W servo, 20:1 gearbox)',
     'cam, one mechanism', 'within the default limits'),
)


def fmt_time(s: float | None) -> str:
    if s is None:
        return '—'
    for unit, scale in (('s', 1.0), ('ms', 1e-3), ('µs', 1e-6)):
        if s >= scale:
            return f'{s / scale:.3g} {unit}'
    return f'{s / 1e-9:.3g} ns'


def fmt_rate(r: float | None, unit: str) -> str:
    if r is None:
        return '—'
    for prefix, scale in (('G', 1e9), ('M', 1e6), ('k', 1e3)):
        if r >= scale:
            return f'{r / scale:.3g} {prefix} {unit}s/s'
    return f'{r:.3g} {unit}s/s'


def fmt_error(e: float | None) -> str:
    if e is None:
        return '—'
    return '0' if e == 0 else f'{e:.1e}'


def fmt_size(n: int | None) -> str:
    if not n:
        return ''
    return f'{n:.0e}'.replace('e+0', 'e') if n >= 10_000 else str(n)


HEADER = ('method', 'n', 'time/call', 'p10–p90', 'p99', 'per item', 'throughput', 'error',
          'target')
LEFT = (0, len(HEADER) - 1)      # columns aligned left: method, target


def row_cells(r: Row) -> tuple[str, ...]:
    """The HEADER columns of one row as text; a row that did not run carries its note only."""
    if r.status != 'ok':
        return (r.note,) + ('',) * (len(HEADER) - 1)
    t = r.timing
    spread = f'{fmt_time(t.p10)}–{fmt_time(t.p90)}' if t else '—'
    tail = fmt_time(t.p99) if t and t.p99 is not None else ''
    per = fmt_time(r.per_item) if r.size and r.size > 1 else ''
    rate = fmt_rate(r.throughput, r.unit) if r.size and r.size > 1 else ''
    return (r.method, fmt_size(r.size), fmt_time(t.median if t else None), spread, tail, per,
            rate, fmt_error(r.error), '; '.join(str(x) for x in r.targets))


def table_lines(rows: Sequence[Row]) -> list[str]:
    cells = [(r.what, row_cells(r)) for r in rows]
    # rows without a size (FAILED, not available) print their note only: not in the widths
    widths = [max([len(HEADER[i]), *(len(c[1][i]) for c in cells if c[1][1] or i == 0)])
              for i in range(len(HEADER))]
    widths[0] = max([len(HEADER[0]), *(len(c[1][0]) for c in cells if c[1][1])])

    def line(values: Sequence[str]) -> str:
        return '  ' + '  '.join(v.ljust(w) if i in LEFT else v.rjust(w)
                                for i, (v, w) in enumerate(zip(values, widths))).rstrip()

    out = [line(HEADER)]
    group: str | None = None
    for what, values in cells:
        if what != group:
            out.append(what)
            group = what
        if values[1] or values[2]:
            out.append(line(values))
        else:
            out.append('  ' + values[0])
    return out


def error_notes(rows: Iterable[Row]) -> list[str]:
    seen: list[tuple[str, str]] = []
    for r in rows:
        if r.error_of and (r.what, r.error_of) not in seen:
            seen.append((r.what, r.error_of))
    return [f'  error, {what}: {text}' for what, text in seen]


def row_notes(rows: Iterable[Row]) -> list[str]:
    out: list[str] = []
    for r in rows:
        line = f'  {r.what} / {r.method}: {r.note}'
        if r.status == 'ok' and r.note and line not in out:
            out.append(line)
    return out


TIME_LEGEND = ('time/call: median of repeats (p10–p90 spread); per item = time/call ÷ n. '
               'Latency rows: median, p10–p90 and p99 over single events (count in the notes).')
ERROR_LEGEND = ('error: relative, against mpmath at 40 digits computed by this run, unless its '
                'line below says otherwise; — where no error is defined.')


def format_table(machine: MachineInfo, rows: Sequence[Row]) -> str:
    lines = [f'planter bench · {machine_line(machine)}', '']
    lines += table_lines(rows)
    lines += ['', TIME_LEGEND, ERROR_LEGEND]
    lines += error_notes(rows)
    lines += ['notes:']
    lines += row_notes(rows)
    return '\n'.join(lines)


def command_line(quick: bool, only: Sequence[str] | None, runs: int | None,
                 markdown: str) -> str:
    """The `planter bench` command that reproduces a run (for the page's header)."""
    words = ['planter', 'bench'] + ['--quick'] * bool(quick)
    words += [word for text in only or () for word in ('--only', text)]
    words += ['--runs', str(runs)] if runs else []
    return shlex.join(words + ['--markdown', str(markdown)])


def as_json(machine: MachineInfo, rows: Iterable[Row], quick: bool) -> dict[str, object]:
    return {'machine': machine, 'quick': quick, 'rows': [r.as_dict() for r in rows]}


# --- markdown ---------------------------------------------------------------------------------

# How the rows are made, for the page's readers (the per-row details are in each table's notes).
METHOD_NOTES = (
    'Every error is against a reference this run computes itself with mpmath (working precision '
    'raised where a formula cancels); no expected numbers are stored.',
    'Five-bar design rows: the hole the computed (float) bars achieve, evaluated in mpmath, '
    'against k·D over random scenes (D 20–100 mm, d 0.15–0.6 m, k up to half its feasible '
    'limit); the bars themselves are also compared with the mpmath exact design (notes).',
    'Dense sampling is the naive hole width: sample one sun-bar turn, keep the points below the '
    'soil, take their extent.',
    'Sync loop: the real `sync_node` in its own single-threaded executor thread, on a python-can '
    'virtual bus with the simulated drive, ROS in a fresh context on a private DDS domain '
    '(localhost discovery); each ground-speed message is timed from `publish()` to the RPDO it '
    'caused (python-can\'s send stamp).',
    'Control loop under load: whole `planter demo` runs (one five-bar row) with two '
    '`python -c "while True: pass"` processes beside each; the gaps between a row\'s command '
    'frames as the sync process sends them, pooled over every run; watchdog trips of the '
    'simulated drive (judged on the frames\' bus time).',
    'Replay: a generated 10-minute input bag (× real time against the target) and the committed '
    'sample bags, whose error is against the live monitor\'s recorded predictions.',
    'Season analysis: `planter analyze` of a season `planter simulate` wrote (one-minute '
    'runs of a 4-row machine, copied to 200 bags), on a local Dask cluster of 1 and 2 worker '
    'processes; the cluster start is timed apart; the targets are judged on each worker '
    'count\'s fastest of 3 runs (the least disturbed by other load), the median is in the note.',
    'Command path (doc/command.md): the demo\'s layout, a sync node shell, its command process '
    '(SCHED_FIFO) and the simulated drives in a process of their own; the sample-to-frame '
    'latency is the command process\'s own figure, from the shell\'s receipt of a sample to the '
    'last row\'s RPDO sent, in profile velocity (where a sample sends its frames at once).',
    '4-row demo in CSP: whole `planter demo --scene config/tomato_4row.yaml` runs, each beside '
    'two `python -c "while True: pass"` processes; the spacing error of each row is the replay\'s '
    '(plants at the distance integrated from the recorded ground speed), the SYNC intervals '
    'as the command process sent them; `--runs N` makes fewer or more than the 10 runs.',
    'CAN drive: master and simulated drive in one process on a python-can virtual bus.',
    'Footprint: each run in a fresh interpreter; peak RSS is the child\'s own VmHWM; a five-bar '
    'design must load no scipy, matplotlib, rclpy or other mechanism.',
    'Cam rows: one five-bar designed for D = 45 mm, d = 0.15 m, k = 0.05; the evaluation is '
    'timed per call over 2000 successive SYNC cycles of one row (10 ms at 0.3 m/s) and checked '
    'against scipy\'s PPoly of the same coefficients; the brute-force tip sweep samples θ(s) '
    'at 10⁶ points per revolution (an error of at most max|dx/ds|·d/10⁶ of its own).',
    'A row group is one function `@bench_case(name)` in a case module, named with its module in '
    '`planter_ros/bench/registry.py` (`CASES`: only the modules of the cases asked for are '
    'imported); a case whose module cannot be imported (an extra not installed) reports one '
    '"not available" row, a case that raises one FAILED row and a non-zero exit.',
)


def _md_cell(text: object) -> str:
    return str(text).replace('|', '\\|').replace('\n', ' ')


def _md_row(values: Iterable[object]) -> str:
    return '| ' + ' | '.join(_md_cell(v) for v in values) + ' |'


def target_status(rows: Iterable[Row], group: str | None, text: str) -> str:
    """'met', 'NOT MET (k of n rows)' or 'no row in this run' for one quality target."""
    if group is None:
        return 'not a bench row'
    found = [t for r in rows if r.status == 'ok' and r.what.startswith(group)
             for t in r.targets if t.text.startswith(text)]
    if not found:
        return 'no row in this run'
    missed = sum(not t.met for t in found)
    if not missed:
        return 'met' if len(found) == 1 else f'met ({len(found)} rows)'
    return f'NOT MET ({missed} of {len(found)} rows)'


def _groups(rows: Iterable[Row]) -> dict[str, list[Row]]:
    out: dict[str, list[Row]] = {}
    for r in rows:
        out.setdefault(r.what, []).append(r)
    return out


def format_markdown(machine: MachineInfo, rows: Sequence[Row], command: str,
                    quick: bool = False, seconds: float | None = None) -> str:
    """The bench as a markdown page: how it was made, the quality targets and whether this run
    met them, one table per row group with its error definition and notes."""
    took = f' · {seconds:.3g} s of bench work' if seconds is not None else ''
    lines = ['# Benchmarks', '',
             f'Written by `{command}`; re-run that command to update this page rather than '
             'editing it.', '',
             f'Run: {machine_line(machine)}{took}.', '']
    if quick:
        lines += ['**`--quick` run: tiny sizes and few repeats; its figures mean nothing.**', '']
    lines += ['## Quality targets', '',
              'Reported as met / NOT MET from the figures of this run, never asserted in tests '
              '(a timing target can be missed on a busy machine).', '',
              _md_row(('quantity', 'target', 'measured in', 'this run')),
              '|---|---|---|---|']
    for quantity, target, group, text in QUALITY_TARGETS:
        where = f'{group} rows' if group else 'its own output (search time)'
        lines.append(_md_row((quantity, target, where, target_status(rows, group, text))))
    lines += ['', '## Results', '', TIME_LEGEND, '',
              'error: relative, against mpmath at 40 digits computed by this run, unless the '
              'line under its table says otherwise; — where no error is defined.', '']
    numeric = {1, 2, 3, 4, 5, 6, 7}
    align = ['---:' if i in numeric else '---' for i in range(len(HEADER))]
    for what, members in _groups(rows).items():
        lines += [f'### {what}', '', _md_row(HEADER), '|' + '|'.join(align) + '|']
        lines += [_md_row(row_cells(r)) for r in members]
        lines.append('')
        definitions: list[str] = []
        for r in members:
            if r.error_of and r.error_of not in definitions:
                definitions.append(r.error_of)
        if len(definitions) == 1:
            lines.append(f'Error: {definitions[0]}')
        elif definitions:
            lines += ['Error:', ''] + [f'- {text}' for text in definitions]
        notes: list[tuple[str, str]] = []
        for r in members:
            if r.status == 'ok' and r.note and (r.method, r.note) not in notes:
                notes.append((r.method, r.note))
        if notes:
            lines += ([''] if definitions else []) + ['Notes:', '']
            lines += [f'- {method}: {note}' for method, note in notes]
        if definitions or notes:
            lines.append('')
    lines += ['## How the bench measures', '']
    lines += [f'- {text}' for text in METHOD_NOTES]
    return '\n'.join(lines).rstrip('\n') + '\n'

