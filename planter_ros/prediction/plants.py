"""The plants a prediction gives: their fields (`PLANT_FIELDS`, SI, in this order everywhere: the
`plants` topic's layout, JSON keys, replay's tables, the Parquet tables of a season), the
`Plants` arrays (the run's summary figures: prediction.summary). Pure numpy, no ROS.
"""

from collections.abc import Iterable
from dataclasses import dataclass, fields
import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = ['PLANT_FIELDS', 'Plants']

# Per-plant record, in this order everywhere (topic layout, JSON keys, replay tables). SI units.
PLANT_FIELDS = (
    'index',             # plant number since the start of the stream (0, 1, ...)
    'time',              # s, measurement time of the planting instant (source clock)
    'position',          # m, travelled distance along the row since the first speed sample
    'spacing',           # m, distance to the previous plant (NaN for the first plant)
    'spacing_error',     # m, spacing - design spacing d (NaN for the first plant)
    'speed_ratio',       # λ = A0·ω/v (1 = in sync; inf when v = 0)
    'ground_speed',      # m/s, measured ground speed at the planting instant
    'shaft_speed',       # rad/s, measured mechanism shaft speed at the planting instant
    'hole_width',        # m, tip_sweep + the nozzle's width along the row: the soil's hole
    'tilt',              # rad from vertical, + = top leans forward (direction of travel)
    'upright',           # 1 if the stem's angle to the ground >= upright_threshold, else 0
    'uprightness_rate',  # fraction upright over the last `window` plants (this one included)
    'row',               # the planting unit: its index in the machine's rows (0 without rows)
    # later fields go last, so a consumer reading the older ones by place keeps working
    'tip_sweep',         # m, swept extent of the nozzle tip (a point) below the soil
    'latitude',          # deg WGS 84 of the plant (the as-planted map); NaN without GNSS
    'longitude',         # deg WGS 84; NaN without GNSS
    'input_gap',         # 1: the instant fell in a gap of the ground speed or joint samples
                         # (time and position interpolated; hole, tilt, upright NaN), else 0
    'seedlings',         # seedlings the row's cup sensor counted for this instant (NaN: none)
    'status',            # prediction.seedlings.STATUSES: 0 planted, 1 empty, 2 double, 3 unknown
    'reason',            # prediction.seedlings.REASONS: why the status (0 = sensed)
)


@dataclass
class Plants:
    """Per-plant arrays (one entry per plant, fields as in PLANT_FIELDS)."""

    index: np.ndarray
    time: np.ndarray
    position: np.ndarray
    spacing: np.ndarray
    spacing_error: np.ndarray
    speed_ratio: np.ndarray
    ground_speed: np.ndarray
    shaft_speed: np.ndarray
    hole_width: np.ndarray
    tilt: np.ndarray
    upright: np.ndarray
    uprightness_rate: np.ndarray
    row: np.ndarray
    tip_sweep: np.ndarray
    latitude: np.ndarray
    longitude: np.ndarray
    input_gap: np.ndarray
    seedlings: np.ndarray
    status: np.ndarray
    reason: np.ndarray

    def __len__(self) -> int:
        return int(self.index.size)

    def table(self) -> np.ndarray:
        """(n_plants, n_fields) float array in PLANT_FIELDS order."""
        return np.column_stack([np.asarray(getattr(self, f), dtype=float) for f in PLANT_FIELDS]) \
            if len(self) else np.zeros((0, len(PLANT_FIELDS)))

    def take(self, which: ArrayLike) -> 'Plants':
        """The plants `which` (a boolean mask or indices), every field."""
        return Plants(**{f: getattr(self, f)[which] for f in PLANT_FIELDS})

    def rows(self) -> list[dict[str, float | None]]:
        """List of dicts, JSON-ready: non-finite values become None."""
        return [{f: _json_value(v) for f, v in zip(PLANT_FIELDS, row)} for row in self.table()]

    @classmethod
    def from_table(cls, table: ArrayLike, fields: tuple[str, ...] = PLANT_FIELDS) -> 'Plants':
        """Plants of a table whose columns are `fields` (an older layout: fewer; a field it
        lacks is NaN, but input_gap 0 and status/reason unknown/no sensor)."""
        table = np.asarray(table, dtype=float).reshape(-1, len(fields))
        have = {f: table[:, i].copy() for i, f in enumerate(fields)}
        n = table.shape[0]
        defaults = {'input_gap': 0.0, 'status': 3.0, 'reason': 1.0}
        return cls(**{f: have[f] if f in have else np.full(n, defaults.get(f, np.nan))
                      for f in PLANT_FIELDS})

    @classmethod
    def empty(cls) -> 'Plants':
        """No plants: every field an empty float array of its own (as `from_table` of an
        empty table gives, without building one; the monitor's predictor answers most
        samples with it)."""
        return cls(**{f: np.empty(0) for f in PLANT_FIELDS})

    @classmethod
    def concatenate(cls, parts: Iterable['Plants']) -> 'Plants':
        parts = list(parts)
        if not parts:
            return cls.empty()
        return cls(**{f.name: np.concatenate([getattr(p, f.name) for p in parts])
                      for f in fields(cls)})


def _json_value(v: float) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None
