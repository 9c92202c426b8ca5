"""Replay results as text for people: the per-plant table and the summary (mm and degrees,
labelled), as `planter replay` prints them and the demo shows its own bag's."""

from __future__ import annotations

from collections.abc import Collection
import math
from typing import TYPE_CHECKING

from planter_ros import interfaces
from planter_ros.prediction import format_acceptance, format_quality, reason_name, status_name

if TYPE_CHECKING:
    from planter_ros.prediction import Plants
    from planter_ros.prediction.model import PredictionNote
    from .replay import ReplayResult

__all__ = ['format_summary', 'format_table']


def _named_rows(result: ReplayResult) -> bool:
    return len(result.rows) > 1 or bool(result.rows[0].name)


def format_table(result: ReplayResult) -> str:
    """Per-plant rows and the summary for people (mm and degrees, labelled)."""
    p = result.plants
    t0 = float(p.time[0]) if len(p) else 0.0
    messages = result.messages
    names = {row.index: row.label for row in result.rows} if _named_rows(result) else None
    width = max((len(n) for n in names.values()), default=3) if names else 0
    row_head = f'{"row":<{width}} ' if names else ''
    lines = [f'bag {result.path}: {messages[interfaces.GROUND_SPEED.name]} ground speed and '
             f'{messages[interfaces.JOINT_STATES.name]} joint state messages over '
             f'{result.duration:.1f} s',
             f'{row_head}{"plant":>5} {"t [s]":>8} {"x [m]":>8} {"spacing [mm]":>12} '
             f'{"error [mm]":>10} {"lambda":>7} {"sweep [mm]":>10} {"hole [mm]":>9} '
             f'{"tilt [deg]":>10} {"upright":>7}']
    for i in range(len(p)):
        spacing = '' if not math.isfinite(p.spacing[i]) else f'{p.spacing[i] * 1e3:.1f}'
        err = '' if not math.isfinite(p.spacing_error[i]) else f'{p.spacing_error[i] * 1e3:+.1f}'
        lam = f'{p.speed_ratio[i]:.3f}' if math.isfinite(p.speed_ratio[i]) else 'inf'
        row = f'{names.get(int(p.row[i]), "?"):<{width}} ' if names else ''
        lines.append(f'{row}{int(p.index[i]):>5} {p.time[i] - t0:>8.3f} {p.position[i]:>8.3f} '
                     f'{spacing:>12} {err:>10} {lam:>7} {p.tip_sweep[i] * 1e3:>10.2f} '
                     f'{p.hole_width[i] * 1e3:>9.2f} {math.degrees(p.tilt[i]):>10.2f} '
                     f'{_upright(p.upright[i]):>7}'
                     f'{"  " + _status(p, i) if p.status[i] != 3 or p.input_gap[i] else ""}')
    return '\n'.join(lines + [''] + format_summary(result).splitlines())


def _upright(value: float) -> str:
    return '?' if not math.isfinite(value) else 'yes' if value else 'NO'


def _status(p: Plants, i: int) -> str:
    return f'{status_name(p.status[i])} ({reason_name(p.reason[i])})'


def _mm(v: float | None) -> str:
    return 'n/a' if v is None else f'{v * 1e3:.2f} mm'


def format_summary(result: ReplayResult) -> str:
    """The replay summary for people: plants, spacing error and quality, hole width (tip sweep
    and nozzle), uprightness, the map; what a figure means where the model is not validated,
    next to it; with rows, one line per row too (positions along each row's own travelled
    distance)."""
    s = result.summary
    rate = 'n/a' if s['uprightness_rate'] is None else f'{100 * s["uprightness_rate"]:.1f} %'
    threshold = math.degrees(result.settings.upright_threshold)
    nozzle = _nozzle(result)
    notes = list(result.notes or [])
    n = s.get('instants') or {}
    lines = [
        f'plants: {s["plants"]} planting instants (design spacing '
        f'{s["design_spacing"] * 1e3:.1f} mm): {n.get("planted", 0)} planted, '
        f'{n.get("empty", 0)} empty, {n.get("double", 0)} double, {n.get("unknown", 0)} '
        f'unknown ({n.get("input_gap", 0)} in input gaps)',
        f'spacing error: mean {_mm(s["spacing_error_mean"])}, sigma '
        f'{_mm(s["spacing_error_std"])}, max |error| {_mm(s["spacing_error_max"])} (plants at '
        'the distance integrated from the recorded ground speed)',
        f'spacing quality (ISO 7256-1): {format_quality(s["spacing_quality"])}',
        f'hole width: mean {_mm(s["hole_width_mean"])}, max {_mm(s["hole_width_max"])} (tip '
        f'sweep mean {_mm(s["tip_sweep_mean"])} + nozzle width {nozzle})']
    lines += _notes_for(notes, ('tip_sweep', 'hole_width'))
    lines.append(f'uprightness: {rate} (threshold {threshold:.1f} deg to the ground)')
    lines += _notes_for(notes, ('tilt', 'upright', 'uprightness_rate'))
    lines.append(_map_line(result))
    if result.acceptance is not None:
        lines.append(format_acceptance(result.acceptance, f'limits: {result.acceptance_source}'))
    if _named_rows(result):
        for row, r in zip(result.rows, result.row_summaries):
            where = f'y = {row.lateral_offset:+.2f} m'
            if not row.enabled:
                lines.append(f'row {row.label} ({where}): disabled')
                continue
            upright = 'n/a' if r['uprightness_rate'] is None else \
                f'{100 * r["uprightness_rate"]:.1f} %'
            q = r['spacing_quality']['quality_of_feed_index']
            feed = 'n/a' if q is None else f'{100 * q:.1f} %'
            lines.append(f'row {row.label} ({where}): {r["plants"]} plants, spacing error mean '
                         f'{_mm(r["spacing_error_mean"])}, sigma {_mm(r["spacing_error_std"])}, '
                         f'max {_mm(r["spacing_error_max"])}; quality of feed {feed}; upright '
                         f'{upright}')
    return '\n'.join(lines)


def _nozzle(result: ReplayResult) -> str:
    return _mm(result.nozzle_width)


def _notes_for(notes: list[PredictionNote], fields: Collection[str]) -> list[str]:
    """The notes about any of `fields` not shown yet, as indented lines (taken from `notes`)."""
    lines = []
    for note in list(notes):
        if set(note['fields']) & set(fields):
            lines.append(f'  note: {note["text"]}')
            notes.remove(note)
    return lines


def _map_line(result: ReplayResult) -> str:
    placed = int(sum(1 for v in result.plants.latitude if math.isfinite(v)))
    if not result.fixes:
        return 'map: no usable GNSS fix in the bag: no plant has a map position'
    origin = result.placement.origin
    at = 'no origin' if origin is None else f'origin {origin[0]:.7f}, {origin[1]:.7f}'
    return (f'map: {placed} of {len(result.plants)} plants placed from {result.fixes} GNSS '
            f'fixes (antenna at x = {result.antenna.antenna_position[0]:+.2f} m, y = '
            f'{result.antenna.antenna_position[1]:+.2f} m; {at})')
