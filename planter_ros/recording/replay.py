"""Replay: re-run the plant prediction model on a recorded bag, far faster than real time.

Reads any rosbag2 MCAP (a .mcap file, or a bag directory / split files `<name>_<n>.mcap`) with
a ground speed (geometry_msgs/TwistStamped `.../ground_speed`), mechanism feedback
(sensor_msgs/JointState `.../joint_states`) and design (std_msgs/String `.../design`) topic.

Speed: finalised files are read with `rosbags` (raw bytes, ~250 k msgs/s here); the few fields
the model needs are then decoded in bulk with numpy — messages of one layout (same length, same
frame_id, joint names and array sizes) share their byte offsets, found by walking the CDR of
the first one — and every other message is walked on its own. A file without its summary
(a killed recorder) or with a damaged chunk is read by the mcap library's streaming reader up to
its last intact chunk, with a warning.

The live monitor's rules are applied the same way: samples before the first design are not
predicted, a changed design starts a new row, stamps of 0 mean "use the receive (log) time".
"""

from dataclasses import dataclass, field
import json
import math
from pathlib import Path
import re
import struct

import numpy as np

from planter_ros import interfaces
from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.plant_prediction import (
    PLANT_FIELDS, Plants, PredictionSettings, planting_model_from_design, predict_plants,
    summarize)

MAGIC = b'\x89MCAP0\r\n'
TYPES = {
    'ground_speed': 'geometry_msgs/msg/TwistStamped',
    'joint_states': 'sensor_msgs/msg/JointState',
    'design': 'std_msgs/msg/String',
    'plants': 'std_msgs/msg/Float64MultiArray',
}
NAMES = {'ground_speed': interfaces.GROUND_SPEED, 'joint_states': interfaces.JOINT_STATES,
         'design': interfaces.DESIGN, 'plants': interfaces.PLANTS}
REQUIRED = ('ground_speed', 'joint_states', 'design')
SETTINGS_RECORD = 'planter_monitor'     # MCAP metadata record with the monitor's settings


class ReplayError(ValueError):
    """A bag replay cannot use (one line: the file and what is wrong)."""


# ----------------------------------------------------------------------------- files

def bag_files(path):
    """The .mcap files of a bag: the file itself, or a directory's files in split order."""
    path = Path(path)
    if not path.exists():
        raise ReplayError(f'bag {path} does not exist')
    if path.is_dir():
        files = sorted(path.glob('*.mcap'), key=_split_index)
        if not files:
            raise ReplayError(f'bag directory {path} holds no .mcap files')
        return files
    return [path]


def _split_index(path):
    m = re.search(r'_(\d+)$', path.stem)
    return (int(m.group(1)) if m else -1, path.name)


def _check_magic(path):
    try:
        with open(path, 'rb') as f:
            head = f.read(len(MAGIC))
            f.seek(0, 2)
            size = f.tell()
            f.seek(max(size - len(MAGIC), 0))
            tail = f.read(len(MAGIC))
    except OSError as exc:
        raise ReplayError(f'cannot read {path}: {exc.strerror or exc}') from None
    if head != MAGIC:
        raise ReplayError(f'{path} is not an MCAP file (no MCAP magic at its start)')
    return size > 2 * len(MAGIC) and tail == MAGIC


# ----------------------------------------------------------------------------- reading

@dataclass
class _Topic:
    key: str
    name: str
    type_name: str
    log: list = field(default_factory=list)
    raw: list = field(default_factory=list)


@dataclass
class Recording:
    """Raw messages of the topics replay uses, plus what the bag says about itself."""

    files: list
    topics: dict                  # key -> _Topic (log times ns, raw CDR bytes)
    all_topics: dict              # name -> type, everything in the bag
    settings: dict                # the monitor's recorded settings, if any
    warnings: list
    message_count: int = 0


