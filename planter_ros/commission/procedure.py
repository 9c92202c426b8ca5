"""Commissioning one planting unit after the other, against a real bus or the simulated drive.

Per row of the machine file (doc/deploy.md, "Commissioning"):

1. identify the drive by SDO (0x1000 device type 402, 0x1018 identity) and check it against
   the machine file: the modes the row lists (0x6502 bit 7 CSP, bit 2 profile velocity), homing
   mode (bit 5) when the row has a homing method, the encoder resolution (0x608F, checked by the
   master at enable);
2. enable it in profile velocity, polarity 0x607E cleared, jog slowly forward and ask the
   observer whether the mechanism turned forward: no -> polarity `reversed` (0x607E = C0h),
   jogged again to confirm;
3. home it (mode 6, the row's homing method; 0: none, the position at enable stays);
4. measure the phase offset from the bottom proximity switch, wired as the drive's home switch
   (0x60FD bit 2): four slow passes over it (its lower and upper edge, each crossed forwards and
   backwards, so the delay between the switch and the position we read cancels); the middle is
   the bottom, where the tip is lowest. No switch found within a turn: the phase is left for
   the user to set by eye (the checklist says so).

The observer is the one thing a machine needs a person for: whether the unit turned forward.
`Observer` asks on the terminal; `SimulatedObserver` reads the simulated mechanism.
Units: mechanism rad and rad/s (the master's), angles stored in [0, 2 pi).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
from typing import Callable

from planter_ros.drive import objects as od
from planter_ros.drive.cia402 import CanopenBus, Cia402Drive, DriveConfig
from planter_ros.drive.dictionary import entry
from planter_ros.drive.eds import default_eds_path
from planter_ros.drive.errors import DriveError
from planter_ros.drive.plan import plan_for_file
from planter_ros.drive.setup import (HOMING_SEARCH_SPEED, HOMING_ZERO_SPEED, DriveSetup,
                                     homing_timeout, missing_modes)
from planter_ros.errors import PlanterError

__all__ = ['CommissionError', 'Observer', 'RowFindings', 'SimulatedObserver', 'checklist',
           'commission_machine', 'commission_row', 'run_warnings', 'updated_machine']

TWO_PI = 2.0 * math.pi
JOG_SPEED = 0.3          # rad/s at the mechanism: the direction jog (about 3 r/min)
JOG_TIME = 1.0           # s
# rad/s: homing's search for the switch (the master homes at every start with the same), and
# the search for the switch here; homing's search for zero and the passes over the switch
SEARCH_SPEED, EDGE_SPEED = HOMING_SEARCH_SPEED, HOMING_ZERO_SPEED


class CommissionError(PlanterError):
    """Commissioning cannot go on; one line naming the row and what was found."""


class Observer:
    """The person at the machine: asked whether a row turned forward (planting direction)."""

    def __init__(self, ask: Callable[[str], str] = input):
        self.ask = ask

    def before_jog(self, row: str) -> None:
        print(f'row {row}: watch the planting unit; it turns slowly for {JOG_TIME:g} s')

    def moved_forward(self, row: str) -> bool:
        answer = self.ask(f'row {row}: did it turn forward (the tip moving as when planting)? '
                          '[y/n] ').strip().lower()
        if answer not in ('y', 'yes', 'n', 'no'):
            raise CommissionError(f'row {row}: answer {answer!r} is not y or n')
        return answer.startswith('y')


class SimulatedObserver(Observer):
    """Reads the simulated mechanism's true angle instead of asking (SimulatedDrive)."""

    def __init__(self, drives: dict):
        self.drives = drives              # row name -> SimulatedDrive
        self._start: dict[str, float] = {}

    def before_jog(self, row: str) -> None:
        self._start[row] = self.drives[row].mechanism_angle

    def moved_forward(self, row: str) -> bool:
        moved = self.drives[row].mechanism_angle - self._start[row]
        return (moved + math.pi) % TWO_PI - math.pi > 0.0


@dataclass
class RowFindings:
    """What commissioning found for one row."""

    row: str
    node_id: int
    identity: dict = field(default_factory=dict)
    polarity: str = 'normal'
    homing_method: int = 0
    homed: bool = False
    phase_offset: float | None = None     # rad, None: no switch found (set it by eye)
    switch_width: float | None = None     # rad of mechanism turn the switch is active
    edges: tuple[float, ...] = ()         # the four edge positions measured (rad)
    warnings: tuple[str, ...] = ()        # the start-up plan's (drive.plan), for the run's mode


