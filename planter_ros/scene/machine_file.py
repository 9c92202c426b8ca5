"""The machine file: one per tractor and planter, apart from the crop's scene.

What a scene cannot know because it belongs to the iron: the CAN bus (channel, bit rate) and per
planting unit (row) its drive's node id, where its planting point sits from the GNSS antenna
(the lever arm), the drive train (gear ratio, encoder counts, polarity), how it is homed and at
which shaft angle it plants (phase offset), the drive's limits and the CiA 402 modes it
supports. `config/machine_example.yaml` is a complete example; doc/machine_file.md the table.

Read strictly, like a scene: the file is bounded YAML (safe_yaml), every key must be one of the
file's (an unknown one is refused naming the closest: "did you mean `gear_ratio`?"), every value
is checked against its declaration below (config.setting: type, finite, unit, range, choices),
node ids are unique and row names are the scene's row names. A refusal is one line naming the
file and the key (MachineFileError, a SceneError: the command line's exit 2).

Frames: the lever arms are in the machine's frame (REP 103: x forward, y left) from the GNSS
antenna's phase centre to the row's planting point (the nozzle tip at the bottom of its path):
`longitudinal_offset` + forward (a planting point behind the antenna is negative),
`lateral_offset` + left. The machine's reference point is the antenna, so a scene run with a
machine file has `antenna_position` [0, 0] and each row's offsets from the antenna.
Pure: no ROS, no bus.
"""

from collections.abc import Sequence
from dataclasses import dataclass, fields
import dataclasses
import math
import os
from pathlib import Path
import re
import sys
from typing import Any

import yaml

from planter_ros.config import (
    ConfigError, Spec, check, choice, from_mapping, name_list, setting, specs)
from planter_ros.drive.config import DriveConfig
from planter_ros.drive.plan import plan_for_file
from planter_ros.drive.setup import HOMING_ALLOWED, DriveSetup, homing_method_ok
from planter_ros.plausibility import (STANDARD_BITRATES, PlausibilityError, RowLimits,
                                      check as check_plausibility)
from planter_ros.rows import RowLayout
from planter_ros.safe_yaml import YamlError, load_yaml

from . import open_scene
from .files import SceneError, read_small_yaml
from .machine_setting import MachineFileSetting
from .schema import NODES, closest, node_parameters

__all__ = ['CanBus', 'IsobusBus', 'Machine', 'MachineFileError', 'MachineFileSetting',
           'MachineRow', 'SECTIONS',
           'check_drive_plans', 'deployment_parameters', 'machine_text', 'open_machine',
           'parse_machine', 'rows_asked',
           'write_machine']

RPM = 2.0 * math.pi / 60.0
_INTERFACE_NAME = re.compile(r'[A-Za-z0-9_.-]{1,15}\Z')     # a Linux network interface name
MODES = ('csp', 'pv')              # CiA 402 cyclic synchronous position (8), profile velocity (3)
POLARITIES = ('normal', 'reversed')
ISOBUS_BITRATE = 250_000          # ISO 11783-2


class MachineFileError(SceneError):
    """A machine file that cannot be used; one line naming the file and the key."""


@dataclass(frozen=True)
class CanBus:
    """The CAN bus of the planting units' drives (the `can` block)."""

    interface: str = setting('socketcan', "python-can interface ('socketcan' on the machine)")
    channel: str = setting('can0', 'SocketCAN network interface of the drives')
    bitrate: int = setting(500_000, 'bit rate the interface is brought up at (the systemd unit '
                           'reads it) and the drives are set to', unit='bit/s',
                           range=(10_000, 1_000_000))

    def __post_init__(self) -> None:
        check(self)
        if not self.interface or not _INTERFACE_NAME.match(self.channel):
            raise ConfigError(f'channel = {self.channel!r} is out of range: allowed a network '
                              'interface name (1..15 letters, digits, _ . -)')
        if self.bitrate not in STANDARD_BITRATES:
            raise ConfigError(f'bitrate = {self.bitrate} is out of range: allowed a CiA 301 bit '
                              'rate (the drives support no other): '
                              + ', '.join(str(b) for b in STANDARD_BITRATES) + ' bit/s')