def read_recording(path):
    """Read a bag's needed topics as raw CDR (fast path, or streaming up to a damaged end)."""
    files = bag_files(path)
    topics, all_topics, settings, warnings = {}, {}, {}, []
    count = 0
    for file in files:
        finalised = _check_magic(file)
        read = None
        if finalised:
            try:
                read = _read_rosbags(file)
            except Exception as exc:           # a damaged file: say so, read what is intact
                warnings.append(f'{file}: {_one_line(exc)}; reading up to the last intact chunk')
        else:
            warnings.append(f'{file} is not finalised (recorder killed?): reading up to its '
                            'last intact chunk')
        if read is None:
            read = _read_stream(file, warnings)
        file_topics, file_all, file_settings, n = read
        count += n
        all_topics.update(file_all)
        settings.update(file_settings)
        for key, topic in file_topics.items():
            if key in topics:
                if topics[key].name != topic.name:
                    continue
                topics[key].log.extend(topic.log)
                topics[key].raw.extend(topic.raw)
            else:
                topics[key] = topic
    return Recording(files, topics, all_topics, settings, warnings, count)


def _one_line(exc):
    text = str(exc).strip().splitlines()
    return f'{type(exc).__name__}: {text[0]}' if text else type(exc).__name__


def _pick_topics(channels):
    """channels: {id: (topic, type)} -> {key: (id, topic, type)} by name suffix and type."""
    found = {}
    for key, type_name in TYPES.items():
        matches = [(cid, name) for cid, (name, t) in channels.items()
                   if t == type_name and name.rstrip('/').split('/')[-1] == NAMES[key]]
        if len(matches) > 1:
            preferred = [m for m in matches if m[1] == f'/{interfaces.NAMESPACE}/{NAMES[key]}']
            matches = preferred or matches[:1]
        if matches:
            found[key] = (matches[0][0], matches[0][1], type_name)
    return found


def _read_rosbags(file):
    from rosbags.rosbag2 import Reader
    topics, all_topics = {}, {}
    n = 0
    with Reader(file) as reader:
        channels = {c.id: (c.topic, c.msgtype) for c in reader.connections}
        all_topics = {name: t for name, t in channels.values()}
        picked = _pick_topics(channels)
        wanted = {cid: key for key, (cid, _, _) in picked.items()}
        topics = {key: _Topic(key, name, t) for key, (_, name, t) in picked.items()}
        conns = [c for c in reader.connections if c.id in wanted]
        for conn, log_time, raw in reader.messages(connections=conns):
            t = topics[wanted[conn.id]]
            t.log.append(log_time)
            t.raw.append(raw)
            n += 1
    settings = _read_settings(file)
    return topics, all_topics, settings, n


def _read_settings(file):
    from mcap.reader import make_reader
    try:
        with open(file, 'rb') as f:
            for record in make_reader(f).iter_metadata():
                if record.name == SETTINGS_RECORD:
                    return dict(record.metadata)
    except Exception:        # settings are optional: a file without them replays with defaults
        return {}
    return {}


def _read_stream(file, warnings):
    """Record-by-record read that stops at the first damaged or missing record."""
    from mcap.records import Channel, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader
    schemas, channels = {}, {}
    raw_msgs = []
    settings = {}
    n = 0
    try:
        with open(file, 'rb') as f:
            for record in StreamReader(f, validate_crcs=True).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record.name
                elif isinstance(record, Channel):
                    channels[record.id] = (record.topic, schemas.get(record.schema_id, ''))
                elif isinstance(record, Message):
                    raw_msgs.append((record.channel_id, record.log_time, record.data))
                elif isinstance(record, Metadata) and record.name == SETTINGS_RECORD:
                    settings = dict(record.metadata)
    except Exception as exc:     # truncated or corrupt: keep what was read before it
        warnings.append(f'{file}: stopped at a damaged record ({_one_line(exc)}); '
                        f'{len(raw_msgs)} messages recovered')
    picked = _pick_topics(channels)
    wanted = {cid: key for key, (cid, _, _) in picked.items()}
    topics = {key: _Topic(key, name, t) for key, (_, name, t) in picked.items()}
    for cid, log_time, data in raw_msgs:
        key = wanted.get(cid)
        if key is not None:
            topics[key].log.append(log_time)
            topics[key].raw.append(data)
            n += 1
    return topics, {name: t for name, t in channels.values()}, settings, n


# ----------------------------------------------------------------------------- CDR fields
# CDR (XCDR1, as rosbag2 stores it): 4-byte encapsulation header (byte 1 = 1: little endian),
# then fields aligned to their size relative to the end of that header.

