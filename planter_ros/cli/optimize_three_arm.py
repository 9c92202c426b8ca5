"""`planter optimize three-arm`: search a three-arm design meeting all eight goals.

The base scene, the options and the output path are checked before the search starts; the scene
file is written atomically once the result is known to be a valid design, so a failed or
interrupted run never touches an existing --out. Without --out the scene goes to stdout (and the
report to stderr): `planter optimize three-arm > rice.yaml` leaves nothing else behind."""

from dataclasses import dataclass

from planter_ros.cli.options import output_file, spec_option
from planter_ros.config import check, setting

DEFAULT_WORKERS = 2


@dataclass(frozen=True)
class OptimizeOptions:
    """The search's own settings (the command-line options)."""

    seed: int = setting(1, 'random seed: same seed, same result', range=(0, 2 ** 32 - 1))
    max_time: float = setting(60.0, 'search time limit', unit='s', range=(0.01, 86400.0))
    workers: int = setting(DEFAULT_WORKERS, 'processes scoring each generation (same result '
                           'for any number)', range=(1, 64))

    def __post_init__(self):
        check(self)


def add_arguments(parser):
    parser.add_argument('--seed', type=spec_option(OptimizeOptions, 'seed', '--seed'), default=1,
                        help='random seed, 0..2^32-1 (same seed, same result; default 1)')
    parser.add_argument('--max-time', type=spec_option(OptimizeOptions, 'max_time',
                                                       '--max-time'),
                        default=60.0, metavar='S', help='stop after S seconds (default 60)')
    parser.add_argument('--workers', type=spec_option(OptimizeOptions, 'workers', '--workers'),
                        default=DEFAULT_WORKERS, metavar='N',
                        help='processes scoring each generation (same result for any N; '
                             f'default {DEFAULT_WORKERS})')
    parser.add_argument('--base', metavar='FILE', default=None,
                        help='scene whose crop values and control angles are kept (default '
                             'config/rice_three_arm.yaml)')
    parser.add_argument('--out', metavar='FILE.yaml', type=output_file('--out', ('.yaml', '.yml')),
                        help='parameter file to write, replaced atomically (default: the '
                             'scene on stdout, the report on stderr)')