@dataclass(frozen=True)
class IsobusBus:
    """The tractor's ISOBUS (the `isobus` block): ground speed from its speed messages."""

    channel: str = setting('', "SocketCAN network interface of the tractor's ISOBUS (e.g. "
                           'can1); empty: none (ground speed from GNSS or pulses)')
    bitrate: int = setting(250_000, 'ISOBUS bit rate (ISO 11783-2: 250 kbit/s)', unit='bit/s',
                           range=(10_000, 1_000_000))

    def __post_init__(self) -> None:
        check(self)
        if self.channel and not _INTERFACE_NAME.match(self.channel):
            raise ConfigError(f'channel = {self.channel!r} is out of range: allowed a network '
                              'interface name (1..15 letters, digits, _ . -) or empty')
        if self.bitrate != ISOBUS_BITRATE:
            raise ConfigError(f'bitrate = {self.bitrate} is out of range: allowed '
                              f'{ISOBUS_BITRATE} bit/s (ISO 11783-2: every ISOBUS runs at it)')


@dataclass(frozen=True, kw_only=True)
class MachineRow:
    """One planting unit (a block under `rows`, named like the scene's row)."""

    node_id: int = setting(kind=int, description="CANopen node id of the row's drive",
                           range=(1, 127))
    lateral_offset: float = setting(kind=float, description='planting point from the GNSS '
                                    'antenna, + left (REP 103)', unit='m', range=(-20.0, 20.0))
    longitudinal_offset: float = setting(kind=float, description='planting point from the GNSS '
                                         'antenna, + forward (behind the antenna: negative)',
                                         unit='m', range=(-50.0, 50.0))
    gear_ratio: float = setting(kind=float, description='motor turns per mechanism (sun bar or '
                                'carrier) turn', range=(0.01, 1000.0))
    encoder_counts: int = setting(kind=int, description='encoder counts per motor turn (0x6064 '
                                  'units)', range=(1, 1 << 24))
    polarity: str = choice('normal', 'motor turning direction for a forward mechanism turn: '
                           'normal, or reversed (0x607E bits 6 and 7 set)', POLARITIES)
    homing_method: int = setting(0, 'CiA 402 homing method (0x6098): 0 none (the position at '
                                 'enable is zero), 1..14, 17..30, 33..35, 37 the standard '
                                 'methods (e.g. 33/34 the index pulse, 35/37 the current '
                                 "position), negative: the drive maker's", range=(-128, 127))
    phase_offset: float = setting(0.0, 'mechanism angle after homing at which the tip is at '
                                  'the bottom of its path (a planting instant)', unit='rad',
                                  range=(0.0, 2.0 * math.pi))
    max_motor_speed: float = setting(kind=float, description="the drive's speed limit at the "
                                     'motor (0x607F; no servo of a planting unit turns faster '
                                     'than about 10 000 r/min)', unit='rad/s',
                                     range=(0.1, 1100.0))
    max_motor_acceleration: float = setting(kind=float, description="the drive's acceleration "
                                            'limit at the motor (0x60C5)', unit='rad/s²',
                                            range=(0.1, 1e7))
    max_torque: float = setting(kind=float, description="the drive's torque limit at the motor "
                                '(0x6072 in N·m)', unit='N·m', range=(0.001, 1e4))
    modes: list[str] = name_list(['pv'], 'CiA 402 modes the drive supports (0x6502): csp '
                                 '(cyclic synchronous position, 8), pv (profile velocity, 3)')
    vendor_id: int = setting(-1, 'vendor-ID the drive must report (0x1018:1), checked before '
                             'enabling; -1: not checked (commissioning writes what it found)',
                             range=(-1, 0xFFFF_FFFF))
    product_code: int = setting(-1, 'product code the drive must report (0x1018:2); -1: not '
                                'checked', range=(-1, 0xFFFF_FFFF))
    revision: int = setting(-1, 'revision number the drive must report (0x1018:3); -1: not '
                            'checked', range=(-1, 0xFFFF_FFFF))
    eds: str = setting('', "the drive maker's EDS or DCF file (relative to the machine file): "
                       'every object the master uses must be in it with its type (checked '
                       'before enabling) and the master uses it; empty: config/planter_drive.eds')

    def __post_init__(self) -> None:
        check(self)
        bad = [m for m in self.modes if m not in MODES]
        if bad or not self.modes or len(set(self.modes)) != len(self.modes):
            raise ConfigError(f'modes = {self.modes} is out of range: allowed a list of '
                              f'{" and ".join(MODES)}, each once, at least one')
        if not homing_method_ok(self.homing_method):
            raise ConfigError(f'homing_method = {self.homing_method} is out of range: allowed '
                              f'{HOMING_ALLOWED}')

    @property
    def max_speed(self) -> float:
        """The mechanism's speed limit (rad/s): the motor's over the gear ratio."""
        return self.max_motor_speed / self.gear_ratio

    @property
    def max_acceleration(self) -> float:
        """The mechanism's acceleration limit (rad/s²)."""
        return self.max_motor_acceleration / self.gear_ratio