def _align(pos, size):
    return 4 + ((pos - 4 + size - 1) // size) * size


def _walk_header(raw, e):
    sec, nsec = struct.unpack_from(e + 'iI', raw, 4)
    n = struct.unpack_from(e + 'I', raw, 12)[0]
    return sec, nsec, 16 + n


def _twist_layout(raw):
    """(stamp-sec offset, linear.x offset, layout-defining byte ranges) of a TwistStamped."""
    e = '<' if raw[1] else '>'
    _, _, pos = _walk_header(raw, e)
    return _align(pos, 8), [(0, 4), (12, pos)]


def _joint_layout(raw, name):
    """Offsets of the named joint's position and velocity in a JointState (None if absent),
    and the byte ranges that fix the layout (padding bytes left out: rclpy leaves them
    uninitialised)."""
    e = '<' if raw[1] else '>'
    _, _, pos = _walk_header(raw, e)
    ranges = [(0, 4), (12, pos)]
    pos = _align(pos, 4)
    count = struct.unpack_from(e + 'I', raw, pos)[0]
    ranges.append((pos, pos + 4))
    pos += 4
    names = []
    for _ in range(count):
        pos = _align(pos, 4)
        n = struct.unpack_from(e + 'I', raw, pos)[0]
        names.append(bytes(raw[pos + 4:pos + 3 + n]).decode('utf-8', 'replace'))
        ranges.append((pos, pos + 4 + n))
        pos += 4 + n
    pos = _align(pos, 4)
    n_pos = struct.unpack_from(e + 'I', raw, pos)[0]
    ranges.append((pos, pos + 4))
    pos_data = _align(pos + 4, 8) if n_pos else pos + 4
    vel_count = _align(pos_data + 8 * n_pos, 4)
    n_vel = struct.unpack_from(e + 'I', raw, vel_count)[0]
    ranges.append((vel_count, vel_count + 4))
    vel_data = _align(vel_count + 4, 8) if n_vel else vel_count + 4
    if vel_data + 8 * n_vel > len(raw) or pos_data + 8 * n_pos > len(raw):
        raise ValueError('JointState shorter than its arrays')
    if name in names:
        i = names.index(name)
    elif not names and n_pos == 1:
        i = 0
    else:
        i = None
    p = pos_data + 8 * i if i is not None and i < n_pos else None
    v = vel_data + 8 * i if i is not None and i < n_vel else None
    return p, v, ranges


def _bulk(raws, layout_of, n_values):
    """Decode messages grouped by layout. layout_of(raw) -> (offsets..., ranges); returns
    (stamp_ns int64, values float64 [n, n_values]) with NaN where a value is absent."""
    count = len(raws)
    stamps = np.zeros(count, dtype=np.int64)
    values = np.full((count, n_values), np.nan)
    lengths = np.fromiter((len(r) for r in raws), dtype=np.int64, count=count)
    todo = np.arange(count)
    while todo.size:
        first = raws[todo[0]]
        try:
            *offsets, ranges = layout_of(first)
        except (struct.error, IndexError, ValueError):
            # a message too short for its own fields: left out (NaN values)
            todo = todo[1:]
            continue
        same_len = todo[lengths[todo] == len(first)]
        joined = b''.join(raws) if same_len.size == count else \
            b''.join([raws[i] for i in same_len])
        block = np.frombuffer(joined, dtype=np.uint8).reshape(same_len.size, len(first))
        ref = np.frombuffer(bytes(first), dtype=np.uint8)
        match = np.ones(same_len.size, dtype=bool)
        for lo, hi in ranges:
            match &= np.all(block[:, lo:hi] == ref[lo:hi], axis=1)
        rows = same_len[match]
        block = block[match]
        e = '<' if first[1] else '>'
        sec = block[:, 4:8].copy().view(e + 'i4').ravel().astype(np.int64)
        nsec = block[:, 8:12].copy().view(e + 'u4').ravel().astype(np.int64)
        stamps[rows] = sec * 1_000_000_000 + nsec
        for k, off in enumerate(offsets):
            if off is not None:
                values[rows, k] = block[:, off:off + 8].copy().view(e + 'f8').ravel()
        todo = np.setdiff1d(todo, rows, assume_unique=True)
    return stamps, values


def decode_ground_speed(raws):
    """(stamp ns, linear.x m/s) arrays of TwistStamped CDR messages."""
    if not raws:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    stamps, values = _bulk(raws, _twist_layout, 1)
    return stamps, values[:, 0]


def decode_joint_states(raws, joint):
    """(stamp ns, position rad, velocity rad/s) of the named joint; NaN position = absent."""
    if not raws:
        return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)
    stamps, values = _bulk(raws, lambda r: _joint_layout(r, joint), 2)
    return stamps, values[:, 0], values[:, 1]


