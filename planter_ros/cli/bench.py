"""`planter bench`: run time next to error against an mpmath reference, as a table or JSON,
optionally also written as a markdown page (doc/benchmarks.md is made this way)."""

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
    parser.add_argument('--only', metavar='TEXT', action='append',
                        help='run only the cases whose name contains TEXT (e.g. "hole"); '
                             'repeated: those whose name contains any of them')
    parser.add_argument('--runs', metavar='N', type=spec_option(BenchContext, 'runs', '--runs'),
                        help='how many runs the cases made of whole demo runs make '
                             '(default: each case\'s own, 10)')
    parser.add_argument('--markdown', metavar='FILE.md', type=output_file('--markdown', ('.md',)),
                        help='also write the results as a markdown page to FILE (replaced '
                             'atomically): how it was made, the quality targets, one table '
                             'per row group')