def commission_row(drive, name: str, row, observer: Observer) -> RowFindings:
    """Commission one row (module doc); `drive` a Cia402Drive for the row's node id, configured
    for profile velocity with the row's gear ratio and encoder counts, opened or not.
    CommissionError / DriveError (one line) when it cannot go on."""
    found = RowFindings(name, row.node_id, homing_method=row.homing_method)
    drive.open()
    found.identity = identity = drive.read_identity()
    device_type = identity['device_type']
    if device_type is None or device_type & 0xFFFF != 402:
        raise CommissionError(f'row {name}: node {row.node_id} is not a CiA 402 drive (device '
                              f'type {device_type})')
    modes = identity['supported_modes'] or 0
    missing = missing_modes(modes, DriveSetup(modes=tuple(row.modes),
                                              homing_method=row.homing_method))
    if missing:
        raise CommissionError(f'row {name}: node {row.node_id} supports modes 0x{modes:08X} '
                              f'(0x6502), without {", ".join(missing)} the machine file needs')
    polarity = entry(drive.dictionary, od.POLARITY.index)
    settable = polarity is not None and polarity.writable
    if settable:
        drive.set_polarity(False)
    drive.connect_and_enable()
    if not _turns_forward(drive, name, observer):
        if not settable:
            raise CommissionError(f'row {name}: turns backwards, and the drive\'s EDS has no '
                                  'writable 0x607E polarity: reverse the direction in the '
                                  'drive\'s own configuration, then commission again')
        found.polarity = 'reversed'
        drive.set_polarity(True)
        if not _turns_forward(drive, name, observer):
            raise CommissionError(f'row {name}: turns backwards with either polarity (0x607E): '
                                  'check the drive and the mechanism')
    if row.homing_method:
        drive.home(row.homing_method, SEARCH_SPEED, EDGE_SPEED, timeout=homing_timeout())
        found.homed = True
    edges = _switch_edges(drive)
    if edges is not None:
        found.edges = edges
        lower = 0.5 * (edges[0] + edges[1])
        upper = 0.5 * (edges[2] + edges[3])
        found.switch_width = upper - lower
        found.phase_offset = (0.5 * (lower + upper)) % TWO_PI
    return found


def _turns_forward(drive, name: str, observer: Observer) -> bool:
    observer.before_jog(name)
    drive.jog(JOG_SPEED, timeout=JOG_TIME)
    return observer.moved_forward(name)


def _switch_edges(drive) -> tuple[float, float, float, float] | None:
    """(lower edge crossed backwards, lower forwards, upper forwards, upper backwards) of the
    home switch in mechanism rad, or None when it is not found within 1.2 turns."""
    def switch() -> bool:
        return bool(drive.read_inputs() & od.DI_HOME_SWITCH)

    def crossing(speed: float, active: bool, turns: float) -> float | None:
        at: list[float] = []

        def reached() -> bool:
            if switch() == active:
                at.append(drive.status().position)
                return True
            return False
        drive.jog(speed, until=reached, timeout=turns * TWO_PI / abs(speed))
        return at[0] if at else None

    search = 1.2
    if switch() and crossing(SEARCH_SPEED, False, search) is None:
        return None
    if crossing(SEARCH_SPEED, True, search) is None:
        return None
    if switch():           # stopped on it: leave it backwards over its lower edge
        upper_back = None
    else:                  # stopped past it: back onto it over its upper edge
        upper_back = crossing(-EDGE_SPEED, True, 0.5)
    lower_back = crossing(-EDGE_SPEED, False, 0.5)
    lower_fwd = crossing(EDGE_SPEED, True, 0.5)
    upper_fwd = crossing(EDGE_SPEED, False, 0.5)
    if upper_back is None:
        upper_back = crossing(-EDGE_SPEED, True, 0.5)
    edges = (lower_back, lower_fwd, upper_fwd, upper_back)
    if any(e is None for e in edges):
        return None
    return edges            # type: ignore[return-value]


def written_offset(phase_offset: float) -> float:
    """The phase offset as the machine file gets it (and the checklist prints it): 1 urad."""
    return round(phase_offset, 6) % TWO_PI