# the file's blocks: name -> (class, one line for people); `rows` maps a row name to a block
SECTIONS = {'can': (CanBus, 'the drives\' CAN bus'),
            'isobus': (IsobusBus, "the tractor's ISOBUS"),
            'rows': (MachineRow, 'one block per planting unit, named like the scene\'s rows')}
TOP_KEYS = ('machine', *SECTIONS)


@dataclass(frozen=True)
class Machine:
    """A checked machine file."""

    path: Path | None
    name: str
    can: CanBus
    rows: dict[str, MachineRow]
    isobus: IsobusBus = IsobusBus()

    def ip_commands(self) -> list[list[str]]:
        """The `ip` commands that bring the machine's SocketCAN interfaces up at their bit
        rates (the systemd unit planter-can.service runs them; restart-ms: a bus-off interface
        restarts by itself after 100 ms)."""
        out = []
        buses = [(self.can.channel, self.can.bitrate)]
        if self.isobus.channel:
            buses.append((self.isobus.channel, self.isobus.bitrate))
        for channel, bitrate in buses:
            out += [['ip', 'link', 'set', channel, 'down'],
                    ['ip', 'link', 'set', channel, 'type', 'can', 'bitrate', str(bitrate),
                     'restart-ms', '100'],
                    ['ip', 'link', 'set', channel, 'up']]
        return out

    def node_parameters(self) -> dict[str, dict[str, Any]]:
        """{node: the parameters the machine file sets for it}: the scene nodes' own share of
        `scene_parameters()` (a node is given only what it declares), ground_speed_node's
        ISOBUS channel."""
        params = self.scene_parameters()
        out = {node: dict(node_parameters(node, params)) for node in NODES}
        out['ground_speed_node'] = {'isobus_channel': self.isobus.channel}
        if self.path is not None:
            out['sync_node']['machine_file'] = str(self.path)
        return out

    def drive_setups(self) -> dict[str, Any]:
        """{row: drive.setup.DriveSetup}: what the master checks and applies at every start
        (identity, modes, EDS, polarity, homing, phase offset, gear ratio, encoder counts)."""
        return {name: DriveSetup(
                    modes=tuple(row.modes), polarity=row.polarity,
                    homing_method=row.homing_method, phase_offset=row.phase_offset,
                    vendor_id=row.vendor_id, product_code=row.product_code,
                    revision=row.revision, eds=str(self.eds_path(row)) if row.eds else '',
                    gear_ratio=row.gear_ratio, encoder_counts=row.encoder_counts)
                for name, row in self.rows.items()}

    def eds_path(self, row: MachineRow) -> Path:
        """A row's EDS as a path (relative to the machine file's directory)."""
        base = self.path.parent if self.path is not None else Path('.')
        return base / row.eds

    def row_limits(self) -> list:
        """Each row's limits at the mechanism's shaft for planter_ros.plausibility."""
        return [RowLimits(name, max_acceleration=row.max_acceleration,
                          motor_max_speed=row.max_motor_speed, gear_ratio=row.gear_ratio,
                          encoder_counts=row.encoder_counts)
                for name, row in self.rows.items()]

    def scene_parameters(self) -> dict[str, Any]:
        """The scene parameters the machine file sets (flat, as a parameter file's `/**`): the
        bus, the rows and their node ids and lever arms, the antenna as the reference point.
        Drive-train values shared by every row (gear ratio, encoder counts) too; rows that
        differ keep theirs in the machine file (the command process reads it)."""
        out: dict[str, Any] = {'can_interface': self.can.interface,
                               'can_channel': self.can.channel,
                               'can_bitrate': self.can.bitrate,
                               'antenna_position': [0.0, 0.0], 'rows': list(self.rows)}
        for name, row in self.rows.items():
            out[f'{name}.lateral_offset'] = row.lateral_offset
            out[f'{name}.longitudinal_offset'] = row.longitudinal_offset
            out[f'{name}.drive_node_id'] = row.node_id
        for key, attr in (('motor_gear_ratio', 'gear_ratio'),
                          ('counts_per_motor_rev', 'encoder_counts')):
            values = {getattr(row, attr) for row in self.rows.values()}
            if len(values) == 1:
                out[key] = values.pop()
        return out