def decode_string(raw):
    e = '<' if raw[1] else '>'
    n = struct.unpack_from(e + 'I', raw, 4)[0]
    return bytes(raw[8:8 + max(n - 1, 0)]).decode('utf-8')


# ----------------------------------------------------------------------------- replay

@dataclass
class ReplayResult:
    path: str
    design: dict
    settings: PredictionSettings
    plants: Plants
    summary: dict
    duration: float               # s of log time covered by the inputs
    messages: dict                # topic key -> messages used
    warnings: list
    recorded_plants: np.ndarray   # the live monitor's plant table, if recorded (n, fields)

    def as_json(self):
        return {'bag': self.path, 'design': self.design,
                'settings': {'nozzle_width': self.settings.nozzle_width,
                             'upright_threshold': self.settings.upright_threshold,
                             'window': self.settings.window},
                'duration': self.duration, 'messages': self.messages,
                'summary': self.summary, 'plants': self.plants.rows(),
                'warnings': self.warnings}


def settings_from_recording(recorded, overrides=None):
    """The monitor's recorded settings (if any), overridden by explicit values."""
    base = PredictionSettings()
    values = {'nozzle_width': base.nozzle_width, 'upright_threshold': base.upright_threshold,
              'window': base.window}
    for key in values:
        if key in recorded:
            try:
                values[key] = type(values[key])(float(recorded[key]))
            except ValueError:
                pass
    values.update({k: v for k, v in (overrides or {}).items() if v is not None})
    return PredictionSettings(**values)


def replay(path, settings_overrides=None, with_recorded=False):
    """Re-run the prediction model on a bag. Raises ReplayError for an unusable bag."""
    rec = read_recording(path)
    missing = [k for k in REQUIRED if k not in rec.topics]
    if missing:
        found = ', '.join(f'{n} ({t})' for n, t in sorted(rec.all_topics.items())) or 'none'
        want = ', '.join(f'.../{NAMES[k]} ({TYPES[k]})' for k in missing)
        raise ReplayError(f'bag {path} lacks {want}; topics found: {found}')
    design_topic = rec.topics['design']
    if not design_topic.raw:
        raise ReplayError(f'bag {path} has a design topic but no design message')
    settings = settings_from_recording(rec.settings, settings_overrides)

    designs = []         # (log ns, text) of each change
    for log, raw in sorted(zip(design_topic.log, design_topic.raw), key=lambda x: x[0]):
        text = decode_string(raw)
        if designs and designs[-1][1] == text:
            continue
        try:
            design = json.loads(text)
            model = planting_model_from_design(design)
        except (ValueError, DesignError) as exc:
            rec.warnings.append(f'design message at {log * 1e-9:.3f} s ignored: '
                                f'{str(exc).splitlines()[0]}')
            continue
        designs.append((log, text, design, model))
    if not designs:
        raise ReplayError(f'bag {path} has no usable design message')

    speed = rec.topics['ground_speed']
    joint = rec.topics['joint_states']
    s_log = np.asarray(speed.log, dtype=np.int64)
    j_log = np.asarray(joint.log, dtype=np.int64)
    s_order = np.argsort(s_log, kind='stable')
    j_order = np.argsort(j_log, kind='stable')
    s_log = s_log[s_order]
    j_log = j_log[j_order]
    s_stamp, s_v = decode_ground_speed([speed.raw[i] for i in s_order])
    parts = []
    for k, (log, _, design, model) in enumerate(designs):
        end = designs[k + 1][0] if k + 1 < len(designs) else np.iinfo(np.int64).max
        name = interfaces.MECHANISM_JOINT.get(design.get('mechanism', 'five_bar'))
        s_sel = (s_log > log) & (s_log <= end)
        j_idx = np.nonzero((j_log > log) & (j_log <= end))[0]
        j_stamp, j_pos, j_vel = decode_joint_states([joint.raw[j_order[i]] for i in j_idx], name)
        st = np.where(s_stamp[s_sel] != 0, s_stamp[s_sel], s_log[s_sel]) * 1e-9
        jt = np.where(j_stamp != 0, j_stamp, j_log[j_idx]) * 1e-9
        # each design starts a new row, numbered from 0 like the live monitor
        parts.append(predict_plants(st, s_v[s_sel], jt, j_pos, j_vel, model, settings))
    plants = Plants.concatenate(parts)
    last_model = designs[-1][3]
    logs = np.concatenate((s_log, j_log))
    recorded = np.zeros((0, len(PLANT_FIELDS)))
    if with_recorded and 'plants' in rec.topics:
        recorded = _recorded_plants(rec.topics['plants'])
    return ReplayResult(
        path=str(path), design=designs[-1][2], settings=settings, plants=plants,
        summary=summarize(plants, last_model.spacing),
        duration=float((logs.max() - logs.min()) * 1e-9) if logs.size else 0.0,
        messages={'ground_speed': int(s_log.size), 'joint_states': int(j_log.size),
                  'design': len(design_topic.raw), 'total_read': rec.message_count},
        warnings=rec.warnings, recorded_plants=recorded)


