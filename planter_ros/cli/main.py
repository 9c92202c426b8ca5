"""Entry point of `planter`: builds the sub-command tree and turns any of planter_ros's errors
(`errors.PlanterError`: bad input, a setting, a bag or a drive refused) into exit code 2.

Each sub-command's module has `add_arguments(parser)` and `run(args) -> int` and imports numpy,
scipy, matplotlib or rclpy only inside run(): `planter --help` loads none of them."""

import argparse
import importlib
import sys

from planter_ros.errors import PlanterError

# (command words) -> (module, one-line help)
COMMANDS = {
    ('design', 'five-bar'): ('planter_ros.cli.design_five_bar',
                             'reverse-design a geared five-bar from depth and spacing'),
    ('bench',): ('planter_ros.cli.bench', 'run time next to error against an mpmath reference'),
    ('design', 'three-arm'): ('planter_ros.cli.design_three_arm',
                              'score a three-arm non-circular gear design against eight goals'),
    ('optimize', 'three-arm'): ('planter_ros.cli.optimize_three_arm',
                                'search a three-arm design meeting all eight goals'),
    ('demo',): ('planter_ros.cli.demo', 'run the whole machine on a simulated CAN bus'),
    ('replay',): ('planter_ros.cli.replay', 're-run the monitor\'s model on a recorded bag'),
    ('analyze',): ('planter_ros.cli.analyze',
                   'replay a season of bags on Dask into Parquet tables'),
    ('simulate',): ('planter_ros.cli.simulate',
                    'write a season of realistic simulated bags, fast'),
    ('cam', 'five-bar'): ('planter_ros.cli.cam', 'electronic cam: every spacing planted upright'),
    ('commission',): ('planter_ros.commission.command', 'home, polarity, phase: write the machine '
                      'file'),
    ('drive', 'check'): ('planter_ros.commission.drive_check', 'bring up drives: plan, SYNC, jog'),
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


def build_parser(argv=()):
    """The full command tree; only the selected sub-command's module is imported, so a run
    never loads the code (and the imports) of the commands it does not use."""
    from planter_ros.shipped import package_version
    selected = _selected(list(argv))
    parser = _Parser(prog='planter', description='Design and drive a transplanter planting unit.')
    parser.add_argument('--version', action='version', version=f'planter {package_version()}')
    top = parser.add_subparsers(dest='command', required=True, parser_class=_Parser)
    groups = {}
    for words, (module_name, help_text) in COMMANDS.items():
        if len(words) == 1:
            sub = top.add_parser(words[0], help=help_text)
        else:
            if words[0] not in groups:
                g = top.add_parser(words[0], help=GROUPS.get(words[0], f'{words[0]} a mechanism'))
                groups[words[0]] = g.add_subparsers(dest='mechanism', required=True)  # _Parser's
            sub = groups[words[0]].add_parser(words[1], help=help_text)
        if words == selected:
            module = importlib.import_module(module_name)
            module.add_arguments(sub)
            sub.set_defaults(_run=module.run)
    return parser


def main(argv=None):
    from planter_ros.config import one_line
    from planter_ros.dependencies import check_command, error_line
    argv = sys.argv[1:] if argv is None else list(argv)
    selected = _selected(argv)
    if selected == ('demo',):     # a stop signal from the very start is a clean stop (demo.run)
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