def open_machine(path: str | Path) -> Machine:
    """Read and check a machine file; MachineFileError (one line) for anything wrong."""
    path = Path(path)
    text = read_small_yaml(path, 'machine file', MachineFileError)
    return parse_machine(text, path)


def parse_machine(text: str, path: Path | None = None) -> Machine:
    """A machine file's text checked (see the module doc)."""
    where = f'machine file {path}' if path is not None else 'machine file'
    try:
        data = load_yaml(text, where)
    except YamlError as exc:
        raise MachineFileError(str(exc)) from None

    def bad(key: str, why: str) -> None:
        raise MachineFileError(f'{where}: {key} {why}')

    if not isinstance(data, dict):
        bad('(top level)', 'is not a mapping: allowed the keys ' + ', '.join(TOP_KEYS))
    _known(data, TOP_KEYS, '', where)
    name = data.get('machine', '')
    if not isinstance(name, str):
        bad('machine', f'= {name!r} is out of range: allowed a name (text)')
    can = _block(data.get('can', {}), CanBus, 'can', where)
    isobus = _block(data.get('isobus', {}), IsobusBus, 'isobus', where)
    rows_data = data.get('rows')
    if not isinstance(rows_data, dict) or not rows_data:
        bad('rows', 'is missing or empty: allowed one block per planting unit')
    try:
        RowLayout(rows=[str(r) for r in rows_data])
    except ConfigError as exc:
        bad('rows', f'has a bad name: {exc}')
    rows: dict[str, MachineRow] = {}
    owner: dict[int, object] = {}       # node id -> the row that has it
    for row_name, block in rows_data.items():
        row = _block(block, MachineRow, f'rows.{row_name}', where)
        if row.node_id in owner:
            bad(f'rows.{row_name}.node_id', f'= {row.node_id} is also row {owner[row.node_id]}'
                "'s: allowed a node id no other row uses")
        owner[row.node_id] = row_name
        rows[str(row_name)] = row
    if isobus.channel and isobus.channel == can.channel:
        bad('isobus.channel', f'= {isobus.channel!r} is the drives\' bus (can.channel): '
            'allowed the tractor\'s own CAN interface (another channel) or empty')
    machine = Machine(path, name, can, rows, isobus)
    for row_name, row in rows.items():
        if row.eds and not machine.eds_path(row).is_file():
            bad(f'rows.{row_name}.eds', f'= {row.eds!r} is not a file ('
                f'{machine.eds_path(row)}): allowed the drive\'s EDS or DCF file')
    check_drive_plans(machine, {}, where)
    return machine


def rows_asked(machine: Machine, asked: list[str] | None, path: str) -> list[str]:
    """The rows a command was asked for with --row (every row of the machine file when none);
    MachineFileError (one line) naming the first that is not a row of the file at `path`."""
    rows = asked or list(machine.rows)
    unknown = [r for r in rows if r not in machine.rows]
    if unknown:
        raise MachineFileError(f'--row {unknown[0]} is not a row of {path}: allowed '
                               + ', '.join(machine.rows))
    return rows


