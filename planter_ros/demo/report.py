"""The demo's report for people: per row the plants placed and their spacing error (from the
measured mechanism angle against the row's true travelled distance, which only a simulation
knows; replay of the bag, printed after it, places the plants at the distance integrated from
the recorded ground speed, as the machine's monitor does, with the same statistics), commanded
against
measured speed, in the turns the compensation's effect, then the command path's figures from
the sync process (sample counts, slips, send errors, watchdog trips, control-loop periods,
design changes)."""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from planter_ros.command.reports import RowSnapshot, Snapshot
from planter_ros.sim.spacing import error_figures, spacing_in_force, spacing_stats

from .sync_process import SyncReport
from .verdict import RowResult

if TYPE_CHECKING:
    from planter_ros.design import Design
    from planter_ros.rows import Row
    from planter_ros.sim.field import FieldProfile
    from planter_ros.sim.ros_field import Observer

__all__ = ['command_path_lines', 'progress_line', 'row_summary']


@dataclass(frozen=True)
class FieldRun:
    """What the demo's own figures are measured in: the design, the true field profile (speed
    and turns), the observer that saw the mechanisms turn and the spacing changes it saw
    ((t since start, d), spacing_changes)."""

    design: Design
    profile: FieldProfile
    observer: Observer
    changes: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class RowPlants:
    """One planting row's plants at the true travelled distance: their times (s) and
    positions (m), and the design spacing in force for each gap between them (m)."""

    row: Row
    times: npt.NDArray[np.float64]
    positions: npt.NDArray[np.float64]
    in_force: npt.NDArray[np.float64]


def progress_line(t: float, profile: Any, status: Snapshot, plants: int, rows: list) -> str:
    """The line printed every few seconds: time, speed, each row's command (and with one row
    its measured speed and drive state), plants so far. `rows`: the planting rows."""
    shown = status.rows
    if len(rows) == 1:
        row = shown[0] if shown else RowSnapshot('', 0.0, 0.0, '-', False)
        return (f't = {t:5.1f} s  v = {profile(t):.3f} m/s  command = '
                f'{row.command:6.3f} rad/s  measured = '
                f'{row.velocity:6.3f} rad/s  plants = {plants:3d}  '
                f'drive: {row.state}')
    commands = ' '.join(f'{row.command:5.2f}' for row in shown)
    return (f't = {t:5.1f} s  v = {profile(t):.3f} m/s  yaw rate = '
            f'{profile.yaw_rate(t):+.3f} rad/s  commands = {commands} rad/s  '
            f'plants = {plants:3d}')


def spacing_changes(observer: Any) -> list[tuple[float, float]]:
    """(t since start, d) of each design change the observer saw."""
    return [(t, design.plant_spacing) for t, design in observer.design_changes()]


def row_summary(design: Any, rows: list, profile: Any, observer: Any,
                report: SyncReport) -> tuple[str, list[RowResult]]:
    """The demo's own figures per planting row and the command path's report:
    (text, [RowResult] for the verdict). `rows`: every row of the scene."""
    d = design.plant_spacing
    n = design.plants_per_revolution
    named = bool(rows[0].name)
    changes = spacing_changes(observer)
    run = FieldRun(design, profile, observer, tuple(changes))
    lines = ['', 'summary']
    results = []
    for row in (row for row in rows if row.enabled):
        joint = row.joint(design.mechanism)
        times, positions = observer.plants(profile, design, joint, row.lateral_offset)
        in_force = spacing_in_force(times, d, changes)      # each gap against its design
        stats = spacing_stats(positions, in_force)
        gaps = np.diff(positions) - in_force
        mean, sigma, worst, rms = (v or 0.0 for v in error_figures(gaps))
        relative = float(np.sqrt(np.mean((gaps / in_force) ** 2))) if gaps.size else 0.0
        results.append(RowResult(row.label if named else '', stats.plants, relative))
        head = f'  row {row.label} (y = {row.lateral_offset:+.2f} m)' if named else ''
        if head:
            lines.append(head)
        pad = '    ' if named else '  '
        against = (f'd = {d * 1e3:.0f} mm' if not changes else
                   'd in force: ' + ' -> '.join(f'{x * 1e3:.0f}' for x in
                                                [d] + [c[1] for c in changes]) + ' mm')
        lines += [f"{pad}plants placed            {stats.plants}",
                  f"{pad}spacing error gap - d   mean {mean * 1e3:+.2f} mm, sigma "
                  f"{sigma * 1e3:.2f} mm, max |error| {worst * 1e3:.2f} mm, RMS "
                  f"{rms * 1e3:.2f} mm  ({against})",
                  f"{pad}{'':24} plants at the true travelled distance (the simulator's; "
                  "replay below: at the recorded ground speed's)",
                  f"{pad}drift from the grid      max {stats.max_abs_drift * 1e3:.2f} mm, "
                  f"last plant {stats.final_drift * 1e3:+.2f} mm"]
        for label, (a, b) in (('cruise 1', (profile.start + 0.5, profile.t_change)),
                              ('cruise 2', (profile.t_change + 1.5, profile.t_stop))):
            expected = 2 * math.pi * profile(0.5 * (a + b)) / (
                n * _in_force_at(0.5 * (a + b), d, changes))
            cmd = observer.window('command', a, b, joint)
            meas = observer.window('velocity', a, b, joint)
            if cmd.size and meas.size and not named:
                rms_speed = np.sqrt(np.mean((meas - expected) ** 2))
                lines.append(f"{pad}{label + ' speed':<24} expected {expected:.3f} rad/s, "
                             f'commanded {np.mean(cmd):.3f}, measured {np.mean(meas):.3f} '
                             f'(rms measured - expected {rms_speed:.3f})')
        lines += _curve_lines(run, RowPlants(row, times, positions, in_force), pad)
    lines += command_path_lines(report)
    return '\n'.join(lines), results


