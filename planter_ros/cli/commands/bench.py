"""`planter bench`: run (the options: cli/bench.py)."""

import json
import time

from planter_ros.bench.host import machine_info
from planter_ros.bench.registry import BenchContext, run_cases
from planter_ros.bench.report import as_json, command_line, format_markdown, format_table
from planter_ros.cli.main import BadInput
from planter_ros.output_files import atomic_output, write_text_atomically


def run(args):
    ctx = BenchContext(quick=args.quick, runs=args.runs)
    machine = machine_info()
    started = time.monotonic()
    rows = run_cases(ctx, only=args.only)
    seconds = time.monotonic() - started
    if not rows:
        raise BadInput(f'--only = {", ".join(args.only or [])} matches no bench case')
    if args.plot:
        # lazy: the plot's module only with --plot (matplotlib, an extra: dependencies; loaded
        # without one it writes its font cache into the user's home: test_no_leftovers)
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