def check_drive_plans(machine: Machine, params: dict[str, Any], where: str) -> list[str]:
    """Each row's start-up plan made from its drive's EDS (drive.plan, the one the start
    carries out), with the drive settings in `params` (a scene's): refused before anything
    moves in one line naming the row, node, object, purpose and remedy (MachineFileError).
    A row without its own EDS uses config/planter_drive.eds, which serves every mode. Returns
    the plans' warnings, one line each, naming the row."""
    names = {f.name for f in fields(DriveConfig)}
    settings = {key: value for key, value in params.items() if key in names}
    warnings = []
    for name, row in machine.rows.items():
        if not row.eds:
            continue
        who = f'row {name}, drive node {row.node_id}'
        try:
            config = DriveConfig(**{**settings, 'can_bitrate': machine.can.bitrate,
                                    'drive_node_id': row.node_id,
                                    'motor_gear_ratio': row.gear_ratio,
                                    'counts_per_motor_rev': row.encoder_counts})
            plan = plan_for_file(str(machine.eds_path(row)), config,
                                 machine.drive_setups()[name], who)
        except ConfigError as exc:         # a DictionaryError too
            text = str(exc)
            raise MachineFileError(f'{where}: {text if text.startswith(who) else f"{who}: {text}"}'
                                   ) from None
        warnings += [f'{who}: {text}' for text in plan.warnings]
    return warnings


def rebased(machine: Machine, path: Path) -> Machine:
    """`machine` as a file at `path` says it: each row's relative `eds` rewritten relative to
    the new file's directory, so it names the same EDS file wherever the machine file goes."""
    if machine.path is None or machine.path.parent.resolve() == path.parent.resolve():
        return machine
    rows = {}
    for name, row in machine.rows.items():
        if row.eds and not Path(row.eds).is_absolute():
            target = (machine.path.parent / row.eds).resolve()
            row = dataclasses.replace(row, eds=os.path.relpath(target, path.parent.resolve()))
        rows[name] = row
    return dataclasses.replace(machine, rows=rows)


def machine_text(machine: Machine, comment: str = '') -> str:
    """The machine file's text for `machine` (every key written; `comment` as # lines on top);
    parse_machine reads it back to an equal Machine."""
    data: dict[str, Any] = {'machine': machine.name}
    for section, block in (('can', machine.can), ('isobus', machine.isobus)):
        data[section] = {spec.name: getattr(block, spec.name) for spec in specs(type(block))}
    data['rows'] = {name: {spec.name: getattr(row, spec.name) for spec in specs(MachineRow)}
                    for name, row in machine.rows.items()}
    head = ''.join(f'# {line}\n' for line in comment.splitlines()) if comment else ''
    return head + yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)


def write_machine(machine: Machine, path: str | Path, comment: str = '') -> None:
    """Write `machine` to `path` (checked by reading it back strictly first, then replaced in
    one rename: a reader never sees half a file). MachineFileError (one line) on failure."""
    path = Path(path)
    machine = rebased(machine, path)
    text = machine_text(machine, comment)
    if parse_machine(text, path) != Machine(path, machine.name, machine.can, machine.rows,
                                            machine.isobus):
        raise MachineFileError(f'machine file {path}: would not read back as written')
    tmp = path.with_name(f'.{path.name}.tmp')
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise MachineFileError(f'machine file {path} cannot be written: '
                               f'{str(exc).splitlines()[0]}') from None


def _known(mapping: dict, allowed: Sequence[str], prefix: str, where: str) -> None:
    for key in mapping:
        if key not in allowed:
            raise MachineFileError(f'{where}: {prefix}{key} is not a machine-file key: did you '
                                   f'mean `{prefix}{closest(str(key), allowed)}`?')


def _block(block: object, cls: type, prefix: str, where: str) -> Any:
    """A block of the file as `cls`; its keys known, its values in range."""
    names = [spec.name for spec in specs(cls)]
    if not isinstance(block, dict):
        raise MachineFileError(f'{where}: {prefix} is not a mapping: allowed the keys '
                               + ', '.join(names))
    _known(block, names, f'{prefix}.', where)
    try:
        return from_mapping(cls, block, strict=True, prefix=f'{prefix}.')
    except ConfigError as exc:
        text = str(exc)
        raise MachineFileError(f'{where}: '
                               f'{text if text.startswith(prefix) else f"{prefix}.{text}"}') \
            from None


