"""`planter commission`: its run (the options: cli/commission.py)."""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import uuid

import can

from planter_ros.output_files import OutputError, check_output
from planter_ros.scene.files import SceneError
from planter_ros.scene.machine_file import (CanBus, deployment_parameters, open_machine,
                                            rows_asked, write_machine)
from planter_ros.simdrive.drive import SimulatedDrive
from planter_ros.simdrive.mechanism import simulated_mechanism
from planter_ros.simdrive.spec import SimSpec

from .procedure import (CommissionError, Observer, SimulatedObserver, checklist,
                        commission_machine, updated_machine)


def run(args: argparse.Namespace) -> int:
    def fail(message: str) -> int:
        print(f'planter: error: commission: {message}', file=sys.stderr)
        return 2

    try:
        machine = open_machine(args.machine)
        if args.scene:
            for warning in deployment_parameters(args.machine, args.scene)[1]:
                print(f'warning: {warning}', file=sys.stderr)
        # where the result goes, checked before anything moves: '' is no file (it never
        # means the input), a directory or a missing one is refused now, not after homing
        output = args.machine if args.output is None else args.output
        check_output(output, '--output' if args.output is not None else '--machine',
                     ('.yaml', '.yml'))
    except (SceneError, OutputError) as exc:
        return fail(str(exc))
    try:
        rows = rows_asked(machine, args.row, args.machine)
    except SceneError as exc:
        return fail(str(exc))
    simulated = args.simulated or machine.can.interface == 'virtual'
    bus, sims = None, {}
    observer: Observer = Observer()
    run_machine = machine
    try:
        if simulated:
            channel = f'planter-commission-{uuid.uuid4().hex}'
            run_machine = dataclasses.replace(machine, can=CanBus(interface='virtual',
                                                                   channel='vcan0'))
            for name in rows:
                row = machine.rows[name]
                modes = tuple({'pv': 3, 'csp': 8}[m] for m in row.modes)
                offset, reversed_ = simulated_mechanism(args.seed, row.node_id)
                sims[name] = SimulatedDrive(channel, node_id=row.node_id, spec=SimSpec(
                    counts_per_motor_rev=row.encoder_counts, gear_ratio=row.gear_ratio,
                    supported_modes=modes, mechanical_offset=offset, motor_reversed=reversed_,
                    eds_path=str(machine.eds_path(row)) if row.eds else None))
                sims[name].start()
            bus = can.Bus(interface='virtual', channel=channel)
            observer = SimulatedObserver(sims)
        findings = commission_machine(run_machine, rows, observer, bus=bus)
        write_machine(updated_machine(machine, findings), output,
                      comment=f'machine file written by planter commission (rows: '
                              f'{", ".join(rows)})')
    except (CommissionError, SceneError) as exc:
        return fail(str(exc))
    except EOFError:
        return fail('no answer on the terminal (the direction must be confirmed by eye)')
    finally:
        if bus is not None:
            bus.shutdown()
        for sim in sims.values():
            sim.stop()
    print(checklist(findings, output))
    for f in findings:
        if f.row in sims and f.phase_offset is not None:
            error = math.degrees(sims[f.row].mechanism_angle_at(f.phase_offset))
            print(f'simulated row {f.row}: mechanical offset '
                  f'{math.degrees(sims[f.row].spec.mechanical_offset):.2f} deg, wiring '
                  f'{"reversed" if sims[f.row].spec.motor_reversed else "normal"}; phase error '
                  f'{error:+.3f} deg')
    return 0
