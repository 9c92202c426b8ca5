"""The start-up plan of one drive, computed from its EDS/DCF: which objects the master writes,
which it skips and why, which PDOs carry what, and what the row's mode needs that the drive
lacks (refused before anything moves). One plan, two uses: the machine file's check and the
`planter drive check` print it; `Cia402Drive` carries it out at every start.

A write is **needed** (refused when the file lacks the object, or has it read-only with a value
that does not serve) or **optional** (skipped, with the reason, when the object is absent or
read-only/const with a value that already serves; a warning when that weakens a safeguard).
The PDO layouts fill each PDO up to the mapping capacity the file states (its mapping
sub-indices, sub-index 0's high limit, 64 bits), spreading the entries over more PDOs where a
PDO takes fewer. CiA 301 timing: in cyclic synchronous position every PDO is synchronous
(transmission type 1: an RPDO acts at the next SYNC, a TPDO is sent after each SYNC); in profile
velocity the RPDO acts at once (255) and the TPDOs are sent on their event timer (255), or
after each SYNC when the drive has no TPDO event timer (then the master produces SYNC in
profile velocity too).

Messages: `who` (e.g. 'row a, drive node 3') then the object, what is wrong, what it is for
and what to do, one line. Pure: no bus (canopen's object dictionary only).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import TYPE_CHECKING

from . import objects as od
from .config import interpolation_period
from .dictionary import Entry, entry, mapping_capacity, read_dictionary
from .errors import DictionaryError
from .setup import (HOMING_ALLOWED, HOMING_SEARCH_SPEED, HOMING_ZERO_SPEED, homing_method_ok,
                    missing_modes, mode_bits)
from .states import ABORT_OPTION_QUICK_STOP, CSP_SUPPORTED, CYCLIC_SYNC_POSITION, \
    PROFILE_VELOCITY, PROFILE_VELOCITY_SUPPORTED

if TYPE_CHECKING:
    from canopen.objectdictionary import ObjectDictionary

    from .config import DriveConfig
    from .setup import DriveSetup

__all__ = ['DrivePlan', 'PdoPlan', 'Write', 'choose_mode', 'interpolation_period', 'plan_for_file',
           'plan_drive', 'MODE_NAMES', 'homing_writes', 'PDO_NUMBERS']

MODE_NAMES = {PROFILE_VELOCITY: 'profile velocity', CYCLIC_SYNC_POSITION: 'cyclic synchronous '
              'position'}
PDO_NUMBERS = (1, 2, 3, 4)            # the predefined connection set's PDOs (COB-IDs known)
PDO_NOT_VALID = 1 << 31
SYNCHRONOUS, EVENT = 1, 255           # transmission types the master uses
MAX_PDO_BITS = 64


@dataclass(frozen=True)
class Write:
    """One SDO write of the plan: `obj` = `value`, in the start-up step `step`."""

    obj: od.Obj
    value: int
    step: str


@dataclass(frozen=True)
class PdoPlan:
    """One PDO as the plan maps it (COB-ID from the predefined connection set)."""

    kind: str                         # 'RPDO' or 'TPDO'
    number: int                       # 1..4
    entries: tuple[od.Obj, ...]
    trans_type: int
    event_timer: int | None = None    # ms written to sub-index 5 (None: not written)
    inhibit_time: int | None = None   # 100 µs written to sub-index 3 (None: not written)

    @property
    def comm_index(self) -> int:
        return (0x1400 if self.kind == 'RPDO' else 0x1800) + self.number - 1

    @property
    def map_index(self) -> int:
        return self.comm_index + 0x200

    @property
    def layout(self) -> od.PdoLayout:
        return od.PdoLayout(self.kind, self.number, self.entries, '')

    def cob_id(self, node_id: int) -> int:
        return self.layout.cob_id(node_id)

    @property
    def text(self) -> str:
        kind = ('synchronous (type 1: ' + ('acts at the next SYNC)' if self.kind == 'RPDO'
                                          else 'after each SYNC)')
                if self.trans_type == SYNCHRONOUS else
                ('at once (type 255)' if self.kind == 'RPDO' else
                 f'every {self.event_timer} ms and on a change (type 255)'))
        entries = ', '.join(f'{o.index:04X}h {o.name}' for o in self.entries)
        return f'{self.kind}{self.number}: {entries}; {kind}'


@dataclass(frozen=True)
class DrivePlan:
    """What the master does with one drive (see the module doc)."""

    node_id: int
    mode: int
    rpdos: tuple[PdoPlan, ...]
    tpdos: tuple[PdoPlan, ...]
    off: tuple[tuple[str, int], ...]               # (kind, number) of PDOs switched off
    writes: tuple[Write, ...]                      # watchdogs, polarity, CSP, in order
    skipped: tuple[str, ...]                       # the optional writes left out, and why
    warnings: tuple[str, ...]
    sync_feedback: bool = False                    # TPDOs on SYNC in profile velocity
    heartbeat_consumer: bool = True                # 1016h written: the drive watches us
    deadline: bool = True                          # 1400h:5 written: RPDO deadline watched
    interpolation: tuple[int, int] | None = None   # 60C2h (value, index) written
    homing: tuple[Write, ...] = ()                 # homing's objects (setup's method)
    comm: tuple[Write, ...] = field(default=(), repr=False)   # every PDO write, in order

    @property
    def needs_sync(self) -> bool:
        """The master must produce SYNC while this drive runs (CSP, or TPDOs on SYNC)."""
        return self.mode == CYCLIC_SYNC_POSITION or self.sync_feedback

    @property
    def target(self) -> od.Obj:
        return od.TARGET_POSITION if self.mode == CYCLIC_SYNC_POSITION else od.TARGET_VELOCITY

    def lines(self) -> list[str]:
        """The plan for people, one item a line."""
        out = [f'mode: {MODE_NAMES[self.mode]} (6060h = {self.mode})']
        out += [f'  {pdo.text}' for pdo in (*self.rpdos, *self.tpdos)]
        if self.off:
            out.append('  switched off: ' + ', '.join(f'{k}{n}' for k, n in self.off))
        out += [f'write {w.obj.index:04X}h' + (f':{w.obj.subindex}' if w.obj.subindex else '')
                + f' {w.obj.name} = {_shown(w)}' for w in (*self.writes, *self.homing)]
        out += [f'skip {text}' for text in self.skipped]
        out += [f'warning: {text}' for text in self.warnings]
        return out


def _shown(write: Write) -> str:
    return _value(write.obj, write.value)


def _value(obj: od.Obj, value: int) -> str:
    """A value as people read it: COB-IDs, bit fields and big numbers in hex."""
    return f'0x{value:X}' if value > 0xFFFF or obj.index in (0x1005, 0x1016, 0x607E) \
        else str(value)


def choose_mode(operation_mode: str, supported: int | None, setup: DriveSetup | None,
                who: str, kind: type = DictionaryError) -> int:
    """The mode the drive runs: the machine file's modes (CSP when it lists csp and
    `operation_mode` allows it) or, without one, `operation_mode` against 6502h = `supported`
    (None: not said, profile velocity). `kind` (DictionaryError: from the EDS; the drive's
    own answer at start: DriveRefusedError) when none fits."""
    bits = PROFILE_VELOCITY_SUPPORTED if supported is None else supported
    modes = tuple(setup.modes) if setup is not None and setup.modes else ()
    if modes:
        if 'csp' in modes and operation_mode != 'velocity':
            wanted = CYCLIC_SYNC_POSITION
        elif 'pv' in modes and operation_mode != 'csp':
            wanted = PROFILE_VELOCITY
        else:
            raise kind(f'{who}: operation_mode {operation_mode} is none of the machine '
                       f'file\'s modes [{", ".join(modes)}]: set operation_mode to auto')
    elif operation_mode == 'csp' or (operation_mode == 'auto' and bits & CSP_SUPPORTED):
        wanted = CYCLIC_SYNC_POSITION
    else:
        wanted = PROFILE_VELOCITY
    bit = CSP_SUPPORTED if wanted == CYCLIC_SYNC_POSITION else PROFILE_VELOCITY_SUPPORTED
    if not bits & bit:
        name = MODE_NAMES[wanted]
        other = 'pv' if wanted == CYCLIC_SYNC_POSITION else 'csp'
        remedy = (f'list only `modes: [{other}]` in the machine file' if modes else
                  f'set operation_mode to {"velocity" if other == "pv" else "csp"} or auto')
        raise kind(f'{who}: 0x6502 supported drive modes 0x{bits:08X} lack {name} (bit '
                   f'{bit.bit_length() - 1}): the row runs {name}; {remedy}, or use a drive '
                   'that has it')
    return wanted


class _Planner:
    """The plan's making: one drive's file, settings and machine-file entry."""

    def __init__(self, dictionary: ObjectDictionary, config: DriveConfig,
                 setup: DriveSetup | None, mode: int, who: str) -> None:
        self.od, self.config, self.setup, self.mode, self.who = (dictionary, config, setup,
                                                                 mode, who)
        self.writes: list[Write] = []
        self.skipped: list[str] = []
        self.warnings: list[str] = []
        self.comm: list[Write] = []

    def refuse(self, what: str, why: str, remedy: str) -> DictionaryError:
        return DictionaryError(f'{self.who}: {what}: {why}; {remedy}')

    def entry(self, obj: od.Obj) -> Entry | None:
        """The file's entry of `obj` (None: not listed); refused when its type differs."""
        found = entry(self.od, obj.index, obj.subindex)
        if found is not None and found.data_type != obj.dtype:
            raise self.refuse(f'{_name(obj)} is {od.type_name(found.data_type)} in this '
                              'drive\'s EDS', f'the master reads and writes it as '
                              f'{obj.type_name}', 'correct the EDS (the drive maker\'s is '
                              'right)')
        return found

    def needed(self, obj: od.Obj, value: int, step: str, why: str, remedy: str) -> None:
        """A write the row cannot do without."""
        found = self.entry(obj)
        if found is None:
            raise self.refuse(f'{_name(obj)} is not in this drive\'s EDS', why, remedy)
        if found.writable:
            self.writes.append(Write(obj, value, step))
        elif found.value != value:
            raise self.refuse(f'{_name(obj)} is {found.access} in this drive\'s EDS'
                              + (f' (value {found.value})' if found.value is not None else ''),
                              f'{why}, as {value}', remedy)

    def optional(self, obj: od.Obj, value: int, step: str, absent: str = '',
                 serves: bool | None = None) -> bool:
        """A write done where it can be: skipped when the object is absent (`absent`: a
        warning why that matters) or read-only with a value that serves (`serves`: whether
        a read-only value does; None: equal to `value`). True when written."""
        found = self.entry(obj)
        if found is None:
            self.skipped.append(f'{_name(obj)} = {_value(obj, value)}: not in the EDS')
            if absent:
                self.warnings.append(absent)
            return False
        if found.writable:
            self.writes.append(Write(obj, value, step))
            return True
        ok = found.value == value if serves is None else serves
        self.skipped.append(f'{_name(obj)} = {_value(obj, value)}: {found.access}'
                            + (f' at {_value(obj, found.value)}' if found.value is not None
                               else '')
                            + ('' if ok else ' (it does not serve)'))
        if not ok and absent:
            self.warnings.append(absent)
        return False

    def mapped(self, obj: od.Obj, why: str, remedy: str) -> None:
        found = self.entry(obj)
        if found is not None and obj is not od.STATUSWORD and obj is not od.POSITION_ACTUAL \
                and obj is not od.VELOCITY_ACTUAL and not found.writable:
            raise self.refuse(f'{_name(obj)} is {found.access} in this drive\'s EDS', why,
                              remedy)
        if found is None:
            raise self.refuse(f'{_name(obj)} is not in this drive\'s EDS', why, remedy)
        if not found.mappable:
            raise self.refuse(f'{_name(obj)} is not PDO-mappable in this drive\'s EDS', why,
                              remedy)


