"""Replay: re-run the plant prediction model on a recorded bag, far faster than real time.

Reads any rosbag2 MCAP (a .mcap file, or a bag directory of split files) with the ground speed,
joint states and design topics of the contract (planter_ros.interfaces), through
recording.bag_reader (raw CDR; damaged files read up to what is intact) and recording.cdr (the
few fields the model needs, decoded in bulk). The monitor's settings recorded in the bag are
used unless overridden.

The live monitor's rules are applied the same way: samples before the first design are not
predicted, a changed design is in force from the next planting instant after its message (the
plant set next is the old design's last; planter_ros.prediction), a design of another
mechanism starts a new sequence, stamps of 0 mean "use the receive (log) time". A machine
with several rows (the bag's rows record, interfaces.ROWS_RECORD) is predicted row by row
(all rows in one call: prediction.predict_rows), each from its own joint and its own travelled
distance (ground speed, yaw rate `twist.angular.z` and the row's lateral offset:
sensing.row_speed), and summarised per row; a bag without the record has one row, the joint
`sun_bar` / `carrier`.

Like the monitor, replay places each plant on the earth from the recorded GNSS fixes
(sensing.plant_map, with the antenna position and map settings of the bag's map record), ends a
row's spacing sequence where the sync node's `sections` say its section was switched off (in a
bag recorded before that topic: its /diagnostics), and judges the spacings by the ISO 7256-1
indices (prediction.quality), per row and overall.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import json
from typing import TYPE_CHECKING, TypeVar
from pathlib import Path
import struct

import numpy as np
from numpy.typing import NDArray

from planter_ros import config, diagnostics, interfaces
from planter_ros.config import ConfigError
from planter_ros.design import Design, from_json, to_dict
from planter_ros.geo import AntennaSettings
from planter_ros.kinematics.arrays import FloatArray
from planter_ros.kinematics.planting import Planting
from planter_ros.kinematics.design_inputs import DesignInputs
from planter_ros.prediction import (
    PLANT_FIELDS, Acceptance, AcceptanceLimits, Plants, PredictionSettings, RowInputs,
    SeedlingAccount, design_spacing_of, judge_acceptance, planting_model_from_design,
    predict_rows, prediction_notes, section_breaks, summarize)
from planter_ros.rows import Row, implicit_row, rows_from_record
from planter_ros.sensing.plant_map import (
    GnssFix, MapSettings, Placement, PlantSpots, fix_sigma, place_plants)
from planter_ros.sensing.row_speed import motion_samples, row_speed_samples

from .bag_reader import Recording, TopicMessages, read_recording
from .cdr import (
    decode_joint_states, decode_joints, decode_navsatfix, decode_string, decode_twist, take)
from .errors import DecodeError, ReplayError, TopicMissingError

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

    from planter_ros.prediction.model import PredictionNote
    from planter_ros.prediction.summary import RunSummary

_D = TypeVar('_D', bound='DataclassInstance')
# a design message: (log ns, its JSON text, the design, its planting model)
_DesignEntry = tuple[int, str, Design, Planting]

REQUIRED = (interfaces.GROUND_SPEED, interfaces.JOINT_STATES, interfaces.DESIGN)
OPTIONAL = (interfaces.GNSS_FIX, interfaces.SECTIONS, interfaces.DIAGNOSTICS,
            interfaces.SEEDLINGS)


@dataclass
class ReplayResult:
    path: str
    design: Design
    settings: PredictionSettings
    plants: Plants
    summary: RunSummary
    duration: float               # s of log time covered by the inputs
    messages: dict[str, int]      # topic name -> messages used, and 'total_read'
    warnings: list[str]
    recorded_plants: np.ndarray   # the live monitor's plant table, if recorded (n, fields)
    rows: list[Row]               # the machine's rows (one without a record)
    row_summaries: list[RunSummary]   # of each row's plants, in `rows` order
    placement: Placement          # each plant in the map's local frame (sensing.plant_map)
    notes: list[PredictionNote]   # what some figures mean (prediction_notes)
    map_settings: MapSettings
    antenna: AntennaSettings
    fixes: int                    # usable GNSS fixes in the bag
    nozzle_width: float           # m, of the last design's predictions
    recorded_fields: tuple[str, ...]  # the PLANT_FIELDS the live recording has (older: fewer)
    acceptance: Acceptance        # the run judged by the crop's limits (judge_acceptance)
    acceptance_source: str        # whose limits: the bag's, a scene's, the defaults
    seedling_readings: dict[int, tuple[FloatArray, FloatArray]]  # {row: (times s, counts)}

    def recorded_columns(self) -> list[int]:
        """Indices of the plant fields the live recording has: replay and the recording can
        be compared on these."""
        return [PLANT_FIELDS.index(f) for f in self.recorded_fields]

    def as_json(self, plants: bool = True) -> dict[str, object]:
        """replay --json's object; `plants` False: without the plants (a caller that takes
        them from `self.plants` as arrays)."""
        out: dict[str, object] = {'bag': self.path, 'design': to_dict(self.design),
                'settings': config.as_dict(self.settings),
                'map': {**config.as_dict(self.map_settings), **config.as_dict(self.antenna),
                        'fixes': self.fixes,
                        'origin': None if self.placement.origin is None else
                        list(self.placement.origin)},
                'nozzle_width': self.nozzle_width,
                'duration': self.duration, 'messages': self.messages,
                'summary': self.summary,
                'rows': [{**row.as_dict(), 'summary': summary}
                         for row, summary in zip(self.rows, self.row_summaries)],
                'acceptance': {**(self.acceptance or {}), 'source': self.acceptance_source},
                'plants': None, 'notes': self.notes or [],
                'warnings': self.warnings}
        if plants:
            out['plants'] = self.plants.rows()
        else:
            del out['plants']
        return out


def settings_from_recording(recorded: Mapping[str, object],
                            overrides: Mapping[str, object] | None = None,
                            warnings: list[str] | None = None) -> PredictionSettings:
    """The monitor's recorded settings (strings), overridden by explicit values. A recorded
    value out of range is replaced by the default (with a warning); a bad override is an
    error (ConfigError). A monitor that recorded its settings before `measured_arc` existed
    predicted from the speed ratio at each planting instant: replay does the same."""
    values: dict[str, object] = {}
    if recorded and 'measured_arc' not in recorded:
        values['measured_arc'] = False
    for spec in config.specs(PredictionSettings):
        if spec.name in recorded:
            try:
                values[spec.name] = config.coerce(spec, recorded[spec.name])
            except config.ConfigError as exc:
                if warnings is not None:
                    warnings.append(f'recorded setting ignored, default used: {exc}')
    values.update({k: v for k, v in (overrides or {}).items() if v is not None})
    return config.from_mapping(PredictionSettings, values)


def replay(path: str | Path, settings_overrides: Mapping[str, object] | None = None,
           with_recorded: bool = False, fallback_design: Design | None = None,
           acceptance: AcceptanceLimits | None = None) -> ReplayResult:
    """Re-run the prediction model on a bag. Raises a RecordingError for a bag it cannot use
    (BagUnreadableError, TopicMissingError, ReplayError: recording.errors) and ConfigError
    for a bad setting override (`nozzle_width` among them replaces the design's).
    `fallback_design` (a Design, e.g. of the scene the run used) stands in for the whole
    bag when it holds no usable design message (lost in a damaged part); it is ignored, with a
    warning, when the bag has its own. `acceptance` (AcceptanceLimits, e.g. a scene's; or the
    override `acceptance`, a mapping of them) replaces the limits the bag recorded (without
    either: the defaults) in the run's judgement."""
    overrides = dict(settings_overrides or {})
    nozzle = overrides.pop('nozzle_width', None)
    nozzle_override: float | None = None if nozzle is None else config.coerce(
        config.spec_of(DesignInputs, 'nozzle_width'), nozzle)
    given = overrides.pop('acceptance', None)       # a scene's limits as a mapping
    if acceptance is None and given is not None:
        if not isinstance(given, Mapping):
            raise ConfigError(f'acceptance = {given!r} is not a mapping of limits')
        acceptance = config.from_mapping(AcceptanceLimits, given)
    wanted = REQUIRED + OPTIONAL + ((interfaces.PLANTS,) if with_recorded else ())
    rec = read_recording(path, wanted)
    required = REQUIRED if fallback_design is None else REQUIRED[:2]
    missing = [t for t in required if t not in rec.topics]
    if missing:
        found = ', '.join(f'{n} ({t})' for n, t in sorted(rec.all_topics.items())) or 'none'
        want = ', '.join(f'.../{t.name} ({t.type_name})' for t in missing)
        raise TopicMissingError(f'bag {path} lacks {want}; topics found: {found}')
    design_topic = rec.topics.get(interfaces.DESIGN)
    recorded_settings = rec.metadata.get(interfaces.PREDICTION_SETTINGS_RECORD, {})
    settings = settings_from_recording(recorded_settings, overrides, rec.warnings)
    map_settings, antenna = map_from_recording(rec.metadata.get(interfaces.MAP_RECORD, {}),
                                               rec.warnings)
    widths = _NozzleWidth(nozzle_override, recorded_settings)

    designs: list[_DesignEntry] = []         # each change
    undecodable = 0
    for log, raw in sorted(zip(design_topic.log, design_topic.raw) if design_topic else (),
                           key=lambda x: x[0]):
        try:
            text = decode_string(raw)
        except (DecodeError, IndexError, struct.error):
            undecodable += 1     # empty, cut short or not UTF-8
            continue
        if designs and designs[-1][1] == text:
            continue
        try:
            design = from_json(text)
            model = planting_model_from_design(design, widths.width(design))
        except ValueError as exc:    # a ConfigError (ours) or a foreign JSON error
            rec.warnings.append(f'design message at {log * 1e-9:.3f} s ignored: '
                                f'{str(exc).splitlines()[0]}')
            continue
        designs.append((log, text, design, model))
    if undecodable:
        rec.warnings.append(f'{undecodable} design message(s) could not be decoded (empty, cut '
                            'short or not UTF-8 text): skipped')
    if fallback_design is not None:
        if designs:
            rec.warnings.append("the bag holds its own design: the scene's design is not used "
                                '(its acceptance limits are)')
        else:
            try:
                model = planting_model_from_design(fallback_design,
                                                   widths.width(fallback_design))
            except ConfigError as exc:
                raise ReplayError(f'the scene given has no usable design: {exc}') from None
            designs.append((int(np.iinfo(np.int64).min), '', fallback_design, model))
            rec.warnings.append('the bag holds no usable design message: the whole bag is '
                                "predicted with the scene's design")
    if not designs:
        what = 'no usable design message' if design_topic and design_topic.raw else \
            'no design message'
        lost = f'; {len(rec.losses)} part(s) of it are lost ({rec.losses[0]}), the design may '\
            "have been there: give the run's scene (--scene FILE)" if rec.losses else ''
        raise ReplayError(f'bag {path} has {what}{lost}')

    rows = [implicit_row()]
    if interfaces.ROWS_RECORD in rec.metadata:
        recorded_rows = rows_from_record(rec.metadata[interfaces.ROWS_RECORD])
        if recorded_rows:
            rows = recorded_rows
        else:
            rec.warnings.append(f'rows record {interfaces.ROWS_RECORD!r} unreadable: one row '
                                'assumed')
    planting = [row for row in rows if row.enabled]
    offsets = [row.lateral_offset for row in planting]
    breaks = _section_breaks(rec, planting)

    speed = rec.topics[interfaces.GROUND_SPEED]
    joint = rec.topics[interfaces.JOINT_STATES]
    s_log = np.asarray(speed.log, dtype=np.int64)
    j_log = np.asarray(joint.log, dtype=np.int64)
    s_order = np.argsort(s_log, kind='stable')
    j_order = np.argsort(j_log, kind='stable')
    s_log = s_log[s_order]
    j_log = j_log[j_order]
    s_stamp, s_v, s_w = decode_twist(take(speed.raw, s_order))
    _count_undecodable(rec.warnings, interfaces.GROUND_SPEED.name, s_stamp, s_v)
    fixes_topic = rec.topics.get(interfaces.GNSS_FIX)
    fixes = _fixes(fixes_topic)          # the map's dead reckoning needs the yaw rate
    parts, motions = [], []
    segments = _mechanism_segments(designs)
    for k, (log, group) in enumerate(segments):
        end = segments[k + 1][0] if k + 1 < len(segments) else np.iinfo(np.int64).max
        mechanism = group[0][2].mechanism
        s_sel = (s_log > log) & (s_log <= end)
        j_idx = np.nonzero((j_log > log) & (j_log <= end))[0]
        st = np.where(s_stamp[s_sel] != 0, s_stamp[s_sel], s_log[s_sel]) * 1e-9
        # the machine's motion as the rows use it, and each row's own speed v − ω_z·y,
        # filtered as the sync node and the monitor do
        twist = (st, s_v[s_sel], s_w[s_sel])
        motion = motion_samples(twist, offsets, settings.speed_limits,
                                yaw=True if fixes[0].size else None)
        motions.append(motion)
        rt, rv = row_speed_samples(twist, offsets, settings.speed_limits, motion=motion)
        raws = take(joint.raw, j_order[j_idx])
        j_stamp, j_positions, j_velocities = decode_joints(
            raws, [row.joint(mechanism) for row in planting])
        # a change before the first joint sample is in force at once (nothing turned yet),
        # a later one from the next planting instant after its message, as the live monitor
        first_joint = j_log[j_idx[0]] if j_idx.size else np.iinfo(np.int64).max
        model = [m for t, _, _, m in group if t < first_joint or t == log][-1]
        changes = [(t * 1e-9, m) for t, _, _, m in group if t >= first_joint and t != log]
        if planting:
            _count_undecodable(rec.warnings, interfaces.JOINT_STATES.name, j_stamp,
                               j_positions[0])
            _unusable_joints(rec.warnings, planting, mechanism, j_stamp, j_positions)
        jt = np.where(j_stamp != 0, j_stamp, j_log[j_idx]) * 1e-9
        # another mechanism starts a new sequence, numbered from 0 like the live monitor; the
        # rows predicted together (their arcs in one pass)
        segment = predict_rows(
            [RowInputs(rt, rv[r], jt, j_positions[r], j_velocities[r], row.index,
                       breaks.get(row.name, ())) for r, row in enumerate(planting)],
            model, settings, speed_filter=False, changes=changes)
        order = np.argsort(segment.time, kind='stable')
        parts.append(segment.take(order))
    plants = Plants.concatenate(parts)
    # each instant's seedlings from the rows' cup sensors (prediction.seedlings): its status,
    # and spacings between the seedlings in the ground
    design_spacing = design_spacing_of(plants, designs[-1][3].spacing)
    account = _seedlings(rec, plants, planting, segments)
    plants = account.apply(plants, design_spacing)
    offset_of = {row.index: row.lateral_offset for row in rows}
    forward_of = {row.index: row.longitudinal_offset for row in rows}
    spots = PlantSpots(plants.time, [offset_of.get(int(r), 0.0) for r in plants.row],
                       [forward_of.get(int(r), 0.0) for r in plants.row])
    placement = place_plants(spots, tuple(np.concatenate(c) for c in zip(*motions)), fixes,
                             map_settings, antenna.antenna_position)
    plants.latitude, plants.longitude = placement.latitude, placement.longitude
    usable_fixes = int(np.count_nonzero(np.isfinite(fix_sigma(fixes,
                                                              map_settings.max_fix_sigma))))
    last_design, last_model = designs[-1][2], designs[-1][3]
    logs = np.concatenate((s_log, j_log))
    recorded = np.zeros((0, len(PLANT_FIELDS)))
    recorded_fields: tuple[str, ...] = ()
    if with_recorded and interfaces.PLANTS in rec.topics:
        recorded, recorded_fields = _recorded_plants(rec.topics[interfaces.PLANTS])
    if widths.fallback_used:
        rec.warnings.append(widths.fallback_used)
    limits, source = _acceptance_limits(acceptance, rec.metadata, rec.warnings)
    summary = summarize(plants, last_model.spacing, design_spacing)
    row_summaries = [summarize(_of_row(plants, row.index), last_model.spacing,
                               design_spacing[plants.row == row.index]) for row in rows]
    named = len(rows) > 1 or bool(rows[0].name)
    # (judge_acceptance takes plain dicts: a copy of each summary)
    judged = ([(row.label, dict(s)) for row, s in zip(rows, row_summaries) if row.enabled]
              if named else [('', dict(summary))])
    return ReplayResult(
        path=str(path), design=last_design, settings=settings, plants=plants,
        summary=summary, rows=rows, row_summaries=row_summaries,
        acceptance=judge_acceptance(limits, judged), acceptance_source=source,
        duration=float((logs.max() - logs.min()) * 1e-9) if logs.size else 0.0,
        messages={interfaces.GROUND_SPEED.name: int(s_log.size),
                  interfaces.JOINT_STATES.name: int(j_log.size),
                  interfaces.DESIGN.name: len(design_topic.raw) if design_topic else 0,
                  interfaces.GNSS_FIX.name: len(fixes_topic.raw) if fixes_topic else 0,
                  'total_read': rec.message_count},
        warnings=rec.warnings, recorded_plants=recorded, recorded_fields=recorded_fields,
        placement=placement,
        notes=prediction_notes(last_design, last_model), map_settings=map_settings,
        antenna=antenna, nozzle_width=last_model.nozzle_width,
        fixes=usable_fixes, seedling_readings=account.readings())


def _seedlings(rec: Recording, plants: Plants, planting: Sequence[Row],
               segments: Sequence[tuple[int, list[_DesignEntry]]]) -> SeedlingAccount:
    """A SeedlingAccount holding every reading of the bag's seedling sensor (by row), each row
    with a sensor or without as its rows record declares it (a bag before the setting: not
    declared, inferred from the readings)."""
    account = SeedlingAccount({row.index: row.seedling_sensor for row in planting})
    topic = rec.topics.get(interfaces.SEEDLINGS)
    if topic is None or not topic.raw:
        return account
    order = np.argsort(np.asarray(topic.log, dtype=np.int64), kind='stable')
    raws = take(topic.raw, order)
    logs = np.asarray(topic.log, dtype=np.int64)[order]
    mechanisms = {group[0][2].mechanism for _, group in segments}
    joints = [(row, row.joint(mechanism)) for row in planting for mechanism in mechanisms]
    stamp, counts, _ = decode_joints(raws, [joint for _, joint in joints] + [None])
    t = np.where(stamp != 0, stamp, logs) * 1e-9
    # a reading without names is one row's only on a machine of one row; on several it is
    # no row's for sure: not credited to each of them (the live monitor skips it too)
    unnamed = np.isfinite(counts[-1]) if len(planting) > 1 else np.zeros(t.size, dtype=bool)
    if unnamed.any():
        rec.warnings.append(f'{int(unnamed.sum())} seedling reading(s) without a row name on '
                            f'a machine of {len(planting)} rows: skipped')
    for (row, _), count in zip(joints, counts[:-1]):
        ok = np.isfinite(count) & ~unnamed
        account.add_readings(row.index, t[ok], count[ok])
    return account


def _acceptance_limits(given: AcceptanceLimits | None,
                       metadata: Mapping[str, Mapping[str, str]],
                       warnings: list[str]) -> tuple[AcceptanceLimits, str]:
    """(AcceptanceLimits, whose): the limits given, else the bag's record, else the defaults.
    A recorded value out of range is replaced by its default, with a warning."""
    if given is not None:
        return given, 'the scene given'
    recorded = metadata.get(interfaces.ACCEPTANCE_RECORD)
    if recorded is None:
        return AcceptanceLimits(), 'the defaults: the bag records no limits'
    values: dict[str, object] = {}
    for spec in config.specs(AcceptanceLimits):
        if spec.name in recorded:
            try:
                values[spec.name] = config.coerce(spec, recorded[spec.name])
            except ConfigError as exc:
                warnings.append(f'recorded acceptance limit ignored, default used: {exc}')
    return config.from_mapping(AcceptanceLimits, values), "the run's scene, recorded in the bag"


class _NozzleWidth:
    """Which nozzle width a design is predicted with: the override, else the design's own, else
    (a bag recorded before the nozzle width was a scene value) the monitor's recorded setting,
    else 0 m, with a warning."""

    def __init__(self, override: float | None, recorded: Mapping[str, str]) -> None:
        self.override = override
        self.recorded = recorded.get('nozzle_width')
        self.fallback_used = ''

    def width(self, design: Design) -> float | None:
        if self.override is not None:
            return self.override
        if design.nozzle_width is not None:
            return None                          # the design's own
        width = _number(self.recorded)
        if width is None:
            width = 0.0
            self.fallback_used = ('the design gives no nozzle_width and the bag records none: '
                                  'holes are the tip sweep alone (nozzle width 0 m); give '
                                  '--nozzle-width M')
        return width


def _number(text: str | None) -> float | None:
    """`text` as a float; None when there is none or it is not a number."""
    if text is None:
        return None
    try:
        return float(text)
    except ValueError:
        return None


def map_from_recording(record: Mapping[str, str], warnings: list[str] | None = None
                       ) -> tuple[MapSettings, AntennaSettings]:
    """(MapSettings, AntennaSettings) of the monitor's map record (values as JSON text); the
    defaults for a bag without it, or for a value it cannot use (with a warning)."""
    values: dict[str, object] = {}
    for key, text in record.items():
        try:
            values[key] = json.loads(text)
        except (TypeError, ValueError):
            if warnings is not None:
                warnings.append(f'map record value {key} = {str(text)[:40]!r} is not JSON: '
                                'default used')
    return (_from_record(MapSettings, values, warnings),
            _from_record(AntennaSettings, values, warnings))


def _from_record(cls: type[_D], values: Mapping[str, object],
                 warnings: list[str] | None) -> _D:
    try:
        return config.from_mapping(cls, values)
    except ConfigError as exc:
        if warnings is not None:
            warnings.append(f'recorded map setting ignored, defaults used: {exc}')
        return cls()


def map_record(map_settings: MapSettings, antenna: AntennaSettings) -> dict[str, str]:
    """The bag metadata record (interfaces.MAP_RECORD) of the monitor's map: values as JSON."""
    return {k: json.dumps(v) for k, v in {**config.as_dict(map_settings),
                                          **config.as_dict(antenna)}.items()}


def _fixes(topic: TopicMessages | None) -> GnssFix[FloatArray]:
    """The recorded fixes of `topic` in log order, arrays (none without it); t: the header
    stamp (the receive time if 0)."""
    if topic is None or not topic.raw:
        return GnssFix(*(np.zeros(0) for _ in range(7)))
    log = np.asarray(topic.log, dtype=np.int64)
    order = np.argsort(log, kind='stable')
    stamp, status, latitude, longitude, var_east, var_north, cov_type = decode_navsatfix(
        take(topic.raw, order))
    t = np.where(stamp != 0, stamp, log[order]) * 1e-9
    return GnssFix(t, status, latitude, longitude, var_east, var_north, cov_type)


def _section_breaks(rec: Recording,
                    planting: Sequence[Row]) -> dict[str, list[tuple[float, float]]]:
    """{row name: [(start, end)]} when each row's section was off, from the sync node's
    `sections` in the bag; a bag recorded before that topic: from its /diagnostics."""
    topic = rec.topics.get(interfaces.SECTIONS)
    if topic is None or not topic.raw:
        return _diagnostics_section_breaks(rec.topics.get(interfaces.DIAGNOSTICS), planting)
    log = np.asarray(topic.log, dtype=np.int64)
    states: list[dict[str, bool]] = [{} for _ in topic.raw]   # each message's {row: on}
    times = log * 1e-9
    for k, row in enumerate(planting):
        stamp, position, _ = decode_joint_states(topic.raw, row.name)
        if k == 0:
            times = np.where(stamp != 0, stamp, log) * 1e-9
        for state, value in zip(states, position.tolist()):
            state.update(interfaces.section_states([row.name], [value]))
    return section_breaks(sorted(zip(times.tolist(), states), key=lambda r: r[0]))


def _diagnostics_section_breaks(topic: TopicMessages | None, planting: Sequence[Row]
                                ) -> dict[str, list[tuple[float, float]]]:
    """{row name: [(start, end)]} from the section states of the sync node's /diagnostics in a
    bag recorded before the `sections` topic (diagnostics.section_states)."""
    if topic is None or not topic.raw:
        return {}
    names = {row.name for row in planting}
    reports = []
    for log, raw in sorted(zip(topic.log, topic.raw), key=lambda x: x[0]):
        if b'section' not in bytes(raw):       # not the sync node's: not decoded
            continue
        try:
            msg = diagnostics.decode(raw)
        except ValueError:
            continue
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        states = {k: v for k, v in diagnostics.section_states(msg.status).items()
                  if k in names}
        if states:
            reports.append(((stamp or log) * 1e-9, states))
    reports.sort(key=lambda r: r[0])
    return section_breaks(reports)


def _mechanism_segments(designs: Sequence[_DesignEntry]
                        ) -> list[tuple[int, list[_DesignEntry]]]:
    """The design messages (log ns, text, design, model) grouped into runs of one mechanism:
    [(log ns of the run's first, [its designs])]. Within a run a change is in force from the
    next planting instant; another mechanism is another machine and starts a new sequence."""
    segments: list[tuple[int, list[_DesignEntry]]] = []
    for entry in designs:
        mechanism = entry[2].mechanism
        if segments and segments[-1][1][0][2].mechanism == mechanism:
            segments[-1][1].append(entry)
        else:
            segments.append((entry[0], [entry]))
    return segments


def _count_undecodable(warnings: list[str], name: str, stamps: NDArray[np.int64],
                       values: FloatArray) -> None:
    """cdr's bulk decoders leave a message they cannot decode at stamp 0 and value NaN."""
    bad = int(np.count_nonzero((stamps == 0) & np.isnan(values)))
    if bad:
        warnings.append(f'{bad} {name} message(s) could not be decoded: skipped')


def _unusable_joints(warnings: list[str], planting: Sequence[Row], mechanism: str,
                     stamps: NDArray[np.int64], positions: FloatArray) -> None:
    """A row whose recorded joint positions are all NaN (decoded, not one finite) predicts
    no plant: say so, once per row, rather than report nothing planted in silence."""
    decoded = stamps != 0
    for row, values in zip(planting, positions):
        count = int(np.count_nonzero(decoded))
        if count and not np.any(np.isfinite(values[decoded])):
            text = (f'{row.label}: all {count} recorded positions of joint '
                    f'{row.joint(mechanism)} are NaN: no plant can be predicted from them')
            if text not in warnings:
                warnings.append(text)


def _of_row(plants: Plants, index: int) -> Plants:
    return plants.take(plants.row == index)


def _recorded_plants(topic: TopicMessages) -> tuple[FloatArray, tuple[str, ...]]:
    """(table, fields): the live monitor's plants in PLANT_FIELDS order, by the labels of each
    message (a field the recording lacks is NaN, e.g. tip_sweep and the map position in a
    recording made before them; `row` is 0 in a recording made before rows existed), and the
    fields it has."""
    # lazy: rclpy costs 64 ms and only the comparison with the plants the live monitor
    # recorded (with_recorded) reads them; replay itself imports no rclpy (test_offline_imports)
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import Float64MultiArray  # lazy: as rclpy above
    tables, seen = [], set()
    for _, raw in sorted(zip(topic.log, topic.raw), key=lambda x: x[0]):
        try:
            msg = deserialize_message(bytes(raw), Float64MultiArray)
        except Exception:            # rclpy raises its own errors for bytes that are not CDR
            continue
        width = msg.layout.dim[1].size if len(msg.layout.dim) > 1 else 0
        if not width:
            continue
        data = np.asarray(msg.data, dtype=float).reshape(-1, width)
        labels = msg.layout.dim[1].label.split(',')
        table = np.full((data.shape[0], len(PLANT_FIELDS)), np.nan)
        if 'row' not in labels:
            table[:, PLANT_FIELDS.index('row')] = 0.0
            seen.add('row')
        for i, label in enumerate(labels[:width]):
            if label in PLANT_FIELDS:
                table[:, PLANT_FIELDS.index(label)] = data[:, i]
                seen.add(label)
        tables.append(table)
    fields = tuple(f for f in PLANT_FIELDS if f in seen)
    return (np.vstack(tables) if tables else np.zeros((0, len(PLANT_FIELDS)))), fields
