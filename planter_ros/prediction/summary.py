"""A run's summary figures (SI) from its plants: count, spacing error, hole and tip sweep,
uprightness, every planting instant's status and the spacing quality between the seedlings in
the ground (prediction.seedlings, prediction.quality). Pure numpy."""

from typing import TypedDict

import numpy as np
from numpy.typing import ArrayLike

from .plants import Plants
from .quality import QualityIndices, spacing_quality
from .seedlings import seedling_spacings, status_counts

__all__ = ['RunSummary', 'summarize']


class RunSummary(TypedDict):
    """summarize's figures (SI; None: no plant has the value)."""

    plants: int
    instants: dict[str, int]                 # planting instants by status
    design_spacing: float
    spacing_error_mean: float | None
    spacing_error_std: float | None
    spacing_error_max: float | None
    hole_width_mean: float | None
    hole_width_max: float | None
    tip_sweep_mean: float | None
    tip_sweep_max: float | None
    tilt_max: float | None
    uprightness_rate: float | None
    spacing_quality: QualityIndices


def summarize(plants: Plants, spacing: float,
              design_spacing: ArrayLike | None = None) -> RunSummary:
    """Summary figures (SI) of a run: plant count, spacing error, hole width and tip sweep,
    uprightness, spacing quality (each plant's spacing against `design_spacing`: one per plant,
    default `spacing` for all)."""
    err = plants.spacing_error[np.isfinite(plants.spacing_error)]
    hole = plants.hole_width[np.isfinite(plants.hole_width)]
    sweep = plants.tip_sweep[np.isfinite(plants.tip_sweep)]
    upright = plants.upright[np.isfinite(plants.upright)]
    tilt = plants.tilt[np.isfinite(plants.tilt)]
    d = np.broadcast_to(np.asarray(spacing if design_spacing is None else design_spacing,
                                   dtype=float), plants.spacing.shape)
    x, x_d = seedling_spacings(plants, d)
    return {
        'plants': len(plants),
        'instants': status_counts(plants),
        'design_spacing': float(spacing),
        'spacing_error_mean': float(err.mean()) if err.size else None,
        'spacing_error_std': float(err.std()) if err.size else None,
        'spacing_error_max': float(np.abs(err).max()) if err.size else None,
        'hole_width_mean': float(hole.mean()) if hole.size else None,
        'hole_width_max': float(hole.max()) if hole.size else None,
        'tip_sweep_mean': float(sweep.mean()) if sweep.size else None,
        'tip_sweep_max': float(sweep.max()) if sweep.size else None,
        'tilt_max': float(np.abs(tilt).max()) if tilt.size else None,
        'uprightness_rate': float(upright.mean()) if upright.size else None,
        'spacing_quality': spacing_quality(x, x_d),
    }