def _name(obj: od.Obj) -> str:
    return f'0x{obj.index:04X}' + (f':{obj.subindex}' if obj.subindex else '') + f' {obj.name}'


def plan_drive(dictionary: ObjectDictionary, config: DriveConfig, setup: DriveSetup | None,
               mode: int, who: str = '') -> DrivePlan:
    """The plan for the drive whose file is `dictionary`, set up as `config` and `setup`, in
    `mode` (3 or 8); DictionaryError (one line, `who` first) for what the mode needs and the
    file lacks."""
    who = who or f'drive node {config.drive_node_id}'
    p = _Planner(dictionary, config, setup, mode, who)
    csp = mode == CYCLIC_SYNC_POSITION
    name = MODE_NAMES[mode]
    other = '`modes: [pv]`' if csp else '`modes: [csp]`'
    target = od.TARGET_POSITION if csp else od.TARGET_VELOCITY
    for obj, why in ((od.CONTROLWORD, 'every state change and command travels in it'),
                     (target, f'{name} needs it')):
        p.mapped(obj, why, f'use {other} or a drive that maps it' if obj is target
                 else 'use a CiA 402 drive that maps it')
    for obj, why in ((od.STATUSWORD, 'the drive\'s state and faults travel in it'),
                     (od.POSITION_ACTUAL, 'the row\'s angle travels in it'),
                     (od.VELOCITY_ACTUAL, 'the row\'s speed travels in it')):
        p.mapped(obj, why, 'use a CiA 402 drive that maps it')
    for obj in (od.MODES_OF_OPERATION, od.MODES_DISPLAY):
        if p.entry(obj) is None:
            raise p.refuse(f'{_name(obj)} is not in this drive\'s EDS', 'the mode is set and '
                           'confirmed with it', 'use a CiA 402 drive')
    status = [od.STATUSWORD]
    error_code = p.entry(od.ERROR_CODE)
    if error_code is not None and error_code.mappable:
        status.append(od.ERROR_CODE)
    else:
        p.skipped.append(f'{_name(od.ERROR_CODE)} in a TPDO: '
                         + ('not in the EDS' if error_code is None else 'not PDO-mappable')
                         + ' (the fault code comes from the EMCY)')
    feedback_ms = max(1, round(config.feedback_period * 1000))
    rpdos = _pack(p, 'RPDO', [[od.CONTROLWORD, target]])
    tpdos = _pack(p, 'TPDO', [status, [od.POSITION_ACTUAL, od.VELOCITY_ACTUAL]])
    timers = all(_sub(p, 'TPDO', n, 5) for n, _ in tpdos)
    sync_feedback = not csp and not timers
    if sync_feedback:
        p.warnings.append('the TPDOs have no event timer (1800h:5) in this drive\'s EDS: its '
                          'feedback is sent after each SYNC, which the master produces every '
                          f'control period in {name} too')
    rpdo_plans, deadline = [], True
    for number, entries in rpdos:
        timer = round(config.command_timeout * 1000)
        written = _optional_sub(p, 'RPDO', number, 5, timer, 'event timer (deadline)')
        deadline = deadline and written
        rpdo_plans.append(PdoPlan('RPDO', number, tuple(entries),
                                  SYNCHRONOUS if csp else EVENT, timer if written else None))
    if not deadline:
        p.warnings.append('no RPDO deadline monitoring (1400h:5 not in the EDS): the drive '
                          'does not stop by itself when our commands stop')
    tpdo_plans = []
    for number, entries in tpdos:
        synchronous = csp or sync_feedback
        inhibit = 0 if _optional_sub(p, 'TPDO', number, 3, 0, 'inhibit time') else None
        timer = 0 if synchronous else feedback_ms
        event_timer = timer if _optional_sub(p, 'TPDO', number, 5, timer, 'event timer') else None
        tpdo_plans.append(PdoPlan('TPDO', number, tuple(entries),
                                  SYNCHRONOUS if synchronous else EVENT, event_timer, inhibit))
    used = {('RPDO', n) for n, _ in rpdos} | {('TPDO', n) for n, _ in tpdos}
    off = _switch_off(p, used)
    for pdo in (*rpdo_plans, *tpdo_plans):
        _pdo_writes(p, pdo, config.drive_node_id)
    consumer = _watchdogs(p, deadline, csp)
    _polarity(p)
    interpolation = _csp(p) if csp else None
    if not csp:
        p.optional(od.COMM_CYCLE_PERIOD, 0, 'SYNC period (0x1006 = 0: not watched)')
    homing = tuple(homing_writes(p, setup.homing_method, config)) if (
        setup is not None and setup.homing_method) else ()
    return DrivePlan(config.drive_node_id, mode, tuple(rpdo_plans), tuple(tpdo_plans), off,
                     tuple(p.writes), tuple(p.skipped), tuple(p.warnings), sync_feedback,
                     consumer, deadline, interpolation, homing, tuple(p.comm))


