"""The monitor's prediction pipeline, sample by sample: the one the live monitor node runs and
the season simulator records (sim.season), so a simulated season is what the machine's monitor
would have published, plant for plant.

Inputs come as plain numbers in arrival order (the monitor's receive order), times in s:
ground speed (v, ω_z), the rows' joints by name, GNSS fixes, the rows' section states, seedling
sensor readings, the design and the settings. The pipeline keeps:

* the machine's motion as the rows use it (sensing.row_speed.RowSpeedStream; the yaw rate
  always: the as-planted map dead-reckons the machine's heading), each row's own speed v − ω_z·y;
* one PlantPredictor per planting row (prediction.model), a design change in force from each
  row's next planting instant, a design of another mechanism starting a new sequence;
* the breaks a row's section switched off makes in its spacing sequence (prediction.sections);
* each planting instant's seedlings from the row's cup sensor (prediction.seedlings);
* the as-planted map (sensing.plant_map.PlantPlacer): a plant is released once the fixes that
  place it are in;
* what the monitor publishes with each released batch: the machine's rolling upright rate over
  the last `window` plants whose uprightness is known, and the ISO 7256-1 spacing-quality
  indices of each row and of the whole machine (prediction.quality) so far.

Every input returns the batches it released, as `Placed` (plants, placement, the rate and the
indices right after them), in the order they are to be published. Replay predicts a whole
recording at once with the same model and arithmetic (prediction.model.predict_rows,
sensing.plant_map.place_plants): the test of the two is test_simulate.py. Pure: numpy and the
packages below, no ROS (the messages are built in recording.monitor_topics).
"""

from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import math

from planter_ros.design import Design
from planter_ros.rows import Row
from planter_ros.sensing.plant_map import GnssFix, MapSettings, Placement, PlantPlacer
from planter_ros.sensing.row_speed import RowSpeedStream

from planter_ros.kinematics.planting import Planting

from .model import PlantPredictor, PredictionSettings, planting_model_from_design
from .plants import Plants
from .quality import QualityIndices, SpacingQuality
from .sections import SectionBreaks
from .seedlings import SeedlingAccount, design_spacing_of, seedling_spacings

__all__ = ['MACHINE', 'MonitorPipeline', 'Placed', 'joint_index']

MACHINE = -1           # the `row` of the whole machine's indices (spacing_quality's first line)


# ((row index, its spacing-quality indices), ...): the machine's (row MACHINE) first
SpacingQualities = tuple[tuple[int, QualityIndices], ...]


@dataclass
class _Predicting:
    """What a design starts for the planting rows (a new sequence): its planting model, each
    row's joint name and predictor, and the rows' ground speeds."""

    model: Planting
    joints: list[str]
    predictors: list[PlantPredictor]
    speeds: RowSpeedStream


@dataclass(frozen=True)
class Placed:
    """A batch of plants released by the map, and what the monitor publishes with it."""

    plants: Plants
    placement: Placement
    upright_rate: float            # the machine's rolling upright rate after them (NaN: none)
    quality: SpacingQualities      # MonitorPipeline.spacing_quality()


def joint_index(names: Sequence[str], positions: Sequence[float], name: str) -> int | None:
    """Index of the joint `name` in a JointState's names and positions (the only one if the
    message names none), or None."""
    if name in names:
        i = list(names).index(name)
    elif not names and len(positions) == 1:
        i = 0
    else:
        return None
    return i if len(positions) > i else None


