"""`planter demo --machine FILE`: the demo on a commissioned machine file.

The machine file's rows, node ids, lever arms and drive train replace the scene's (the antenna is
the machine's reference point); the sync node gets the file (`machine_file`) and so checks each
drive against it and applies its polarity, homing and phase offset at start. The simulated
drives are the machine's: its gear ratio and encoder counts, the identity it states, wired as
`simdrive.mechanism.simulated_mechanism` says for the seed (as `planter commission
--simulated --seed N` found them) but powered up at another mechanical offset (a drive reset:
the encoder counts from wherever the motor stood), and each keeps the instants its mechanism
truly passes its bottom. After the run the first plant of each row as the bag has it (replay) is
set against that truth: how far along the row the plant the machine recorded lies from where the
tip really was lowest.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from planter_ros.rows import rows_from_scene

__all__ = ['FIRST_PLANT_LIMIT', 'POWER_UP', 'first_plant_errors', 'first_plant_lines',
           'first_plant_reasons', 'machine_rows', 'simulated_drives']

POWER_UP = 1        # the demo's power-up of the simulated drives (commissioning's is 0)
FIRST_PLANT_LIMIT = 0.005   # m: a commissioned machine's first plant lands this close (issue 22)


def machine_rows(scene: Any, machine: Any) -> list:
    """The rows the sync node runs: the scene's with the machine file's values over them."""
    return rows_from_scene({**scene.parameters('sync_node'), **machine.scene_parameters()})


def simulated_drives(machine: Any, seed: int) -> dict[str, Any]:
    """SimulatedBus keyword arguments: each row's drive as the machine file and the seed say,
    recording its true bottom passes."""
    # lazy: simdrive.mechanism loads python-can and canopen (79 ms in the demo's process,
    # which has no bus): only a --machine demo asks for its drives
    from planter_ros.simdrive.mechanism import simulated_mechanism
    node_kwargs = {}
    for row in machine.rows.values():
        offset, reversed_ = simulated_mechanism(seed, row.node_id, POWER_UP)
        kwargs = {'gear_ratio': row.gear_ratio, 'counts_per_motor_rev': row.encoder_counts,
                  'mechanical_offset': offset, 'motor_reversed': reversed_,
                  'record_bottom': True}
        if row.eds:                  # the simulated drive serves the row's own dictionary
            kwargs['eds_path'] = str(machine.eds_path(row))
        default = (0x0000_0000, 0x0000_0402, 1, 0)          # the simulated drive's own
        kwargs['identity'] = [default[i] if value == -1 else value for i, value in
                              enumerate((row.vendor_id, row.product_code, row.revision))] + [0]
        node_kwargs[str(row.node_id)] = kwargs
    return {'node_kwargs': node_kwargs}


def first_plant_errors(rows: list, replayed: Any, bottom_times: dict, profile: Any,
                       start_ros: float, start_monotonic: float) -> dict[str, dict]:
    """Per planting row: {'recorded': s of its first plant in the bag (replay), 'true': s of the
    mechanism's true bottom pass nearest it, 'error': recorded - true (m, along the row, both
    on the simulator's true distance)} or {'error': None, 'why': ...}."""
    out: dict[str, dict] = {}
    plants = replayed.plants
    for row in rows:
        if not row.enabled:
            continue
        times = np.asarray(plants.time)[np.asarray(plants.row) == row.index]
        truth = [t - start_monotonic for t in bottom_times.get(str(row.drive_node_id), [])]
        truth = [t for t in truth if t >= 0.0]
        if not times.size or not truth:
            out[row.label] = {'error': None, 'why': 'no plant in the bag' if not times.size
                              else 'the simulated mechanism never passed its bottom'}
            continue
        recorded = float(np.min(times)) - start_ros
        true = min(truth, key=lambda t: abs(t - recorded))
        at, real = (_along(profile, t, row.lateral_offset) for t in (recorded, true))
        out[row.label] = {'recorded': at, 'true': real, 'error': at - real}
    return out


def _along(profile: Any, t: float, lateral_offset: float) -> float:
    """The row's true travelled distance at `t` s of the field run."""
    if hasattr(profile, 'row_distance'):
        return float(profile.row_distance(np.array([t]), lateral_offset)[0])
    return float(profile.distance(np.array([t]))[0])


def first_plant_lines(errors: dict[str, dict]) -> list[str]:
    """The demo summary's lines of `first_plant_errors`."""
    lines = ['', 'first plant after the start (machine file: homed, phase offset applied)']
    for label, found in errors.items():
        if found['error'] is None:
            lines.append(f'  row {label}: not measured: {found["why"]}')
            continue
        lines.append(f'  row {label}: recorded (bag replay) at {found["recorded"]:.4f} m, the '
                     f'tip truly lowest at {found["true"]:.4f} m along the row: error '
                     f'{found["error"] * 1e3:+.2f} mm')
    return lines


def first_plant_reasons(errors: dict[str, dict]) -> list[str]:
    """The verdict's reasons: a row whose first plant was not measured or lands farther than
    FIRST_PLANT_LIMIT from where the machine recorded it."""
    out = []
    for label, found in errors.items():
        if found['error'] is None:
            out.append(f'row {label}: first plant not measured ({found["why"]})')
        elif abs(found['error']) > FIRST_PLANT_LIMIT:
            out.append(f'row {label}: first plant {found["error"] * 1e3:+.1f} mm from where the '
                       f'machine recorded it > {FIRST_PLANT_LIMIT * 1e3:g} mm (polarity, homing '
                       'or phase offset wrong: commission again)')
    return out