def _comm_obj(kind: str, number: int, sub: int, what: str) -> od.Obj:
    index = (0x1400 if kind == 'RPDO' else 0x1800) + number - 1
    dtype = {1: od.UNSIGNED32, 2: od.UNSIGNED8, 3: od.UNSIGNED16, 5: od.UNSIGNED16}[sub]
    return od.Obj(index, sub, dtype, f'{kind}{number} {what}', '')


def _sub(p: _Planner, kind: str, number: int, sub: int) -> bool:
    found = entry(p.od, (0x1400 if kind == 'RPDO' else 0x1800) + number - 1, sub)
    return found is not None and found.writable


def _optional_sub(p: _Planner, kind: str, number: int, sub: int, value: int, what: str) -> bool:
    obj = _comm_obj(kind, number, sub, what)
    if _sub(p, kind, number, sub):
        return True
    found = entry(p.od, obj.index, sub)
    p.skipped.append(f'{_name(obj)} = {value}: '
                     + ('not in the EDS' if found is None else found.access))
    return False


def _usable(p: _Planner, kind: str, number: int, trans_type: int) -> int:
    """How many entries PDO `kind``number` takes for the plan (0: not usable)."""
    comm = (0x1400 if kind == 'RPDO' else 0x1800) + number - 1
    cob, trans = entry(p.od, comm, 1), entry(p.od, comm, 2)
    if cob is None or trans is None or not cob.writable:
        return 0
    if not trans.writable and trans.value != trans_type:
        return 0
    return mapping_capacity(p.od, comm + 0x200)