def _recorded_plants(topic):
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import Float64MultiArray
    rows = []
    for _, raw in sorted(zip(topic.log, topic.raw), key=lambda x: x[0]):
        msg = deserialize_message(bytes(raw), Float64MultiArray)
        width = msg.layout.dim[1].size if len(msg.layout.dim) > 1 else 0
        if width:
            rows.append(np.asarray(msg.data, dtype=float).reshape(-1, width))
    return np.vstack(rows) if rows else np.zeros((0, 0))


def format_table(result):
    """Per-plant rows and the summary for people (mm and degrees, labelled)."""
    p = result.plants
    t0 = float(p.time[0]) if len(p) else 0.0
    lines = [f'bag {result.path}: {result.messages["ground_speed"]} ground speed and '
             f'{result.messages["joint_states"]} joint state messages over '
             f'{result.duration:.1f} s',
             f'{"plant":>5} {"t [s]":>8} {"x [m]":>8} {"spacing [mm]":>12} {"error [mm]":>10} '
             f'{"lambda":>7} {"hole [mm]":>9} {"tilt [deg]":>10} {"upright":>7}']
    for i in range(len(p)):
        spacing = '' if not math.isfinite(p.spacing[i]) else f'{p.spacing[i] * 1e3:.1f}'
        err = '' if not math.isfinite(p.spacing_error[i]) else f'{p.spacing_error[i] * 1e3:+.1f}'
        lam = f'{p.speed_ratio[i]:.3f}' if math.isfinite(p.speed_ratio[i]) else 'inf'
        lines.append(f'{int(p.index[i]):>5} {p.time[i] - t0:>8.3f} {p.position[i]:>8.3f} '
                     f'{spacing:>12} {err:>10} {lam:>7} {p.hole_width[i] * 1e3:>9.2f} '
                     f'{math.degrees(p.tilt[i]):>10.2f} {"yes" if p.upright[i] else "NO":>7}')
    return '\n'.join(lines + [''] + format_summary(result).splitlines())


def format_summary(result):
    """The replay summary for people: plants, spacing error, hole width, uprightness."""
    s = result.summary

    def mm(v):
        return 'n/a' if v is None else f'{v * 1e3:.2f} mm'
    rate = 'n/a' if s['uprightness_rate'] is None else f'{100 * s["uprightness_rate"]:.1f} %'
    threshold = math.degrees(result.settings.upright_threshold)
    return '\n'.join([
        f'plants: {s["plants"]} (design spacing {s["design_spacing"] * 1e3:.1f} mm)',
        f'spacing error: mean {mm(s["spacing_error_mean"])}, sigma '
        f'{mm(s["spacing_error_std"])}, max |error| {mm(s["spacing_error_max"])}',
        f'hole width: mean {mm(s["hole_width_mean"])}, max {mm(s["hole_width_max"])}',
        f'uprightness: {rate} (threshold {threshold:.1f} deg to the ground)'])
