"""The one validation layer of command-line options: argparse `type=` adapters.

An option mirroring a configuration value (a scene's depth, ...) is checked against its
`config.Spec`, so the command line, scene files and ROS parameters accept the same values and
name the same range; output paths by `planter_ros.output_files`. Checks run while the arguments
are parsed, before any work, raising `BadInput` (one line: option, value, what is allowed)."""

import math

from planter_ros.cli.main import BadInput
from planter_ros.config import ConfigError, coerce, spec_of
from planter_ros.output_files import OutputError, check_output


def spec_option(cls, name, option):
    """argparse `type=` for `option`, checked against field `name` of config dataclass `cls`."""
    spec = spec_of(cls, name)

    def parse(text):
        def bad(why='is out of range'):
            raise BadInput(f'{option} = {shown(text)} {why}: allowed {spec.allowed()}')
        value = text
        if spec.kind is float:
            try:
                value = float(text)
            except ValueError:
                bad('is not a number')
            if not math.isfinite(value):
                bad()
        elif spec.kind is int:
            try:
                value = int(text, 10)
            except ValueError:
                bad('is not an integer')
        elif spec.kind is bool:
            value = {'true': True, 'false': False}.get(text.lower())
            if value is None:
                bad('is not true or false')
        try:
            return coerce(spec, value)
        except ConfigError:
            bad()
    parse.__name__ = spec.name
    return parse


def output_file(option, suffixes):
    """argparse `type=` for an output file (checked, not created: see output_files)."""
    def parse(text):
        try:
            return str(check_output(text, option, suffixes))
        except OutputError as exc:
            raise BadInput(str(exc)) from None
    return parse


def output_path(check, option):
    """argparse `type=` for an output a function checks: `check(text, option)` returns the
    path or raises OutputError (export.shapefile.check_path, export.isoxml.check_path)."""
    def parse(text):
        try:
            return str(check(text, option))
        except OutputError as exc:
            raise BadInput(str(exc)) from None
    return parse


def shown(text, limit=40):
    """A value as a one-line message shows it: control characters escaped, long text cut."""
    text = str(text)
    if len(text) > limit:
        text = text[:limit - 3] + '...'
    return text if text.isprintable() else repr(text)


def add_engine_arguments(parser):
    """--workers N | --scheduler ADDRESS: where `planter analyze` and `planter simulate` run
    (planter_ros.analysis.engine)."""
    # lazy: analysis.engine (asyncio) only for analyze and simulate, the commands with an
    # engine: a design loads no analysis (test_skip_what_a_scene_does_not_need)
    from planter_ros.analysis.engine import EngineSettings
    group = parser.add_mutually_exclusive_group()
    group.add_argument('--workers', metavar='N',
                       type=spec_option(EngineSettings, 'workers', '--workers'),
                       help='worker processes of the local cluster, 1..512 (default: one per '
                            'usable core)')
    group.add_argument('--scheduler', metavar='ADDRESS', type=_scheduler,
                       help="run on an existing Dask cluster instead: its scheduler's address, "
                            'e.g. tcp://host:8786 (workers read the bags from the same paths)')


def _scheduler(text):
    # lazy: as add_engine_arguments
    from planter_ros.analysis.engine import EngineError, scheduler_address
    try:
        return scheduler_address(text)
    except EngineError as exc:
        raise BadInput(str(exc)) from None