def _pack(p: _Planner, kind: str,
          groups: list[list[od.Obj]]) -> list[tuple[int, list[od.Obj]]]:
    """The groups' entries over the PDOs `kind` 1..4, in order: each group starts a PDO; a PDO
    takes entries up to its capacity and 64 bits, the rest go to the next (the error code, an
    extra, is left out rather than refused)."""
    csp = p.mode == CYCLIC_SYNC_POSITION
    trans = SYNCHRONOUS if csp else EVENT
    free = [(n, cap) for n in PDO_NUMBERS if (cap := _usable(p, kind, n, trans)) > 0]
    out: list[tuple[int, list[od.Obj]]] = []
    for group in groups:
        current: tuple[int, list[od.Obj], int] | None = None    # (number, entries, capacity)
        for obj in group:
            if current is None or len(current[1]) >= current[2] or (
                    sum(o.bits for o in current[1]) + obj.bits > MAX_PDO_BITS):
                if not free:
                    if obj is od.ERROR_CODE:
                        p.skipped.append(f'{_name(obj)} in a TPDO: no PDO left to carry it')
                        continue
                    needed = sum(len(g) for g in groups)
                    raise p.refuse(f'{kind}s 1..4 of this drive\'s EDS cannot carry '
                                   f'{_name(obj)}', f'the row needs {needed} entries in '
                                   f'{kind}s ({", ".join(o.name for g in groups for o in g)})',
                                   f'use a drive whose {kind} mapping takes them')
                number, cap = free.pop(0)
                current = (number, [], cap)
                out.append((number, current[1]))
            current[1].append(obj)
    return out


