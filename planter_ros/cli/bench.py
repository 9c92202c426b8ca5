"""`planter bench`: run time next to error against an mpmath reference, as a table or JSON,
optionally also written as a markdown page (doc/benchmarks.md is made this way)."""

import json
import os
import shlex
import time


def add_arguments(parser):
    parser.add_argument('--json', action='store_true',
                        help='print JSON (seconds, SI) for machines')
    parser.add_argument('--quick', action='store_true',
                        help='tiny sizes and few repeats: checks the bench works (CI), '
                             'figures are not meaningful')
    parser.add_argument('--plot', metavar='FILE.png',
                        help='draw error against run time (log-log) for the methods that '
                             'trade one for the other')
    parser.add_argument('--only', metavar='TEXT',
                        help='run only the cases whose name contains TEXT (e.g. "hole")')
    parser.add_argument('--markdown', metavar='FILE',
                        help='also write the results as a markdown page to FILE (replaced '
                             'atomically): how it was made, the quality targets, one table '
                             'per row group')


def run(args):
    from planter_ros.cli.main import BadInput
    if args.plot and not args.plot.lower().endswith('.png'):
        raise BadInput(f'--plot = {args.plot} is not a .png file name')
    if args.markdown:
        check_markdown_path(args.markdown, BadInput)      # before minutes of bench work
    from planter_ros.bench.machine import machine_info
    from planter_ros.bench.registry import BenchContext, run_cases
    from planter_ros.bench.report import as_json, format_markdown, format_table, write_atomically

    ctx = BenchContext(quick=args.quick)
    machine = machine_info()
    started = time.monotonic()
    rows = run_cases(ctx, only=args.only)
    seconds = time.monotonic() - started
    if not rows:
        raise BadInput(f'--only = {args.only} matches no bench case')
    if args.plot:
        from planter_ros.plots.bench import plot_tradeoff
        plot_tradeoff(machine, rows, args.plot)
    if args.markdown:
        write_atomically(args.markdown, format_markdown(
            machine, rows, command_line(args), quick=args.quick, seconds=seconds))
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


def check_markdown_path(path, error):
    """Refuse a --markdown FILE that cannot be written (raises `error` with one line)."""
    directory = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        raise error(f'--markdown = {path} is a directory, not a file name')
    if not os.path.isdir(directory):
        raise error(f'--markdown = {path}: directory {directory} does not exist')
    if not os.access(directory, os.W_OK | os.X_OK):
        raise error(f'--markdown = {path}: directory {directory} is not writable')


def command_line(args):
    """The `planter bench` command that reproduces this run (for the page's header)."""
    words = ['planter', 'bench']
    if args.quick:
        words.append('--quick')
    if args.only:
        words += ['--only', args.only]
    words += ['--markdown', args.markdown]
    return shlex.join(words)
