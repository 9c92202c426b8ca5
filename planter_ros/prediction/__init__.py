"""Per-plant predictions from measured motion, the monitor's model and replay's: where each
seedling went, how wide its hole is and whether it stands upright, judged by the ISO 7256-1
spacing-quality indices.

`model` turns ground-speed and shaft samples into plants (a whole recording at once, or sample
by sample for the live monitor) with the prediction settings; `plants` holds the plant fields,
the `Plants` arrays and a run's summary; `motion` each plant's hole and tilt from the motion
measured through its in-soil arc; `quality` the spacing-quality indices; `sections` the
breaks a row's section switched off makes in its spacing sequence; `pipeline` (imported by
name) all of them sample by sample as the monitor node and the season simulator run them. The
mechanism's planting geometry they use is kinematics.planting. Pure numpy/scipy, no ROS;
depends downward only (kinematics, sensing, design, config).
"""

from .acceptance import (Acceptance, AcceptanceLimits, acceptance_failures,
                         format_acceptance, judge_acceptance)
from .model import (PlantPredictor, PredictionSettings, RowInputs, clean_samples,
                    plant_values, planting_model_from_design, predict_plants, predict_rows,
                    prediction_notes, travelled_distance)
from .plants import PLANT_FIELDS, Plants
from .quality import (QUALITY_FIELDS, SpacingQuality, format_quality, spacing_quality,
                      spacing_quality_by_row)
from .sections import SectionBreaks, section_breaks
from .summary import summarize
from .seedlings import (REASONS, STATUSES, SeedlingAccount, design_spacing_of, reason_name,
                        seedling_spacings, status_counts, status_name)

__all__ = ['Acceptance', 'AcceptanceLimits', 'acceptance_failures', 'format_acceptance',
           'judge_acceptance',
           'PLANT_FIELDS', 'Plants', 'summarize', 'PredictionSettings', 'PlantPredictor',
           'predict_plants', 'predict_rows', 'RowInputs', 'plant_values',
           'planting_model_from_design', 'prediction_notes',
           'clean_samples', 'travelled_distance', 'QUALITY_FIELDS', 'SpacingQuality',
           'spacing_quality', 'spacing_quality_by_row', 'format_quality', 'SectionBreaks',
           'section_breaks', 'REASONS', 'STATUSES', 'SeedlingAccount', 'design_spacing_of',
           'reason_name', 'seedling_spacings', 'status_counts', 'status_name']