def _switch_off(p: _Planner, used: set[tuple[str, int]]) -> tuple[tuple[str, int], ...]:
    off = []
    for kind, base in (('RPDO', 0x1400), ('TPDO', 0x1800)):
        for number in range(1, 513):
            comm = base + number - 1
            if comm not in p.od or (kind, number) in used:
                continue
            cob = entry(p.od, comm, 1)
            if cob is not None and cob.writable:
                default = cob.value if cob.value is not None else 0
                cob_id = (0x180 if kind == 'TPDO' else 0x200) + 0x100 * (number - 1) + \
                    p.config.drive_node_id if number <= 4 else default & 0x7FF
                p.comm.append(Write(_comm_obj(kind, number, 1, 'COB-ID'),
                                    PDO_NOT_VALID | cob_id, f'switch {kind}{number} off'))
                off.append((kind, number))
            elif cob is not None and cob.value is not None and not cob.value & PDO_NOT_VALID:
                p.warnings.append(f'{kind}{number} cannot be switched off ({comm:04X}h:1 is '
                                  f'{cob.access}): its frames add to the bus load')
    return tuple(off)


def _pdo_writes(p: _Planner, pdo: PdoPlan, node_id: int) -> None:
    """CiA 301's order: invalid, transmission type, timers, count 0, entries, count, valid."""
    step = f'configure {pdo.kind}{pdo.number} ({pdo.comm_index:04X}h, {pdo.map_index:04X}h)'
    cob = pdo.cob_id(node_id)
    writes = [Write(_comm_obj(pdo.kind, pdo.number, 1, 'COB-ID'), PDO_NOT_VALID | cob, step)]
    trans_type = entry(p.od, pdo.comm_index, 2)
    if trans_type is not None and trans_type.writable:
        writes.append(Write(_comm_obj(pdo.kind, pdo.number, 2, 'transmission type'),
                            pdo.trans_type, step))
    if pdo.inhibit_time is not None:
        writes.append(Write(_comm_obj(pdo.kind, pdo.number, 3, 'inhibit time'),
                            pdo.inhibit_time, step))
    if pdo.event_timer is not None:
        writes.append(Write(_comm_obj(pdo.kind, pdo.number, 5, 'event timer'),
                            pdo.event_timer, step))
    count = od.Obj(pdo.map_index, 0, od.UNSIGNED8, f'{pdo.kind}{pdo.number} mapped objects', '')
    writes.append(Write(count, 0, step))
    for sub, obj in enumerate(pdo.entries, start=1):
        writes.append(Write(od.Obj(pdo.map_index, sub, od.UNSIGNED32,
                                   f'{pdo.kind}{pdo.number} mapping {sub}', ''),
                            (obj.index << 16) | (obj.subindex << 8) | obj.bits, step))
    writes.append(Write(count, len(pdo.entries), step))
    writes.append(Write(_comm_obj(pdo.kind, pdo.number, 1, 'COB-ID'), cob, step))
    p.comm.extend(writes)


