"""`planter bench`: run time next to error against an mpmath reference, as a table or JSON."""

import json


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


def run(args):
    from planter_ros.cli.main import BadInput
    if args.plot and not args.plot.lower().endswith('.png'):
        raise BadInput(f'--plot = {args.plot} is not a .png file name')
    from planter_ros.bench.machine import machine_info
    from planter_ros.bench.registry import BenchContext, run_cases
    from planter_ros.bench.report import as_json, format_table

    ctx = BenchContext(quick=args.quick)
    machine = machine_info()
    rows = run_cases(ctx, only=args.only)
    if not rows:
        raise BadInput(f'--only = {args.only} matches no bench case')
    if args.plot:
        from planter_ros.plots.bench import plot_tradeoff
        plot_tradeoff(machine, rows, args.plot)
    if args.json:
        out = as_json(machine, rows, args.quick)
        if args.plot:
            out['plot'] = args.plot
        print(json.dumps(out, indent=2))
    else:
        print(format_table(machine, rows))
        if args.plot:
            print(f'plot: {args.plot}')
    return 1 if any(r.status == 'FAILED' for r in rows) else 0
