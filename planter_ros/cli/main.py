"""Entry point of `planter`: builds the sub-command tree and turns any of planter_ros's errors
(`errors.PlanterError`: bad input, a setting, a bag or a drive refused) into exit code 2.

A sub-command is two modules (COMMANDS): its options, `add_arguments(parser)`, light (argparse
and the option checks), and its work, `run(args) -> int`, which imports what it uses at its
top. `_load` is the one place that imports late: the options of the sub-command asked for only,
its work only once the arguments parsed (`--help` never loads it): `planter --help` loads no
sub-command, `planter replay --help` no numpy, mcap or rclpy."""

import argparse
from dataclasses import dataclass
import importlib
import sys
from types import ModuleType

from planter_ros.config import one_line
from planter_ros.dependencies import check_command, error_line
from planter_ros.errors import PlanterError
from planter_ros.shipped import package_version


@dataclass(frozen=True)
class Command:
    """A sub-command: the module of its options, the module of its work, its help line."""

    options: str
    work: str
    help: str


def _cli(name: str, help_text: str) -> Command:
    return Command(f'planter_ros.cli.{name}', f'planter_ros.cli.commands.{name}', help_text)


COMMANDS = {
    ('design', 'five-bar'): _cli('design_five_bar',
                                 'reverse-design a geared five-bar from depth and spacing'),
    ('bench',): _cli('bench', 'run time next to error against an mpmath reference'),
    ('design', 'three-arm'): _cli('design_three_arm', 'score a three-arm non-circular gear '
                                  'design against eight goals'),
    ('optimize', 'three-arm'): _cli('optimize_three_arm',
                                    'search a three-arm design meeting all eight goals'),
    ('demo',): _cli('demo', 'run the whole machine on a simulated CAN bus'),
    ('replay',): _cli('replay', 're-run the monitor\'s model on a recorded bag'),
    ('analyze',): _cli('analyze', 'replay a season of bags on Dask into Parquet tables'),
    ('simulate',): _cli('simulate', 'write a season of realistic simulated bags, fast'),
    ('cam', 'five-bar'): _cli('cam', 'electronic cam: every spacing planted upright'),
    ('commission',): Command('planter_ros.cli.commission', 'planter_ros.commission.command',
                             'home, polarity, phase: write the machine file'),
    ('drive', 'check'): Command('planter_ros.cli.drive_check',
                                'planter_ros.commission.drive_check',
                                'bring up drives: plan, SYNC, jog'),
}
GROUPS = {'drive': 'check the CANopen drives of a machine file'}    # others: a mechanism's

EXIT_BAD_INPUT = 2


class BadInput(PlanterError):
    """A user error the command line reports as one line with exit code 2."""


class _Parser(argparse.ArgumentParser):
    """argparse that reports errors in one line (no usage dump, no traceback) and takes no
    abbreviated option (`--dur` for `--duration` would change meaning when an option is added)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **{**kwargs, 'allow_abbrev': False})

    def error(self, message):
        # main() prints 'planter: error: ': name only the sub-command after it
        where = self.prog.partition(' ')[2]
        raise BadInput(f'{where}: {message}' if where else message)

    def _get_values(self, action, arg_strings):
        # Python 3.11's argparse drops a '--' given as an option's value (`--seed=--`) and
        # hands the option an empty list instead of calling its type check: refuse it here
        if action.option_strings and action.nargs is None and arg_strings == ['--']:
            raise BadInput(f'{self.prog}: argument {action.option_strings[0]}: expected one '
                           'value, got --')
        return super()._get_values(action, arg_strings)


def _selected(argv):
    """The COMMANDS key the arguments name, if any (only its module gets imported)."""
    words = tuple(a for a in argv[:2] if not a.startswith('-'))
    for key in COMMANDS:
        if words[:len(key)] == key:
            return key
    return None


def _load(name: str) -> ModuleType:
    """A sub-command's module, imported when that sub-command is asked for (module doc)."""
    # lazy: the one late import of the command line: only the sub-command asked for is loaded
    # (its options for --help; its work, with numpy, mcap, rclpy or canopen, for a run):
    # test_help_opens_nothing, test_skip_what_a_scene_does_not_need
    return importlib.import_module(name)


def _work(name: str):
    """`args._run`: loads the sub-command's work module, then runs it."""
    def run(args: argparse.Namespace) -> int:
        return _load(name).run(args)
    return run


def build_parser(argv=()):
    """The full command tree; only the selected sub-command's options module is imported, so a
    run never loads the code (and the imports) of the commands it does not use."""
    selected = _selected(list(argv))
    parser = _Parser(prog='planter', description='Design and drive a transplanter planting unit.')
    parser.add_argument('--version', action='version', version=f'planter {package_version()}')
    top = parser.add_subparsers(dest='command', required=True, parser_class=_Parser)
    groups = {}
    for words, command in COMMANDS.items():
        if len(words) == 1:
            sub = top.add_parser(words[0], help=command.help)
        else:
            if words[0] not in groups:
                g = top.add_parser(words[0], help=GROUPS.get(words[0], f'{words[0]} a mechanism'))
                groups[words[0]] = g.add_subparsers(dest='mechanism', required=True)  # _Parser's
            sub = groups[words[0]].add_parser(words[1], help=command.help)
        if words == selected:
            _load(command.options).add_arguments(sub)
            sub.set_defaults(_run=_work(command.work))
    return parser


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    selected = _selected(argv)
    if selected == ('demo',):     # a stop signal from the very start is a clean stop (demo.run)
        # lazy: only the demo installs them; host.stop_signals and signal cost every other
        # command 1.2 ms (-X importtime)
        from planter_ros.host import stop_signals
        stop_signals.install('planter demo')
    try:
        args = build_parser(argv).parse_args(argv)
        check_command(selected, args)
        return int(args._run(args) or 0)
    except (PlanterError, ModuleNotFoundError) as exc:     # ModuleNotFoundError: an extra's
        print(f'planter: error: {one_line(error_line(selected, exc))}', file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print('planter: interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())