def _watchdogs(p: _Planner, deadline: bool, csp: bool) -> bool:
    cfg = p.config
    step = 'heartbeat (0x1017 producer, 0x1016 consumer)'
    period = round(cfg.drive_heartbeat_period * 1000)
    p.needed(od.HEARTBEAT_PRODUCER, period, step, 'the master watches the drive\'s heartbeat '
             '(a drive lost stops its row)', 'set drive_heartbeat_period to the drive\'s own, '
             'or use a drive that produces a heartbeat')
    consumer = (cfg.master_node_id << 16) | round(cfg.master_heartbeat_timeout * 1000)
    stop = (' (its RPDO deadline, 1400h:5, still stops it when our commands stop)'
            if deadline else '')
    written = p.optional(od.HEARTBEAT_CONSUMER, consumer, step,
                         'no heartbeat consumer (1016h) in this drive\'s EDS: the master '
                         'watches the drive\'s heartbeat, but the drive will not stop by '
                         f'itself if the master dies{stop}', serves=False)
    p.optional(od.ABORT_CONNECTION, ABORT_OPTION_QUICK_STOP,
               'watchdog (0x6007 abort connection option = quick stop)',
               'no 6007h abort connection option in this drive\'s EDS: on a lost master it '
               'reacts as its maker set it')
    if not csp:
        p.optional(od.TARGET_VELOCITY, 0, 'target velocity 0 (0x60FF)')
    return written


