"""Replay: re-run the plant prediction model on a recorded bag, far faster than real time.

Reads any rosbag2 MCAP (a .mcap file, or a bag directory of split files) with the ground speed,
joint states and design topics of the contract (planter_ros.interfaces), through
recording.bag_reader (raw CDR; damaged files read up to what is intact) and recording.cdr (the
few fields the model needs, decoded in bulk). The monitor's settings recorded in the bag are
used unless overridden.

The live monitor's rules are applied the same way: samples before the first design are not
predicted, a changed design is in force from the next planting instant after its message (the
plant set next is the old design's last; kinematics.plant_prediction), a design of another
mechanism starts a new sequence, stamps of 0 mean "use the receive (log) time". A machine
with several rows (the bag's rows record, interfaces.ROWS_RECORD) is predicted row by row,
each from its own joint and its own travelled distance (ground speed, yaw rate
`twist.angular.z` and the row's lateral offset: sensing.row_speed), and summarised per row; a
bag without the record has one row, the joint `sun_bar` / `carrier`.
"""

from dataclasses import dataclass
import json
import struct

import numpy as np

from planter_ros import config, interfaces
from planter_ros.config import ConfigError
from planter_ros.kinematics.plant_prediction import (
    PLANT_FIELDS, Plants, PredictionSettings, planting_model_from_design, predict_plants,
    summarize)
from planter_ros.rows import implicit_row, rows_from_record
from planter_ros.sensing.row_speed import row_speed_samples

from .bag_reader import BagError, read_recording
from .cdr import decode_joint_states, decode_string, decode_twist

REQUIRED = (interfaces.GROUND_SPEED, interfaces.JOINT_STATES, interfaces.DESIGN)


class ReplayError(ValueError):
    """A bag replay cannot use (one line: the file and what is wrong)."""


@dataclass
class ReplayResult:
    path: str
    design: dict
    settings: PredictionSettings
    plants: Plants
    summary: dict
    duration: float               # s of log time covered by the inputs
    messages: dict                # topic name -> messages used, and 'total_read'
    warnings: list
    recorded_plants: np.ndarray   # the live monitor's plant table, if recorded (n, fields)
    rows: list                    # planter_ros.rows.Row of the machine (one without a record)
    row_summaries: list           # summarize() of each planting row's plants, in `rows` order

    def as_json(self):
        return {'bag': self.path, 'design': self.design,
                'settings': config.as_dict(self.settings),
                'duration': self.duration, 'messages': self.messages,
                'summary': self.summary,
                'rows': [{**row.as_dict(), 'summary': summary}
                         for row, summary in zip(self.rows, self.row_summaries)],
                'plants': self.plants.rows(), 'warnings': self.warnings}


def settings_from_recording(recorded, overrides=None, warnings=None):
    """The monitor's recorded settings (strings), overridden by explicit values. A recorded
    value out of range is replaced by the default (with a warning); a bad override is an
    error (ConfigError)."""
    values = {}
    for spec in config.specs(PredictionSettings):
        if spec.name in recorded:
            try:
                values[spec.name] = config.coerce(spec, recorded[spec.name])
            except config.ConfigError as exc:
                if warnings is not None:
                    warnings.append(f'recorded setting ignored, default used: {exc}')
    values.update({k: v for k, v in (overrides or {}).items() if v is not None})
    return config.from_mapping(PredictionSettings, values)


