"""The error root (planter_ros.errors): every exception class planter_ros defines is a
PlanterError, beside the builtin base its callers catch; the one place SDO failures become drive
errors (drive.errors.sdo_error), held to canopen's own abort-code table; the facts an error
carries (where, value, limit; a drive's node, object and abort code) survive pickling, so an
error raised in a worker process reaches its parent whole."""
import ast
import builtins
import importlib
import pickle
from types import SimpleNamespace

import can
from canopen.sdo import SdoAbortedError, SdoCommunicationError
import pytest

from cli_helpers import REPO
from planter_ros.config import ConfigError
from planter_ros.drive import objects as od
from planter_ros.drive.config import DriveConfig
from planter_ros.drive.errors import (NO_SUCH_OBJECT, BusError, DictionaryError, DriveError,
                                      DriveRefusedError, DriveTimeoutError, SdoTransfer,
                                      sdo_error)
from planter_ros.drive.sdo import Sdo
from planter_ros.errors import PlanterError

PACKAGE = REPO / 'planter_ros'
BUILTIN_EXCEPTIONS = {name for name, value in vars(builtins).items()
                      if isinstance(value, type) and issubclass(value, BaseException)}


def _module_name(path):
    parts = path.relative_to(REPO).with_suffix('').parts
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def _class_defs():
    """(module name, ClassDef, is at module level) of every class planter_ros's sources define."""
    for path in sorted(PACKAGE.rglob('*.py')):
        tree = ast.parse(path.read_text(), str(path))
        top = {id(node) for node in tree.body}
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                yield _module_name(path), node, id(node) in top


def _base_names(node):
    return {ast.unparse(base).rpartition('.')[2] for base in node.bases}


def exception_classes():
    """{(module, name): class} of every exception class defined in planter_ros, found by walking
    every module's source (not a hand list): a class whose base is a builtin exception, a
    foreign one (a name ending in Error/Exception/Warning) or one of these, to a fixed point;
    then each module imported and each class checked to be a BaseException."""
    defs = list(_class_defs())
    known = set(BUILTIN_EXCEPTIONS)
    while True:
        found = {node.name for _, node, _ in defs if _base_names(node) & known
                 or any(b.endswith(('Error', 'Exception', 'Warning')) for b in _base_names(node))}
        if found <= known:
            break
        known |= found
    out = {}
    for module, node, at_top in defs:
        if node.name not in known or node.name in BUILTIN_EXCEPTIONS:
            continue
        assert at_top, f'{module}.{node.name}: define an exception class at module level'
        cls = getattr(importlib.import_module(module), node.name)
        if isinstance(cls, type) and issubclass(cls, BaseException):
            out[(module, node.name)] = cls
    return out


# helper exceptions that never leave their module (raised and caught inside it)
PRIVATE = {('planter_ros.safe_yaml', '_Refused')}


def test_every_exception_class_of_the_package_is_a_planter_error():
    classes = exception_classes()
    # the walk finds the families and the loners (a walk that finds nothing cannot pass)
    for module, name in (('planter_ros.config', 'ConfigError'),
                         ('planter_ros.drive.errors', 'DictionaryError'),
                         ('planter_ros.recording.errors', 'BagDamagedError'),
                         ('planter_ros.command.channel', 'ChannelClosed'),
                         ('planter_ros.cli.main', 'BadInput'),
                         ('planter_ros.dependencies', 'MissingExtra'),
                         ('planter_ros.analysis.task', 'WorkerMismatch')):
        assert (module, name) in classes
    assert len(classes) >= 40
    outside = sorted(f'{m}.{n}' for (m, n), cls in classes.items()
                     if not issubclass(cls, PlanterError) and (m, n) not in PRIVATE)
    assert outside == [], 'derive these from planter_ros.errors.PlanterError'


def test_a_private_helper_exception_never_leaves_its_module():
    for module, name in PRIVATE:
        users = [p.relative_to(REPO) for p in PACKAGE.rglob('*.py')
                 if name in p.read_text() and _module_name(p) != module]
        assert users == []
        assert name.startswith('_')


def test_each_keeps_the_builtin_base_its_callers_catch():
    """The root is added beside the old base: every `except ValueError` (RuntimeError,
    ConnectionError) written before it still catches the same errors."""
    from planter_ros.command.channel import ChannelClosed
    from planter_ros.kinematics.errors import DesignError
    from planter_ros.output_files import OutputError
    from planter_ros.safe_yaml import YamlError
    for cls in (ConfigError, DesignError, OutputError, YamlError, DictionaryError):
        assert issubclass(cls, ValueError), cls
    for cls in (DriveError, DriveTimeoutError, BusError):
        assert issubclass(cls, RuntimeError), cls
    assert issubclass(ChannelClosed, ConnectionError)
    assert issubclass(DictionaryError, DriveError) and issubclass(DictionaryError, ConfigError)
    with pytest.raises(ValueError):
        raise DesignError('plant_spacing', 0.5, '0.05..0.4 m')


def _mapped(exc, verb='reading'):
    return sdo_error(exc, SdoTransfer(node=5, step='identify (SDO 0x1000 device type)',
                                      verb=verb, index=0x6502, subindex=0,
                                      name='supported drive modes', waited=' within 2 x 0.1 s',
                                      bus='virtual:ch'))


def test_the_abort_codes_the_mapping_names_are_canopens_no_such_object_codes():
    texts = {code: SdoAbortedError.CODES[code].lower() for code in NO_SUCH_OBJECT}
    assert texts == {0x06020000: 'object does not exist', 0x06090011: 'subindex does not exist'}
    # and no other code of canopen's table says an entry does not exist
    assert {c for c, t in SdoAbortedError.CODES.items() if 'not exist' in t} == set(NO_SUCH_OBJECT)