def field_table() -> list[tuple[str, Spec]]:
    """(key as written in the file, its Spec) of every machine-file key, for the doc table."""
    out = []
    for section, (cls, _) in SECTIONS.items():
        key = f'{section}.<row>' if section == 'rows' else section
        out += [(f'{key}.{spec.name}', spec) for spec in specs(cls)]
    return out


def deployment_parameters(machine_path: str | Path, scene_path: str | Path,
                          overrides: dict[str, dict[str, Any]] | None = None
                          ) -> tuple[dict[str, dict[str, Any]], list[str]]:
    """({node: parameters}, warnings): what a launch file gives each node on top of the scene
    file, the machine file's share (`Machine.node_parameters`) and `overrides` (a launch
    argument's, by node), and the scene's unusual values.
    Checked first, as the nodes would (SceneError, one line): both files strict, the scene's
    rows (if it names any) the machine's, and the scene plausible on this machine with its
    drives' limits (planter_ros.plausibility)."""
    machine = open_machine(machine_path)
    scene = open_scene(scene_path)
    rows = scene.parameters('sync_node').get('rows') or []
    if rows and list(rows) != list(machine.rows):
        raise MachineFileError(f'scene {scene_path} names the rows {", ".join(rows)}, machine '
                               f'file {machine_path} has {", ".join(machine.rows)}: allowed '
                               'the same rows in the same order')
    out = machine.node_parameters()
    for node, values in (overrides or {}).items():
        out.setdefault(node, {}).update(values)
    params = {**scene.parameters('design_node'), **scene.parameters('sync_node'),
              **out['sync_node']}
    where = f'{scene_path} on {machine_path}'
    try:
        warnings = check_plausibility(params, machine.row_limits(), where=f'{where}: ')
    except PlausibilityError as exc:
        raise MachineFileError(str(exc)) from None
    if params.get('speed_profile') == 'cam':
        for name, row in machine.rows.items():
            if 'csp' not in row.modes or params.get('operation_mode') == 'velocity':
                said = (f'rows.{name}.modes = [{", ".join(row.modes)}]' if 'csp' not in row.modes
                        else 'operation_mode = velocity')
                raise MachineFileError(f'{where}: {said}: speed_profile cam needs cyclic '
                                       'synchronous position (the cam is a position per SYNC); '
                                       'list csp if the drive offers it, or use speed_profile '
                                       'constant')
    warnings += check_drive_plans(machine, params, where)
    return out, warnings


def main(argv: list[str] | None = None) -> int:
    """`python -m planter_ros.scene.machine_file --ip-commands FILE`: the `ip` commands that bring
    the machine's CAN interfaces up, one a line (planter-can.service pipes them to sh);
    `--check FILE [--scene SCENE]`: the machine file checked, with a scene also the scene's
    plausibility against the machine's limits. Exit 2 with one line for a bad file."""
    # lazy: only this command line uses them (the nodes that read a machine file load none)
    import argparse
    import shlex  # lazy: as argparse
    parser = argparse.ArgumentParser(prog='python -m planter_ros.scene.machine_file',
                                     description='check a machine file; print its ip commands')
    parser.add_argument('file')
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument('--ip-commands', action='store_true')
    what.add_argument('--check', action='store_true')
    parser.add_argument('--scene', help='with --check: a scene to judge against the machine')
    args = parser.parse_args(argv)
    try:
        machine = open_machine(args.file)
        if args.ip_commands:
            for command in machine.ip_commands():
                print(shlex.join(command))
            return 0
        if args.scene:
            for warning in deployment_parameters(args.file, args.scene)[1]:
                print(f'warning: {warning}', file=sys.stderr)
        print(f'{args.file}: {len(machine.rows)} rows on {machine.can.channel} at '
              f'{machine.can.bitrate} bit/s' + (f', ISOBUS on {machine.isobus.channel}'
                                                if machine.isobus.channel else '') + ': ok')
        return 0
    except SceneError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