def command_path_lines(report: SyncReport) -> list[str]:
    """Sample counts, slips, send errors, watchdog trips and the control loop's period
    statistics, from the sync process's report (sync_process.final_report), and how each
    drive ended."""
    lines = []
    command = report.command
    if command is None:
        lines.append(f'  command path             no figures: {report.command_missing}')
    else:
        lines += [f'  ground-speed samples     {command.accepted} accepted, rejected '
                  + ', '.join(f'{k} {v}' for k, v in command.rejected.items()),
                  f'  yaw-rate samples         {command.yaw_accepted} accepted, rejected '
                  + ', '.join(f'{k} {v}' for k, v in command.yaw_rejected.items()),
                  f'  phase slips              {command.phase_slips}; CAN send errors '
                  f'{command.send_errors}; mode '
                  f"{'phase-locked' if command.phase_lock else 'speed-only'}, turn "
                  f"compensation {'on' if command.turn_compensation else 'off'}"]
    trips = ', '.join(f'node {node}: {why} (0x{code:04X})'
                      for node, why, code in report.drives.watchdog_trips)
    lines.append(f"  drive watchdog trips     {trips or 'none'}")
    if command is not None:
        deadline = command.command_timeout
        for row in command.rows:
            loop = row.loop
            name = f' {row.label}' if len(command.rows) > 1 else ''
            if not loop['gaps']:
                lines.append(f'  control loop{name:<12} no command frames')
                continue
            lines.append(f"  control loop{name:<12} command gap mean {loop['mean'] * 1e3:.1f} "
                         f"ms, p99.9 {loop['p999'] * 1e3:.1f} ms, max {loop['max'] * 1e3:.1f} "
                         f"ms over {loop['gaps'] + 1} frames (drive deadline "
                         f'{deadline * 1e3:.0f} ms)')
    if report.command_exit and report.command_exit != 'stop':
        lines.append(f'  command process          stopped by {report.command_exit}: rows '
                     'ramped to 0, drives disabled')
    for node, end in sorted(report.drives.end.items(), key=lambda item: int(item[0])):
        lines.append(f'  drive node {node:<13} ended {end.text()}')
    sources = report.design
    lines.append(f'  design                   from {sources.first or "nobody"}'
                 + (f'; {sources.changes} change(s) during the run, the latest from '
                    f'{sources.last_change}' if sources.changes else
                    '; unchanged during the run'))
    return lines


def _curve_lines(run: FieldRun, plants: RowPlants, pad: str) -> list[str]:
    """Per turn: the row's mean spacing error and speed against 2πv_i/(n·d), next to the
    bias a machine without turn compensation shows there (−y·d/R)."""
    design, profile, observer, changes = run.design, run.profile, run.observer, run.changes
    row, times, positions = plants.row, plants.times, plants.positions
    d = design.plant_spacing
    n = design.plants_per_revolution
    lines = []
    gaps = np.diff(positions) - plants.in_force
    for curve in profile.curves:
        a, b = curve.start + curve.ease, curve.end - curve.ease
        mine = gaps[(times[:-1] >= a) & (times[1:] <= b)]
        meas = observer.window('velocity', a, b, row.joint(design.mechanism))
        grid = np.linspace(a, b, 50)
        expected = np.mean([2 * math.pi * profile(t) * (1 - row.lateral_offset
                                                        / curve.radius)
                            / (n * _in_force_at(t, d, changes)) for t in grid])
        side = 'left' if curve.radius > 0 else 'right'
        err = (f'mean {np.mean(mine) * 1e3:+.2f} mm, RMS '
               f'{np.sqrt(np.mean(mine ** 2)) * 1e3:.2f} mm over {mine.size} gaps'
               if mine.size else 'n/a')
        ratio = (f'; speed {np.median(meas) / expected:.3f} x 2πv_i/(n·d)'
                 if meas.size and expected > 0 else '')
        bias = (f'; without compensation expect '
                f'{-row.lateral_offset * d / curve.radius * 1e3:+.2f} mm (-y·d/R)'
                if row.lateral_offset else '')     # a row at y = 0 sees no difference
        lines.append(f'{pad}{side + " turn R = " + format(abs(curve.radius), "g") + " m":<24}'
                     f' spacing error {err}{ratio}{bias}')
    return lines


def _in_force_at(t, spacing, changes):
    """d (m) in force at t s (by the changes' message times: for speeds, not plants)."""
    for when, new in changes:
        if t >= when:
            spacing = new
    return spacing
