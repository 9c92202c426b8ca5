"""A scene's spacing schedule: its `spacing_schedule` [t1, d1, t2, d2, ...] read as (time s of
the field run, plant spacing m) switches. `planter demo` applies them by setting the design
node's `plant_spacing` (a spacing changed at run time: the design node publishes the new design,
the rows take it at their next planting instant); `planter simulate` gives its runs the same
designs at the same times of each run (sim.season)."""
from __future__ import annotations

from typing import Any

from planter_ros.scene.files import SceneError

__all__ = ['spacing_schedule']


def spacing_schedule(params: dict[str, Any], path: Any, low: float = 0.05,
                     high: float = 2.0) -> list[tuple[float, float]]:
    """(t, d) switches of a scene's design parameters, checked: pairs, times increasing and
    ≥ 0, spacings within [low, high] m. SceneError (one line) otherwise."""
    flat = list(params.get('spacing_schedule') or [])
    if len(flat) % 2:
        raise SceneError(f'scene {path}: spacing_schedule has {len(flat)} numbers: allowed '
                         'pairs t1, d1, t2, d2, ... (s, m)')
    pairs = [(float(t), float(d)) for t, d in zip(flat[0::2], flat[1::2])]
    for i, (t, d) in enumerate(pairs):
        if not low <= d <= high:
            raise SceneError(f'scene {path}: spacing_schedule spacing {d} at {t} s is out of '
                             f'range: allowed {low}..{high} m')
        if i and not t > pairs[i - 1][0]:
            raise SceneError(f'scene {path}: spacing_schedule time {t} s is out of order: '
                             f'allowed > {pairs[i - 1][0]} s (increasing)')
    return pairs
