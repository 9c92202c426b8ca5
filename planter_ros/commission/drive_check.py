"""`planter drive check --machine FILE [--row NAME]`: the bring-up test a technician runs on a new
drive, on any python-can interface (the machine file's `can` block; `virtual` or --simulated:
simulated drives serving each row's EDS).

Per row: the drive's dictionary (its EDS) and the start-up plan made from it (drive.plan: the
PDOs, the mode, the objects written and skipped, the warnings), or the plan's refusal; then on
the bus its identity (1000h, 1018h, 6502h), the start-up by that plan with SYNC from the NMT
start, a move of a few degrees (a position ramp in cyclic synchronous position, a slow jog in
profile velocity) and the disable. Homing is left to `planter commission`. Exit 0 when every
row passed, 2 when a row's drive cannot run its row (the plan refused it), 1 when a drive
failed on the bus. The options: cli/drive_check.py."""
from __future__ import annotations

import argparse
from dataclasses import replace
import math
import sys
from typing import Any
import uuid

import can

from planter_ros.drive.cia402 import Cia402Drive, DriveConfig
from planter_ros.drive.dictionary import device_name, read_dictionary
from planter_ros.drive.eds import default_eds_path
from planter_ros.drive.errors import DictionaryError, DriveError
from planter_ros.drive.plan import plan_for_file
from planter_ros.drive.states import CYCLIC_SYNC_POSITION
from planter_ros.scene.files import SceneError
from planter_ros.scene.machine_file import open_machine, rows_asked
from planter_ros.simdrive.drive import SimulatedDrive
from planter_ros.simdrive.spec import SimSpec

__all__ = ['run', 'check_row']

SPEED = 0.3               # rad/s at the mechanism


def run(args: argparse.Namespace) -> int:
    def fail(message: str) -> int:
        print(f'planter: error: drive check: {message}', file=sys.stderr)
        return 2

    if not math.isfinite(args.degrees) or not 0.0 <= abs(args.degrees) <= 90.0:
        return fail(f'--degrees = {args.degrees} is out of range: allowed -90..90')
    try:
        machine = open_machine(args.machine)
    except SceneError as exc:
        return fail(str(exc))
    try:
        rows = rows_asked(machine, args.row, args.machine)
    except SceneError as exc:
        return fail(str(exc))
    simulated = args.simulated or machine.can.interface == 'virtual'
    outcome = 0
    with _bus(machine, rows, simulated) as bus:
        for name in rows:
            outcome = max(outcome, check_row(machine, name, bus, math.radians(args.degrees)))
    return outcome


class _bus:
    """The bus the rows are checked on: the machine's, or simulated drives on a virtual one
    (each serving its row's EDS); closed, and the simulated drives stopped, on exit."""

    def __init__(self, machine: Any, rows: list[str], simulated: bool) -> None:
        self.machine, self.rows, self.simulated = machine, rows, simulated
        self.bus: can.BusABC | None = None
        self.sims: list[SimulatedDrive] = []

    def __enter__(self) -> Any:
        if not self.simulated:
            return None
        channel = f'planter-drive-check-{uuid.uuid4().hex}'
        for name in self.rows:
            row = self.machine.rows[name]
            spec = SimSpec(supported_modes=None, identity=None,
                           counts_per_motor_rev=row.encoder_counts, gear_ratio=row.gear_ratio,
                           eds_path=str(self.machine.eds_path(row)) if row.eds else None)
            sim = SimulatedDrive(channel, node_id=row.node_id, spec=spec)
            sim.start()
            self.sims.append(sim)
        self.bus = can.Bus(interface='virtual', channel=channel)
        return self.bus

    def __exit__(self, *exc: object) -> None:
        if self.bus is not None:
            self.bus.shutdown()
        for sim in self.sims:
            sim.stop()


def check_row(machine: Any, name: str, bus: Any, angle: float) -> int:
    """Check one row (module doc), printing as it goes; its exit code."""
    row = machine.rows[name]
    setup = replace(machine.drive_setups()[name], homing_method=0)   # homing: commission's
    who = f'row {name}, drive node {row.node_id}'
    eds = setup.eds or str(default_eds_path())
    print(f'row {name} (node {row.node_id} on {machine.can.interface}:{machine.can.channel})')
    try:
        config = setup.device(DriveConfig(can_interface=machine.can.interface,
                                          can_channel=machine.can.channel,
                                          can_bitrate=machine.can.bitrate,
                                          drive_node_id=row.node_id))
        dictionary = read_dictionary(eds, row.node_id)
        print(f'  dictionary: {eds} ({device_name(dictionary) or "no device name"}, '
              f'{len(dictionary)} objects)')
        plan = plan_for_file(eds, config, setup, who)
    except DictionaryError as exc:
        print(f'  refused: {exc}')
        return 2
    for line in plan.lines():
        print(f'  plan: {line}')
    drive = Cia402Drive(config, bus=bus, setup=setup)
    try:
        drive.open()
        ident = drive.read_identity()
        print('  identity: ' + ', '.join(
            f'{key} {"-" if value is None else f"0x{value:08X}"}' for key, value in ident.items()))
        syncs = drive.canbus.syncs_sent
        drive.connect_and_enable()
        print(f'  enabled in {1e3 * drive.enable_duration:.0f} ms, '
              f'{drive.canbus.syncs_sent - syncs} SYNC sent while starting (state '
              f'{drive.status().state})')
        if angle:
            if drive.mode == CYCLIC_SYNC_POSITION:
                moved = drive.move_by(angle, speed=SPEED)
            else:
                before = drive.status().position
                drive.jog(math.copysign(SPEED, angle), timeout=abs(angle) / SPEED)
                moved = drive.status().position - before
            print(f'  moved {math.degrees(angle):+.2f} deg asked, {math.degrees(moved):+.2f} '
                  'deg reported by the drive')
    except DriveError as exc:
        print(f'  failed: {exc}')
        return 2 if isinstance(exc, DictionaryError) else 1
    finally:
        drive.shutdown()
    print(f'  disabled: passed ({len(plan.warnings)} warning(s) above)')
    return 0
