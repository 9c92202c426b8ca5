"""The bench table for people and the JSON for machines."""

from .machine import machine_line


def fmt_time(s):
    if s is None:
        return '—'
    for unit, scale in (('s', 1.0), ('ms', 1e-3), ('µs', 1e-6), ('ns', 1e-9)):
        if s >= scale or unit == 'ns':
            return f'{s / scale:.3g} {unit}'


def fmt_rate(r, unit):
    if r is None:
        return '—'
    for prefix, scale in (('G', 1e9), ('M', 1e6), ('k', 1e3), ('', 1.0)):
        if r >= scale or prefix == '':
            return f'{r / scale:.3g} {prefix + " " if prefix else ""}{unit}s/s'


def fmt_error(e):
    if e is None:
        return '—'
    return '0' if e == 0 else f'{e:.1e}'


def fmt_size(n):
    if not n:
        return ''
    return f'{n:.0e}'.replace('e+0', 'e') if n >= 10_000 else str(n)


HEADER = ('method', 'n', 'time/call', 'p10–p90', 'p99', 'per item', 'throughput', 'error',
          'target (§5)')
LEFT = (0, len(HEADER) - 1)      # columns aligned left: method, target


def table_lines(rows):
    cells = []
    for r in rows:
        if r.status != 'ok':
            cells.append((r.what, (r.note,) + ('',) * (len(HEADER) - 1)))
            continue
        t = r.timing
        spread = f'{fmt_time(t.p10)}–{fmt_time(t.p90)}' if t else '—'
        tail = fmt_time(t.p99) if t and t.p99 is not None else ''
        per = fmt_time(r.per_item) if r.size and r.size > 1 else ''
        rate = fmt_rate(r.throughput, r.unit) if r.size and r.size > 1 else ''
        cells.append((r.what, (r.method, fmt_size(r.size), fmt_time(t.median if t else None),
                               spread, tail, per, rate, fmt_error(r.error),
                               '; '.join(str(x) for x in r.targets))))
    widths = [max(len(HEADER[i]), *(len(c[1][i]) for c in cells if c[1][1] or i == 0))
              for i in range(len(HEADER))]
    widths[0] = max(len(HEADER[0]), *(len(c[1][0]) for c in cells if c[1][1]))

    def line(values):
        return '  ' + '  '.join(v.ljust(w) if i in LEFT else v.rjust(w)
                                for i, (v, w) in enumerate(zip(values, widths))).rstrip()

    out = [line(HEADER)]
    group = None
    for what, values in cells:
        if what != group:
            out.append(what)
            group = what
        if values[1] or values[2]:
            out.append(line(values))
        else:
            out.append('  ' + values[0])
    return out


def error_notes(rows):
    seen = []
    for r in rows:
        if r.error_of and (r.what, r.error_of) not in seen:
            seen.append((r.what, r.error_of))
    return [f'  error, {what}: {text}' for what, text in seen]


def row_notes(rows):
    out = []
    for r in rows:
        line = f'  {r.what} / {r.method}: {r.note}'
        if r.status == 'ok' and r.note and line not in out:
            out.append(line)
    return out


def format_table(machine, rows):
    lines = [f'planter bench · {machine_line(machine)}', '']
    lines += table_lines(rows)
    lines += ['', 'time/call: median of repeats (p10–p90 spread); per item = time/call ÷ n. '
              'Latency rows: median, p10–p90 and p99 over single events (count in the notes).',
              'error: relative, against mpmath at 40 digits computed by this run, unless its line '
              'below says otherwise; — where no error is defined.']
    lines += error_notes(rows)
    lines += ['notes:']
    lines += row_notes(rows)
    return '\n'.join(lines)


def as_json(machine, rows, quick):
    return {'machine': machine, 'quick': quick, 'rows': [r.as_dict() for r in rows]}