@pytest.mark.parametrize('code', sorted(SdoAbortedError.CODES) + [0x12345678],
                         ids=lambda code: f'0x{code:08X}')
def test_every_abort_code_maps_to_the_drive_error_it_means(code):
    error = _mapped(SdoAbortedError(code))
    expected = DictionaryError if code in NO_SUCH_OBJECT else DriveRefusedError
    assert type(error) is expected
    assert (error.node, error.index, error.subindex, error.abort_code) == (5, 0x6502, 0, code)
    text = str(error)
    assert '\n' not in text and text.startswith('drive node 5: identify (SDO 0x1000 device')
    assert f'0x{code:08X}' in text and SdoAbortedError.CODES.get(code, '') in text
    assert '0x6502' in text


def test_no_answer_is_a_timeout_and_a_failed_send_a_bus_error():
    timeout = _mapped(SdoCommunicationError('No SDO response received'))
    assert type(timeout) is DriveTimeoutError and timeout.abort_code is None
    assert 'no SDO answer reading 0x6502 within 2 x 0.1 s (is the drive on virtual:ch as node 5' \
        in str(timeout)
    assert 'is the drive on' not in str(_mapped(SdoCommunicationError('x'), verb='writing'))
    for exc in (can.CanOperationError('tx buffer full'), OSError(105, 'No buffer space')):
        error = _mapped(exc, verb='writing')
        assert type(error) is BusError and error.node == 5
        assert f'CAN send failed: {type(exc).__name__}' in str(error)


def test_the_master_s_sdo_reads_and_writes_map_through_the_one_function():
    """Sdo (the master's SDO access) raises what sdo_error says, with the object it asked."""
    def fails(exc):
        def call(*_args):
            raise exc
        return call
    config = DriveConfig(can_interface='virtual', can_channel='ch', drive_node_id=5)
    node = SimpleNamespace(sdo=SimpleNamespace(upload=fails(SdoAbortedError(0x06090011)),
                                               download=fails(SdoAbortedError(0x06090030))))
    sdo = Sdo(node, config)
    with pytest.raises(DictionaryError) as missing:
        sdo.read('step', od.MODES_DISPLAY)
    assert (missing.value.index, missing.value.abort_code) == (od.MODES_DISPLAY.index, 0x06090011)
    assert sdo.read('step', od.MODES_DISPLAY, optional=True) is None
    with pytest.raises(DriveRefusedError) as refused:
        sdo.write('step', od.MODES_OF_OPERATION, 8)
    assert refused.value.abort_code == 0x06090030 and refused.value.node == 5


def test_the_mapping_is_written_once():
    """No other module of planter_ros turns canopen's SDO exceptions into drive errors: only
    drive/errors.py reads an abort's code or names SdoCommunicationError (the simulated drive
    raises aborts, as a device does; drive/sdo.py lets an optional read's abort through)."""
    readers = sorted(str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob('*.py')
                     if 'SdoCommunicationError' in p.read_text() or 'exc.code' in p.read_text())
    assert readers == ['drive/errors.py']


def test_the_facts_survive_pickling():
    from planter_ros.command.channel import ChannelClosed
    from planter_ros.dependencies import MissingExtra
    from planter_ros.kinematics.errors import DesignError
    from planter_ros.recording.errors import BagDamagedError

    def again(error):
        back = pickle.loads(pickle.dumps(error))
        assert type(back) is type(error) and str(back) == str(error)
        return back
    root = again(PlanterError('--speed = 3 is out of range: allowed 0..2 m/s', where='--speed',
                              value=3.0, limit='0..2 m/s'))
    assert (root.where, root.value, root.limit) == ('--speed', 3.0, '0..2 m/s')
    assert PlanterError('no facts').where is None
    design = again(DesignError('plant_spacing', 0.5, '0.05..0.4 m', 'too wide'))
    assert (design.parameter, design.value, design.allowed) == ('plant_spacing', 0.5,
                                                               '0.05..0.4 m')
    assert (design.where, design.limit) == ('plant_spacing', '0.05..0.4 m')
    extra = again(MissingExtra('planter replay --plot', 'analysis', ['matplotlib']))
    assert (extra.what, extra.extra, extra.missing) == ('planter replay --plot', 'analysis',
                                                        ['matplotlib'])
    damaged = again(BagDamagedError('chunk CRC mismatch', at=4096))
    assert (damaged.reason, damaged.at) == ('chunk CRC mismatch', 4096)
    drive = again(_mapped(SdoAbortedError(0x06020000)))
    assert (drive.node, drive.index, drive.abort_code) == (5, 0x6502, 0x06020000)
    closed = again(ChannelClosed('the command process is gone'))
    assert isinstance(closed, ConnectionError)


@pytest.mark.parametrize('error', [
    DriveTimeoutError('drive node 5: identify: no SDO answer reading 0x1000'),
    ConfigError('plant_spacing = 9 is out of range: allowed 0.05..0.6 m'),
    PlanterError('line one\nline two')], ids=lambda e: type(e).__name__)
def test_the_command_line_turns_any_planter_error_into_one_line_and_exit_2(monkeypatch, capsys,
                                                                           error):
    from planter_ros.cli import main as cli

    def run(_args):
        raise error
    parser = SimpleNamespace(parse_args=lambda argv: SimpleNamespace(_run=run))
    monkeypatch.setattr(cli, 'build_parser', lambda argv: parser)
    assert cli.main(['bench']) == cli.EXIT_BAD_INPUT == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and err.startswith('planter: error: ' + str(error)[:8])