def _polarity(p: _Planner) -> None:
    setup = p.setup
    step = 'polarity (0x607E)'
    if setup is not None and setup.polarity == 'reversed':
        p.needed(od.POLARITY, od.POLARITY_REVERSED, step, 'the machine file\'s `polarity: '
                 'reversed` needs it', 'reverse the direction in the drive\'s own '
                 'configuration and write `polarity: normal`')
        return
    found = p.entry(od.POLARITY)
    if found is not None and not found.writable and (found.value or 0) & od.POLARITY_REVERSED:
        raise p.refuse(f'{_name(od.POLARITY)} is {found.access} at 0x{found.value:02X} '
                       '(reversed)', 'the machine file says `polarity: normal`',
                       'write `polarity: reversed` or set the drive\'s direction')
    p.optional(od.POLARITY, 0, step, serves=True)


def _csp(p: _Planner) -> tuple[int, int] | None:
    cfg = p.config
    step = 'SYNC (0x1005 consumer, 0x1006 period, 0x60C2 interpolation period)'
    found = p.entry(od.SYNC_COB_ID)
    if found is not None and not found.writable and found.value is not None and (
            found.value & 0x7FF != od.SYNC_COB or found.value & (1 << 30)):
        raise p.refuse(f'{_name(od.SYNC_COB_ID)} is {found.access} at 0x{found.value:X}',
                       'cyclic synchronous position needs the drive to consume SYNC 80h',
                       '`modes: [pv]` or a drive that consumes it')
    p.optional(od.SYNC_COB_ID, od.SYNC_COB, step)
    micro = round(cfg.sync_period * 1e6)
    found = p.entry(od.COMM_CYCLE_PERIOD)
    if found is not None and not found.writable and found.value not in (None, 0, micro):
        raise p.refuse(f'{_name(od.COMM_CYCLE_PERIOD)} is {found.access} at {found.value} µs',
                       'the drive expects SYNC at that period',
                       f'set sync_period to {found.value / 1e6:g} s')
    p.optional(od.COMM_CYCLE_PERIOD, micro, step, 'no 1006h communication cycle period in this '
               'drive\'s EDS: the drive does not watch for a late or missing SYNC',
               serves=found is not None and found.value in (None, 0, micro))
    interpolation = _interpolation(p, step)
    window = max(1, round(cfg.following_error_window * cfg.counts_per_motor_rev
                          * cfg.motor_gear_ratio / (2.0 * math.pi)))
    step = 'following error (0x6065 window, 0x6066 time out)'
    absent = ('no following-error window (6065h/6066h) in this drive\'s EDS: the drive '
              'watches its following error as its maker set it')
    p.optional(od.FOLLOWING_ERROR_WINDOW, window, step, absent, serves=True)
    p.optional(od.FOLLOWING_ERROR_TIMEOUT, round(cfg.following_error_timeout * 1e3), step,
               serves=True)
    return interpolation