def updated_machine(machine, findings: list[RowFindings]):
    """The machine file with each commissioned row's polarity and measured phase offset."""
    rows = dict(machine.rows)
    for f in findings:
        row = replace(rows[f.row], polarity=f.polarity)
        # the drive found is the one every start checks for (0x1018), unless the file says
        for key, found in (('vendor_id', f.identity.get('vendor_id')),
                           ('product_code', f.identity.get('product_code')),
                           ('revision', f.identity.get('revision'))):
            if getattr(row, key) == -1 and found is not None:
                row = replace(row, **{key: int(found)})
        if f.phase_offset is not None:
            row = replace(row, phase_offset=written_offset(f.phase_offset))
        rows[f.row] = row
    return replace(machine, rows=rows)


def commission_machine(machine, rows: list[str], observer: Observer, bus=None,
                       drive_config: dict | None = None) -> list[RowFindings]:
    """Commission `rows` of `machine` one after the other on one bus (`bus`: an open
    python-can bus, else the machine's channel); each drive shut down after its row."""
    findings = []
    shared = None
    try:
        for name in rows:
            row = machine.rows[name]
            config = DriveConfig(can_interface=machine.can.interface,
                                 can_channel=machine.can.channel,
                                 can_bitrate=machine.can.bitrate, drive_node_id=row.node_id,
                                 motor_gear_ratio=row.gear_ratio,
                                 counts_per_motor_rev=row.encoder_counts,
                                 operation_mode='velocity', **(drive_config or {}))
            shared = shared or CanopenBus(config, bus)
            setup = machine.drive_setups()[name]
            drive = Cia402Drive(setup.device(config), canbus=shared)
            try:
                found = commission_row(drive, name, row, observer)
                # what the row's own start will be like (its mode, its EDS): the warnings
                found.warnings = run_warnings(machine, name)
                findings.append(found)
            except DriveError as exc:
                raise CommissionError(f'row {name}: {exc}') from None
            finally:
                drive.shutdown()
    finally:
        if shared is not None:
            shared.close()
    return findings


def run_warnings(machine, name: str) -> tuple[str, ...]:
    """The warnings of row `name`'s start-up plan (drive.plan), made from its EDS for the
    mode it runs in (the machine file's check refused what the plan refuses)."""
    row = machine.rows[name]
    setup = machine.drive_setups()[name]
    config = setup.device(DriveConfig(can_bitrate=machine.can.bitrate,
                                      drive_node_id=row.node_id))
    eds = setup.eds or str(default_eds_path())
    return plan_for_file(eds, config, setup).warnings


def checklist(findings: list[RowFindings], machine_path) -> str:
    """What was found per row and what the user must confirm by eye, for the terminal."""
    lines = []
    for f in findings:
        ident = f.identity
        lines.append(f'row {f.row} (node {f.node_id}):')
        lines.append(f'  [found] drive: vendor 0x{ident.get("vendor_id") or 0:08X}, product '
                     f'0x{ident.get("product_code") or 0:08X}, revision '
                     f'{ident.get("revision") or 0}, serial {ident.get("serial") or 0}; modes '
                     f'0x{ident.get("supported_modes") or 0:08X} (0x6502) as the machine file '
                     'needs')
        lines.append(f'  [found] polarity: {f.polarity} (0x607E = '
                     f'{"C0h" if f.polarity == "reversed" else "0"})')
        lines.append('  [found] homing: ' + (f'method {f.homing_method}, attained'
                                              if f.homed else 'none (method 0)'))
        if f.phase_offset is None or f.switch_width is None:   # set together
            lines.append('  [by hand] no home switch seen within a turn: jog the unit until the '
                         f'tip is lowest and write that angle as rows.{f.row}.phase_offset')
        else:
            lines.append(f'  [found] bottom switch: {math.degrees(f.switch_width):.2f} deg wide, '
                         f'phase offset {written_offset(f.phase_offset):.5f} rad '
                         f'({math.degrees(f.phase_offset):.2f} deg)')
        lines += [f'  [drive] {warning}' for warning in f.warnings]
        lines.append('  [by eye] the unit turned forward (planting direction) in the last jog')
        lines.append('  [by eye] at the phase offset the tip is at the bottom of its path, and '
                     'the bottom switch sits there')
        lines.append('  [by eye] nothing rubs or hits in a full slow turn; the tip clears the '
                     'ground with the planter lifted')
    lines.append(f'written: {machine_path}')
    return '\n'.join(lines)