def replay(path, settings_overrides=None, with_recorded=False, fallback_design=None):
    """Re-run the prediction model on a bag. Raises ReplayError for an unusable bag and
    ConfigError for a bad setting override. `fallback_design` (a design dict, e.g. of the scene
    the run used) stands in for the whole bag when it holds no usable design message (lost in
    a damaged part); it is ignored, with a warning, when the bag has its own."""
    wanted = REQUIRED + ((interfaces.PLANTS,) if with_recorded else ())
    try:
        rec = read_recording(path, wanted)
    except BagError as exc:
        raise ReplayError(str(exc)) from None
    required = REQUIRED if fallback_design is None else REQUIRED[:2]
    missing = [t for t in required if t not in rec.topics]
    if missing:
        found = ', '.join(f'{n} ({t})' for n, t in sorted(rec.all_topics.items())) or 'none'
        want = ', '.join(f'.../{t.name} ({t.type_name})' for t in missing)
        raise ReplayError(f'bag {path} lacks {want}; topics found: {found}')
    design_topic = rec.topics.get(interfaces.DESIGN)
    settings = settings_from_recording(
        rec.metadata.get(interfaces.PREDICTION_SETTINGS_RECORD, {}), settings_overrides,
        rec.warnings)

    designs = []         # (log ns, text, design, model) of each change
    undecodable = 0
    for log, raw in sorted(zip(design_topic.log, design_topic.raw) if design_topic else (),
                           key=lambda x: x[0]):
        try:
            text = decode_string(raw)
        except (ValueError, IndexError, struct.error):
            undecodable += 1     # empty, cut short or not UTF-8 (CdrError is a ValueError)
            continue
        if designs and designs[-1][1] == text:
            continue
        try:
            design = json.loads(text)
            model = planting_model_from_design(design)
        except (ValueError, ConfigError) as exc:
            rec.warnings.append(f'design message at {log * 1e-9:.3f} s ignored: '
                                f'{str(exc).splitlines()[0]}')
            continue
        designs.append((log, text, design, model))
    if undecodable:
        rec.warnings.append(f'{undecodable} design message(s) could not be decoded (empty, cut '
                            'short or not UTF-8 text): skipped')
    if fallback_design is not None:
        if designs:
            rec.warnings.append('the bag holds its own design: the scene given is not used')
        else:
            try:
                model = planting_model_from_design(fallback_design)
            except ConfigError as exc:
                raise ReplayError(f'the scene given has no usable design: {exc}') from None
            designs.append((np.iinfo(np.int64).min, '', fallback_design, model))
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
        rows = rows_from_record(rec.metadata[interfaces.ROWS_RECORD])
        if not rows:
            rec.warnings.append(f'rows record {interfaces.ROWS_RECORD!r} unreadable: one row '
                                'assumed')
            rows = [implicit_row()]
    planting = [row for row in rows if row.enabled]
    offsets = [row.lateral_offset for row in planting]

    speed = rec.topics[interfaces.GROUND_SPEED]
    joint = rec.topics[interfaces.JOINT_STATES]
    s_log = np.asarray(speed.log, dtype=np.int64)
    j_log = np.asarray(joint.log, dtype=np.int64)
    s_order = np.argsort(s_log, kind='stable')
    j_order = np.argsort(j_log, kind='stable')
    s_log = s_log[s_order]
    j_log = j_log[j_order]
    s_stamp, s_v, s_w = decode_twist([speed.raw[i] for i in s_order])
    _count_undecodable(rec.warnings, interfaces.GROUND_SPEED.name, s_stamp, s_v)
    parts = []
    segments = _mechanism_segments(designs)
    for k, (log, group) in enumerate(segments):
        end = segments[k + 1][0] if k + 1 < len(segments) else np.iinfo(np.int64).max
        mechanism = group[0][2].get('mechanism', 'five_bar')
        s_sel = (s_log > log) & (s_log <= end)
        j_idx = np.nonzero((j_log > log) & (j_log <= end))[0]
        st = np.where(s_stamp[s_sel] != 0, s_stamp[s_sel], s_log[s_sel]) * 1e-9
        # each row's own speed: v − ω_z·y, filtered as the sync node and the monitor do
        rt, rv = row_speed_samples(st, s_v[s_sel], s_w[s_sel], offsets, settings.speed_limits)
        raws = [joint.raw[j_order[i]] for i in j_idx]
        # a change before the first joint sample is in force at once (nothing turned yet),
        # a later one from the next planting instant after its message, as the live monitor
        first_joint = j_log[j_idx[0]] if j_idx.size else np.iinfo(np.int64).max
        model = [m for t, _, _, m in group if t < first_joint or t == log][-1]
        changes = [(t * 1e-9, m) for t, _, _, m in group if t >= first_joint and t != log]
        segment = []
        for r, row in enumerate(planting):
            j_stamp, j_pos, j_vel = decode_joint_states(raws, row.joint(mechanism))
            if r == 0:
                _count_undecodable(rec.warnings, interfaces.JOINT_STATES.name, j_stamp, j_pos)
            jt = np.where(j_stamp != 0, j_stamp, j_log[j_idx]) * 1e-9
            # another mechanism starts a new sequence, numbered from 0 like the live monitor
            segment.append(predict_plants(rt, rv[r], jt, j_pos, j_vel, model, settings,
                                          row=row.index, speed_filter=False, changes=changes))
        segment = Plants.concatenate(segment)
        order = np.argsort(segment.time, kind='stable')
        parts.append(Plants.from_table(segment.table()[order]))
    plants = Plants.concatenate(parts)
    last_model = designs[-1][3]
    logs = np.concatenate((s_log, j_log))
    recorded = np.zeros((0, len(PLANT_FIELDS)))
    if with_recorded and interfaces.PLANTS in rec.topics:
        recorded = _recorded_plants(rec.topics[interfaces.PLANTS])
    return ReplayResult(
        path=str(path), design=designs[-1][2], settings=settings, plants=plants,
        summary=summarize(plants, last_model.spacing), rows=rows,
        row_summaries=[summarize(_of_row(plants, row.index), last_model.spacing)
                       for row in rows],
        duration=float((logs.max() - logs.min()) * 1e-9) if logs.size else 0.0,
        messages={interfaces.GROUND_SPEED.name: int(s_log.size),
                  interfaces.JOINT_STATES.name: int(j_log.size),
                  interfaces.DESIGN.name: len(design_topic.raw) if design_topic else 0,
                  'total_read': rec.message_count},
        warnings=rec.warnings, recorded_plants=recorded)


def _mechanism_segments(designs):
    """The design messages (log ns, text, design, model) grouped into runs of one mechanism:
    [(log ns of the run's first, [its designs])]. Within a run a change is in force from the
    next planting instant; another mechanism is another machine and starts a new sequence."""
    segments = []
    for entry in designs:
        mechanism = entry[2].get('mechanism', 'five_bar')
        if segments and segments[-1][1][0][2].get('mechanism', 'five_bar') == mechanism:
            segments[-1][1].append(entry)
        else:
            segments.append((entry[0], [entry]))
    return segments


def _count_undecodable(warnings, name, stamps, values):
    """cdr's bulk decoders leave a message they cannot decode at stamp 0 and value NaN."""
    bad = int(np.count_nonzero((stamps == 0) & np.isnan(values)))
    if bad:
        warnings.append(f'{bad} {name} message(s) could not be decoded: skipped')


def _of_row(plants, index):
    return Plants.from_table(plants.table()[plants.row == index])


def _recorded_plants(topic):
    """The live monitor's plants in PLANT_FIELDS order, by the labels of each message (a field
    the recording lacks is NaN; `row` is 0 in a recording made before rows existed)."""
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import Float64MultiArray
    tables = []
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
        for i, label in enumerate(labels[:width]):
            if label in PLANT_FIELDS:
                table[:, PLANT_FIELDS.index(label)] = data[:, i]
        tables.append(table)
    return np.vstack(tables) if tables else np.zeros((0, len(PLANT_FIELDS)))