class MonitorPipeline:
    """The monitor's pipeline for the machine's `rows` (module doc). Nothing is predicted before
    the first design (`set_design`); samples before it still move the map."""

    def __init__(self, rows: Sequence[Row], settings: PredictionSettings,
                 map_settings: MapSettings,
                 antenna_position: Sequence[float]) -> None:
        self.rows = tuple(rows)
        self.planting = tuple(row for row in self.rows if row.enabled)
        self.settings = settings
        self._antenna = tuple(antenna_position)
        self._placer = self._new_placer(map_settings)
        self._sections = SectionBreaks()
        self._seedlings = SeedlingAccount({row.index: row.seedling_sensor for row in self.rows})
        self._quality = {row.index: SpacingQuality() for row in self.planting}
        self._machine_quality = SpacingQuality()
        self.mechanism: str | None = None        # the mechanism of the design in force
        self._on: _Predicting | None = None      # from the first design on
        self._recent: deque[float] = deque()
        self.plants = 0                           # plants released so far
        self.row_plants = {row.index: 0 for row in self.planting}
        self.last: Plants | None = None           # the last batch released
        self.upright_rate: float | None = None    # the rate after it

    # -- configuration -------------------------------------------------------------------
    def _new_placer(self, settings: MapSettings) -> PlantPlacer[Plants]:
        return PlantPlacer(settings, self._antenna,
                           {row.index: row.lateral_offset for row in self.rows},
                           {row.index: row.longitudinal_offset for row in self.rows})

    def _start_predictors(self, model: Planting, joints: list[str]) -> _Predicting:
        """Fresh predictors (and row speeds) for every planting row: a new sequence."""
        predictors = [PlantPredictor(model, self.settings, row=row.index, speed_filter=False)
                      for row in self.planting]
        speeds = RowSpeedStream([row.lateral_offset for row in self.planting],
                                self.settings.speed_limits, yaw=True)
        self._recent = deque(maxlen=self.settings.window)
        return _Predicting(model, joints, predictors, speeds)

    @property
    def model(self) -> Planting | None:
        """The design in force (its planting model); None before the first."""
        return None if self._on is None else self._on.model

    @property
    def has_design(self) -> bool:
        return self._on is not None

    def set_design(self, t: float, design: Design) -> bool:
        """A design arrived at `t` (s). The first one, or one of another mechanism, starts a new
        sequence (returns True); another of the same mechanism is in force from each row's next
        planting instant, as in the sync law. Raises ValueError or ConfigError (nothing
        changed) for a design the model cannot use."""
        model = planting_model_from_design(design)
        mechanism = design.mechanism
        if self._on is None or mechanism != self.mechanism:
            self.mechanism = mechanism
            self._on = self._start_predictors(model, [row.joint(mechanism)
                                                      for row in self.planting])
            return True
        self._on.model = model
        for predictor in self._on.predictors:
            predictor.change_model(model, t)
        return False

    def set_settings(self, settings: PredictionSettings) -> None:
        """New prediction settings: a new sequence starts (once there is a design)."""
        self.settings = settings
        if self._on is not None:
            self._on = self._start_predictors(self._on.model, self._on.joints)

    def set_map(self, settings: MapSettings) -> list[Placed]:
        """A new map from here on: the plants held so far are released placed by the old one."""
        out = self._released(self._placer.flush())
        self._placer = self._new_placer(settings)
        return out

    # -- inputs --------------------------------------------------------------------------
    def speed(self, t: float, v: float, yaw_rate: float) -> list[Placed]:
        """A ground-speed sample stamped `t`: v (m/s), ω_z (rad/s)."""
        on = self._on
        if on is None:
            return []
        motion = on.speeds.motion(t, v, yaw_rate)
        if motion is None:
            return []
        t, v, w = motion
        out = self._released(self._placer.add_motion(t, v, w))
        for predictor, speed in zip(on.predictors, on.speeds.speeds(v, w).tolist()):
            out += self._predicted(on, predictor.add_speed(t, speed))
        return out

    def joints(self, t: float, names: Sequence[str], positions: Sequence[float],
               velocities: Sequence[float] = ()) -> list[Placed]:
        """A joint-state sample stamped `t`: each planting row's joint found by name (rad,
        rad/s; a velocity missing is NaN)."""
        on = self._on
        if on is None:
            return []
        out: list[Placed] = []
        for predictor, name in zip(on.predictors, on.joints):
            i = joint_index(names, positions, name)
            if i is None:
                continue
            velocity = velocities[i] if len(velocities) > i else math.nan
            out += self._predicted(on, predictor.add_joint(t, positions[i], velocity))
        return out

    def fix(self, fix: GnssFix[float]) -> list[Placed]:
        """A GNSS fix (sensor_msgs/NavSatFix's fields): it may place plants held."""
        return self._released(self._placer.add_fix(fix))

    def sections(self, t: float, states: Mapping[str, bool]) -> None:
        """The rows' section states {row name: on} at `t`: a row switched off and on again
        starts a new sequence (its next plant has no spacing)."""
        ended = {row: (start, end) for row, start, end in self._sections.update(t, states)}
        if not ended or self._on is None:
            return
        for predictor, row in zip(self._on.predictors, self.planting):
            if row.name in ended:
                predictor.add_break(*ended[row.name])

    def seedlings(self, t: float, names: Sequence[str], counts: Sequence[float]) -> bool:
        """A seedling sensor reading stamped `t`: each planting row's count by its joint name,
        for the row's next planting instant (prediction.seedlings). False when the reading is
        skipped because it names no row on a machine of several rows: it belongs to none of
        them for sure and is not credited to every row (replay skips it the same way)."""
        if self._on is None:
            return True
        if not names and len(self.planting) > 1:
            return False
        for row, name in zip(self.planting, self._on.joints):
            i = joint_index(names, counts, name)
            if i is not None:
                self._seedlings.add_reading(row.index, t, counts[i])
        return True

    def finish(self) -> list[Placed]:
        """The inputs ended: the plants whose arcs were still open, then every plant still held
        for fixes, placed with the fixes there are."""
        out: list[Placed] = []
        if self._on is not None:
            for predictor in self._on.predictors:
                out += self._predicted(self._on, predictor.finish())
        return out + self._released(self._placer.flush())

    # -- outputs -------------------------------------------------------------------------
    def spacing_quality(self) -> SpacingQualities:
        """((MACHINE, the machine's indices), then (row index, indices) of every planting
        row): the machine first, so a viewer finds it at the same place whatever the rows."""
        return ((MACHINE, self._machine_quality.result()),) + tuple(
            (row.index, self._quality[row.index].result()) for row in self.planting)

    def _predicted(self, on: _Predicting, plants: Plants) -> list[Placed]:
        """Plants just predicted: their seedlings and status, then to the map."""
        if not len(plants):
            return []
        plants = self._seedlings.apply(plants, design_spacing_of(plants, on.model.spacing))
        return self._released(self._placer.add_plants(plants))

    def _released(self, placed: list[tuple[Plants, Placement]]) -> list[Placed]:
        batches = [(plants, placement) for plants, placement in placed if len(plants)]
        if not batches:
            return []
        if self._on is None:     # plants come from a design's predictors: never before one
            raise RuntimeError('the plant map released plants before any design')
        return [self._publish(self._on.model, plants, placement)
                for plants, placement in batches]

    def _publish(self, model: Planting, plants: Plants, placement: Placement) -> Placed:
        """Account a released batch: the rolling upright rate, the spacing quality, counts."""
        self._recent.extend(u for u in plants.upright.tolist() if math.isfinite(u))
        rate = float(sum(self._recent) / len(self._recent)) if self._recent else math.nan
        design_spacing = design_spacing_of(plants, model.spacing)
        for row in set(plants.row.astype(int).tolist()):
            mine = plants.row == row
            x, x_d = seedling_spacings(Plants.from_table(plants.table()[mine]),
                                       design_spacing[mine])
            self._quality.setdefault(row, SpacingQuality()).add(x, x_d)
        self._machine_quality.add(*seedling_spacings(plants, design_spacing))
        self.plants += len(plants)
        for row in plants.row.astype(int).tolist():
            self.row_plants[row] = self.row_plants.get(row, 0) + 1
        self.last, self.upright_rate = plants, rate
        return Placed(plants, placement, rate, self.spacing_quality())

