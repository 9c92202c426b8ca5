"""`planter bench`: run time next to error against an mpmath reference, as a table or JSON,
optionally also written as a markdown page (doc/benchmarks.md is made this way)."""

import json
import time

from planter_ros.bench.registry import BenchContext
from planter_ros.cli.options import output_file, spec_option


def add_arguments(parser):
    parser.add_argument('--json', action='store_true',
                        help='print JSON (seconds, SI) for machines')
    parser.add_argument('--quick', action='store_true',
                        help='tiny sizes and few repeats: checks the bench works (CI), '
                             'figures are not meaningful')
    parser.add_argument('--plot', metavar='FILE.png', type=output_file('--plot', ('.png',)),
                        help='draw error against run time (log-log) for the methods that '
                             'trade one for the other')
    parser.add_argument('--only', metavar='TEXT',
                        help='run only the cases whose name contains TEXT (e.g. "hole")')
    parser.add_argument('--runs', metavar='N', type=spec_option(BenchContext, 'runs', '--runs'),
                        help='how many runs the cases made of whole demo runs make '
                             '(default: each case\'s own, 10)')
    parser.add_argument('--markdown', metavar='FILE.md', type=output_file('--markdown', ('.md',)),
                        help='also write the results as a markdown page to FILE (replaced '
                             'atomically): how it was made, the quality targets, one table '
                             'per row group')


def run(args):
    from planter_ros.cli.main import BadInput
    from planter_ros.bench.host import machine_info
    from planter_ros.bench.registry import run_cases
    from planter_ros.bench.report import as_json, command_line, format_markdown, format_table
    from planter_ros.output_files import atomic_output, write_text_atomically

    ctx = BenchContext(quick=args.quick, runs=args.runs)
    machine = machine_info()
    started = time.monotonic()
    rows = run_cases(ctx, only=args.only)
    seconds = time.monotonic() - started
    if not rows:
        raise BadInput(f'--only = {args.only} matches no bench case')
    if args.plot:
        from planter_ros.plots.bench import plot_tradeoff
        with atomic_output(args.plot) as tmp:
            plot_tradeoff(machine, rows, tmp)
    if args.markdown:
        write_text_atomically(args.markdown, format_markdown(
            machine, rows, command_line(args.quick, args.only, args.runs, args.markdown),
            quick=args.quick, seconds=seconds))
    if args.json:
        out = as_json(machine, rows, args.quick)
        if args.plot:
            out['plot'] = args.plot
        if args.markdown:
            out['markdown'] = args.markdown
        print(json.dumps(out, indent=2))
    else:
        print(format_table(machine, rows))
        if args.plot:
            print(f'plot: {args.plot}')
        if args.markdown:
            print(f'markdown: {args.markdown}')
    return 1 if any(r.status == 'FAILED' for r in rows) else 0