def _interpolation(p: _Planner, step: str) -> tuple[int, int] | None:
    period = p.config.sync_period
    value_entry = p.entry(od.INTERPOLATION_PERIOD_VALUE)
    index_entry = p.entry(od.INTERPOLATION_PERIOD_INDEX)
    if value_entry is None:
        p.skipped.append(f'{_name(od.INTERPOLATION_PERIOD_VALUE)}: not in the EDS')
        p.warnings.append('no 60C2h interpolation time period in this drive\'s EDS: it '
                          'interpolates over its own period (1006h, or its maker\'s setting)')
        return None
    fixed = None
    if index_entry is not None and not index_entry.writable:
        fixed = index_entry.value if index_entry.value is not None else -3
    elif index_entry is None:
        fixed = -3                        # no index: the value counts milliseconds
    found = interpolation_period(period, fixed)
    if found is None:
        raise p.refuse(f'{_name(od.INTERPOLATION_PERIOD_INDEX)} is fixed at {fixed} in this '
                       'drive\'s EDS', f'sync_period {period:g} s is no whole number of '
                       f'10^{fixed} s up to 255', 'use a sync_period that is one (whole ms '
                       'for -3)')
    value, index = found
    if not value_entry.writable and value_entry.value != value:
        raise p.refuse(f'{_name(od.INTERPOLATION_PERIOD_VALUE)} is {value_entry.access} at '
                       f'{value_entry.value}', f'the drive interpolates over '
                       f'{value_entry.value} × 10^{index} s', 'set sync_period to that')
    p.optional(od.INTERPOLATION_PERIOD_VALUE, value, step)
    if index_entry is not None:
        p.optional(od.INTERPOLATION_PERIOD_INDEX, index, step)
    return value, index


def homing_writes(p: _Planner | ObjectDictionary, method: int, config: DriveConfig,
                  switch_speed: float | None = None,
                  zero_speed: float | None = None) -> list[Write]:
    """The objects homing method `method` writes (6098h, 6099h:1/:2 unless the method
    homes on the current position, 607Ch = 0 where it can), speeds in counts/s from
    mechanism rad/s (default: the homing speeds of drive.setup)."""
    if not isinstance(p, _Planner):
        p = _Planner(p, config, None, PROFILE_VELOCITY, f'drive node {config.drive_node_id}')
    before = len(p.writes)
    step = f'homing method {method} (0x6098, 0x6099, 0x607C, 0x6060 = 6)'
    if not homing_method_ok(method):
        raise p.refuse(f'homing method {method}', 'it is no CiA 402 homing method',
                       f'allowed {HOMING_ALLOWED}')
    remedy = 'use homing_method 0 (none) or a drive that homes'
    p.needed(od.HOMING_METHOD, method, step, 'homing at start needs it', remedy)
    counts = config.counts_per_motor_rev * config.motor_gear_ratio / (2.0 * math.pi)
    if method not in (35, 37):
        for obj, speed in ((od.HOMING_SPEED_SWITCH, switch_speed or HOMING_SEARCH_SPEED),
                           (od.HOMING_SPEED_ZERO, zero_speed or HOMING_ZERO_SPEED)):
            p.needed(obj, max(1, round(abs(speed) * counts)), step, f'homing method {method} '
                     'searches at this speed', remedy)
    p.optional(od.HOME_OFFSET, 0, step)
    out = p.writes[before:]
    del p.writes[before:]
    return out


def plan_for_file(path: str, config: DriveConfig, setup: DriveSetup | None,
                  who: str = '') -> DrivePlan:
    """The plan made from the EDS/DCF at `path` alone (no bus: the machine file's check and
    `planter drive check` before it starts): the modes as the machine file lists them, unless
    the file's own 6502h default says the drive lacks one (refused, naming 0x6502)."""
    who = who or f'drive node {config.drive_node_id}'
    dictionary = read_dictionary(path, config.drive_node_id)
    stated = entry(dictionary, od.SUPPORTED_MODES.index)
    supported = stated.value if stated is not None and stated.value else None
    if setup is not None and setup.modes:
        missing = missing_modes(supported, setup) if supported is not None else []
        if missing:
            raise DictionaryError(f'{who}: 0x6502 supported drive modes 0x{supported:08X} in '
                                  f'this drive\'s EDS lack {", ".join(missing)}: the machine '
                                  'file lists them for the row; list only what the drive '
                                  'offers, or use a drive that has them')
        supported = mode_bits(setup) if supported is None else supported
    mode = choose_mode(config.operation_mode, supported, setup, who)
    return plan_drive(dictionary, config, setup, mode, who)
