"""The one MCAP recorder (monitor and demo): rosbag2's layout, crash-safe, split by size/time.

Layout (what `ros2 bag`, Foxglove and `rosbags` expect from rosbag2's MCAP storage):
* header profile `ros2`; one schema per message type, named `pkg/msg/Type`, encoding `ros2msg`,
  data = the type's .msg text followed, for each dependency (depth first, each once), by a line
  of 80 `=`, a line `MSG: pkg/Type` and that type's text (rosbag2's LocalMessageDefinitionSource
  format), read from the .msg files the ROS wheels ship in share/<pkg>/msg;
* channels with message encoding `cdr` and metadata `offered_qos_profiles` (YAML, rosbag2 v9
  style) and `topic_type_hash` (RIHS01, from the shipped .json);
* message log time = receive time, publish time = the sender's source time;
* zstd chunks, closed about once a second (`flush_period`) so a SIGKILL loses at most that;
* on close: a `rosbag2` Metadata record with `serialized_metadata`, then the summary (schemas,
  channels, statistics, chunk and message indexes); a bag directory also gets metadata.yaml.

A path ending in `.mcap` is a single-file bag. Any other path is a rosbag2 bag directory holding
`<name>_0.mcap`, `<name>_1.mcap`, ... (split by size and/or duration). Without a path the bag is
`bags/planter_<YYYY_MM_DD-HH_MM_SS>/`. An existing bag is never overwritten.

Messages are written as the CDR bytes they arrived in (raw subscriptions); only messages the
caller publishes itself are serialised (`write_message`, rclpy.serialization).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
import copy
from dataclasses import dataclass, field
from enum import Enum
import json
import os
from pathlib import Path
import re
import sys
import time
from typing import TYPE_CHECKING, BinaryIO

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
import yaml

from planter_ros.config import check, setting
from planter_ros.interfaces import Qos

from .cdr import encode_message
from .errors import BagWriteError

if TYPE_CHECKING:               # rclpy only where a message is serialised: replay needs none
    from mcap.writer import Writer
    from rclpy.duration import Duration
    from rclpy.qos import QoSProfile

    from .cdr import RosMessage

    from planter_ros.interfaces import Qos

PROFILE = 'ros2'
SCHEMA_ENCODING = 'ros2msg'
MESSAGE_ENCODING = 'cdr'
DELIMITER = '=' * 80 + '\n'
PRIMITIVE_TYPES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string', 'wstring'))
# rosbag2's field-type pattern: "foo_msgs/Bar" in "foo_msgs/Bar[] bar" at a line start
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
# rosbag2's infinite duration in QoS YAML
_INFINITE = {'sec': 9223372036, 'nsec': 854775807}


@dataclass(frozen=True)
class RecorderConfig:
    """What and how to record (the monitor's read-only parameters)."""

    record: bool = setting(True, 'record inputs and predictions to an MCAP bag (rosbag2 '
                           'layout)', read_only=True)
    bag_path: str = setting('', 'bag to write: a directory (rosbag2 layout) or a .mcap file; '
                            'empty = bags/planter_<date-time>; an existing bag is never '
                            'overwritten', read_only=True)
    split_size: int = setting(0, 'start a new bag file after this many bytes (0 = never)',
                              unit='B', range=(0, 2 ** 40), read_only=True)
    split_duration: float = setting(0.0, 'start a new bag file after this much log time '
                                    '(0 = never)', unit='s', range=(0.0, 86400.0),
                                    read_only=True)
    flush_period: float = setting(1.0, 'time between MCAP chunk flushes: the most a killed '
                                  'recorder loses', unit='s', range=(0.001, 60.0),
                                  read_only=True)

    def __post_init__(self) -> None:
        check(self, BagWriteError)


# ----------------------------------------------------------------------------- definitions

def _share_dir(package: str) -> Path:
    os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)
    try:
        return Path(get_package_share_directory(package))
    except PackageNotFoundError:
        raise BagWriteError(f'message package {package} not found (AMENT_PREFIX_PATH='
                            f'{os.environ.get("AMENT_PREFIX_PATH")})') from None


def _split_type(type_name: str) -> tuple[str, str, str]:
    parts = type_name.split('/')
    if len(parts) == 2:
        return parts[0], 'msg', parts[1]
    if len(parts) == 3:
        return parts[0], parts[1], parts[2]
    raise BagWriteError(f'message type {type_name!r} is not pkg/msg/Type')


def message_definition(type_name: str) -> str:
    """rosbag2's full ros2msg text of `pkg/msg/Type` (dependencies appended, each once)."""
    seen: set[str] = set()

    def text_of(name: str) -> tuple[str, str]:
        package, namespace, base = _split_type(name)
        path = _share_dir(package) / namespace / f'{base}.msg'
        try:
            return path.read_text(), package
        except OSError:
            raise BagWriteError(f'no message definition {path} for {name}') from None

    def append(name: str) -> str:
        text, package = text_of(name)
        deps: set[str] = set()
        for match in _FIELD_TYPE.finditer(text):
            dep = match.group(1)
            if dep in PRIMITIVE_TYPES:
                continue
            deps.add(dep if '/' in dep else f'{package}/{dep}')
        out = text
        for dep in sorted(deps):
            if dep not in seen:
                seen.add(dep)
                out += '\n' + DELIMITER + f'MSG: {dep}\n' + append(dep)
        return out

    return append(type_name)


def type_hash(type_name: str) -> str:
    """RIHS01 hash of a type from the .json the wheels ship next to the .msg ('' if absent)."""
    package, namespace, base = _split_type(type_name)
    try:
        data = json.loads((_share_dir(package) / namespace / f'{base}.json').read_text())
    except (OSError, ValueError):
        return ''
    for entry in data.get('type_hashes', ()):
        if entry.get('type_name') == f'{package}/{namespace}/{base}':
            return entry.get('hash_string', '')
    return ''


def qos_yaml(qos: Qos | QoSProfile | dict[str, object] | None) -> str:
    """offered_qos_profiles YAML (rosbag2 v9 style) of an interfaces.Qos, an rclpy QoSProfile
    or a ready dict."""
    if isinstance(qos, Qos):
        qos = qos.profile()
    profiles: list[dict[str, object]]
    if qos is None:
        profiles = []
    elif isinstance(qos, dict):
        profiles = [qos]
    else:
        profiles = [_qos_dict(qos)]
    key = repr(profiles)      # plain values (what safe_dump takes): equal reprs, equal YAML
    text = _QOS_YAML.get(key)
    if text is None:
        text = _QOS_YAML[key] = yaml.safe_dump(profiles, default_flow_style=False,
                                               sort_keys=False)
    return text


# qos_yaml's texts and their profiles read back, per distinct profile list (PyYAML is pure
# Python: a bag's 15 topics have 4 profiles, and a season writes hundreds of bags)
_QOS_YAML: dict[str, str] = {}
_QOS_PROFILES: dict[str, list[object]] = {}


def _qos_profiles(text: str) -> list[object]:
    """`yaml.safe_load(text) or []` of an offered_qos_profiles text, a copy of its own each
    time (an object met twice would be written as a YAML alias)."""
    profiles = _QOS_PROFILES.get(text)
    if profiles is None:
        profiles = _QOS_PROFILES[text] = yaml.safe_load(text) or []
    return copy.deepcopy(profiles)


def _qos_dict(qos: QoSProfile) -> dict[str, object]:
    def duration(d: Duration) -> dict[str, int]:
        ns = d.nanoseconds
        if ns >= 2 ** 63 - 1:
            return dict(_INFINITE)
        return {'sec': ns // 1_000_000_000, 'nsec': ns % 1_000_000_000}

    def word(enum_value: Enum) -> str:
        return enum_value.name.lower()

    return {
        'history': word(qos.history),
        'depth': int(qos.depth),
        'reliability': word(qos.reliability),
        'durability': word(qos.durability),
        'deadline': duration(qos.deadline),
        'lifespan': duration(qos.lifespan),
        'liveliness': word(qos.liveliness),
        'liveliness_lease_duration': duration(qos.liveliness_lease_duration),
        'avoid_ros_namespace_conventions': bool(qos.avoid_ros_namespace_conventions),
    }


# ----------------------------------------------------------------------------- recorder

class _Channel:
    """One topic of the bag and its MCAP channel in the current file."""

    __slots__ = ('name', 'type_name', 'definition', 'hash', 'qos', 'channel', 'count',
                 'file_count')

    def __init__(self, name: str, type_name: str, definition: str, hash_: str,
                 qos: str) -> None:
        self.name, self.type_name, self.definition = name, type_name, definition
        self.hash, self.qos = hash_, qos
        self.channel = 0        # its MCAP channel id in the current file (set on registering)
        self.count = 0          # whole bag
        self.file_count = 0     # current file


def default_bag_path(bags_dir: str | Path = 'bags', prefix: str = 'planter',
                     now: float | None = None) -> Path:
    """`bags/planter_<YYYY_MM_DD-HH_MM_SS>` (a free name: `-1`, `-2`, ... appended if taken)."""
    stamp = time.strftime('%Y_%m_%d-%H_%M_%S', time.localtime(now))
    base = Path(bags_dir) / f'{prefix}_{stamp}'
    path, n = base, 0
    while path.exists() or path.with_suffix('.mcap').exists():
        n += 1
        path = base.with_name(f'{base.name}-{n}')
    return path


@dataclass
class _OpenFile:
    """The MCAP file being written: its stream and writer, the schemas registered in it, and
    the first and last log time (ns) written to it."""

    stream: BinaryIO
    writer: Writer
    schema_ids: dict[str, int] = field(default_factory=dict)
    start: int | None = None
    end: int | None = None


@dataclass(frozen=True)
class BagLayout:
    """How a bag is cut into files and chunks (SI): `split_size` bytes per file (0 = no size
    split), `split_duration` seconds of log time per file (0 = none), `flush_period` seconds
    between chunk flushes (the most a SIGKILL can lose), `chunk_size` bytes of uncompressed
    chunk that force an earlier flush. The Recorder checks the first three as RecorderConfig
    does."""

    split_size: int = 0
    split_duration: float = 0.0
    flush_period: float = 1.0
    chunk_size: int = 1 << 20


class Recorder:
    """Write CDR messages into an MCAP bag in rosbag2's layout, cut as `layout` (BagLayout)
    says. Times passed to `write` are integer nanoseconds.
    """

    def __init__(self, path: str | Path | None = None, layout: BagLayout = BagLayout(), *,
                 bags_dir: str | Path = 'bags',
                 monotonic: Callable[[], float] = time.monotonic) -> None:
        split_size, split_duration = layout.split_size, layout.split_duration
        flush_period, chunk_size = layout.flush_period, layout.chunk_size
        RecorderConfig(split_size=split_size, split_duration=split_duration,
                       flush_period=flush_period)          # BagWriteError if out of range
        path = default_bag_path(bags_dir) if path in (None, '') else Path(path)
        self.single_file = path.suffix == '.mcap'
        if self.single_file and (split_size or split_duration):
            raise BagWriteError(f'bag {path}: splitting needs a bag directory path '
                                '(without .mcap)')
        if path.exists():
            raise BagWriteError(f'bag {path} already exists: choose another path '
                                '(recordings are never overwritten)')
        try:
            if self.single_file:
                path.parent.mkdir(parents=True, exist_ok=True)
            else:
                path.mkdir(parents=True, exist_ok=False)
        except OSError as exc:
            raise BagWriteError(f'cannot create bag {path}: {exc.strerror or exc}') from None
        self.path = path
        self.name = path.stem if self.single_file else path.name
        self.split_size = split_size
        self.split_duration_ns = int(round(split_duration * 1e9))
        self.flush_period = float(flush_period)
        self.chunk_size = int(chunk_size)
        self._monotonic = monotonic
        self._topics: dict[str, _Channel] = {}
        self._definitions: dict[str, tuple[str, str]] = {}   # type -> (definition, hash)
        self._metadata: dict[str, dict[str, str]] = {}
        self.files: list[Path] = []          # finished and current file paths, in order
        self._file_info: list[dict[str, object]] = []   # per finished file: for metadata
        self._bag_start: int | None = None   # first and last log time written (ns)
        self._bag_end: int | None = None
        self._last_flush = monotonic()
        self.closed = False
        self._file: _OpenFile | None = self._open_file()     # None once closed

    # -- public API --------------------------------------------------------------------
    def add_topic(self, topic: str, type_name: str,
                  qos: Qos | QoSProfile | dict[str, object] | None = None) -> None:
        """Declare a topic (`/ns/name`, `pkg/msg/Type`, rclpy QoSProfile or v9 dict)."""
        if topic in self._topics:
            return
        if type_name not in self._definitions:
            self._definitions[type_name] = (message_definition(type_name), type_hash(type_name))
        definition, hash_ = self._definitions[type_name]
        entry = _Channel(topic, type_name, definition, hash_, qos_yaml(qos))
        self._topics[topic] = entry
        self._register(self._open(), entry)

    def add_metadata(self, name: str, values: Mapping[str, object]) -> None:
        """An MCAP Metadata record (string key/values), repeated in every split file."""
        texts = {str(k): str(v) for k, v in values.items()}
        self._metadata[name] = texts
        self._open().writer.add_metadata(name, texts)

    def write(self, topic: str, data: bytes | bytearray | memoryview, log_time: int,
              publish_time: int | None = None) -> None:
        """Record one CDR message (bytes) received at `log_time` ns, sent at `publish_time`."""
        if self.closed:
            raise BagWriteError(f'bag {self.path} is closed')
        entry = self._topics.get(topic)
        if entry is None:
            raise BagWriteError(f'topic {topic} was not added to bag {self.path}')
        log_time = int(log_time)
        file = self._maybe_split(self._open(), log_time)
        file.writer.add_message(entry.channel, log_time, bytes(data),
                                int(log_time if publish_time is None else publish_time))
        entry.count += 1
        entry.file_count += 1
        if file.start is None or log_time < file.start:
            file.start = log_time
        file.end = log_time if file.end is None else max(file.end, log_time)
        self._bag_start = log_time if self._bag_start is None else min(self._bag_start, log_time)
        self._bag_end = log_time if self._bag_end is None else max(self._bag_end, log_time)
        self.tick()

    def write_message(self, topic: str, msg: RosMessage, log_time: int,
                      publish_time: int | None = None) -> None:
        """Serialise a message this process publishes and record it: CDR written
        deterministically (recording.cdr.encode_message: padding zeroed, no bytes after the
        last field, unlike rclpy's serialize_message), so the same messages give the same
        bytes and every reader decodes them without a size mismatch."""
        self.write(topic, encode_message(msg), log_time, publish_time)

    def tick(self) -> None:
        """Close the open chunk if `flush_period` has passed (call from a timer too)."""
        if self._file is not None and self._monotonic() - self._last_flush >= self.flush_period:
            self.flush()

    def flush(self) -> None:
        """Close the open chunk and hand it to the OS (survives a SIGKILL of this process)."""
        if self._file is not None:
            self._file.writer.flush()
        self._last_flush = self._monotonic()

    def close(self) -> None:
        """Finalise: rosbag2 metadata record, summary with statistics; metadata.yaml for a bag
        directory. Safe to call twice."""
        if self.closed:
            return
        self._close_file(self._open())
        self._file = None
        self.closed = True
        if not self.single_file:
            text = yaml.safe_dump({'rosbag2_bagfile_information': self.metadata()},
                                  default_flow_style=False, sort_keys=False)
            tmp = self.path / 'metadata.yaml.tmp'
            tmp.write_text(text)
            tmp.replace(self.path / 'metadata.yaml')

    @property
    def message_count(self) -> int:
        return sum(t.count for t in self._topics.values())

    def metadata(self) -> dict[str, object]:
        """rosbag2 BagMetadata (version 9) of everything written so far."""
        files = list(self._file_info)
        if self._file is not None:
            files.append(self._current_file_info(self._file))
        start = self._bag_start or 0
        return {
            'version': 9,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': (self._bag_end - start) if self._bag_end else 0},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': self.message_count,
            'topics_with_message_count': [{
                'topic_metadata': {
                    'name': t.name, 'type': t.type_name, 'serialization_format': 'cdr',
                    'offered_qos_profiles': _qos_profiles(t.qos),
                    'type_description_hash': t.hash,
                },
                'message_count': t.count,
            } for t in self._topics.values()],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [f['path'] for f in files],
            'files': files,
            'custom_data': {},
            'ros_distro': os.environ.get('ROS_DISTRO', 'jazzy'),
        }

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- files -------------------------------------------------------------------------
    def _file_path(self, index: int) -> Path:
        return self.path if self.single_file else self.path / f'{self.name}_{index}.mcap'

    def _open(self) -> _OpenFile:
        """The file being written; BagWriteError once the bag is closed."""
        if self._file is None:
            raise BagWriteError(f'bag {self.path} is closed')
        return self._file

    def _open_file(self) -> _OpenFile:
        """Start the next file: every topic and metadata record declared again."""
        # lazy: mcap.writer costs 35 ms and only a bag written needs it (a monitor with
        # record: false imports this module and writes none)
        from mcap.writer import CompressionType, Writer
        path = self._file_path(len(self.files))
        try:
            raw = open(path, 'xb')
        except FileExistsError:
            raise BagWriteError(f'bag file {path} already exists (recordings are never '
                                'overwritten)') from None
        except OSError as exc:
            raise BagWriteError(f'cannot create bag file {path}: {exc.strerror or exc}') from None
        writer = Writer(raw, chunk_size=self.chunk_size, compression=CompressionType.ZSTD)
        writer.start(profile=PROFILE, library='planter_ros recorder (mcap python)')
        file = _OpenFile(raw, writer)
        self.files.append(path)
        for entry in self._topics.values():
            entry.file_count = 0
            self._register(file, entry)
        for name, values in self._metadata.items():
            writer.add_metadata(name, values)
        self._last_flush = self._monotonic()
        return file

    def _register(self, file: _OpenFile, entry: _Channel) -> None:
        schema = file.schema_ids.get(entry.type_name)
        if schema is None:
            schema = file.writer.register_schema(entry.type_name, SCHEMA_ENCODING,
                                                 entry.definition.encode())
            file.schema_ids[entry.type_name] = schema
        metadata = {'offered_qos_profiles': entry.qos}
        if entry.hash:
            metadata['topic_type_hash'] = entry.hash
        entry.channel = file.writer.register_channel(entry.name, MESSAGE_ENCODING, schema,
                                                     metadata)

    def _current_file_info(self, file: _OpenFile) -> dict[str, object]:
        start = file.start or 0
        return {
            'path': self._file_path(len(self.files) - 1).name,
            'starting_time': {'nanoseconds_since_epoch': start},
            'duration': {'nanoseconds': (file.end - start) if file.end else 0},
            'message_count': sum(t.file_count for t in self._topics.values()),
        }

    def _close_file(self, file: _OpenFile) -> None:
        info = self._current_file_info(file)
        metadata = self.metadata()
        file.writer.add_metadata('rosbag2', {
            'serialized_metadata': yaml.safe_dump(metadata, default_flow_style=False,
                                                  sort_keys=False)})
        file.writer.finish()
        file.stream.close()
        self._file_info.append(info)

    def _maybe_split(self, file: _OpenFile, log_time: int) -> _OpenFile:
        """The file `log_time` goes to: the open one, or the next after a split."""
        if self.single_file or file.start is None:
            return file
        by_time = self.split_duration_ns and log_time - file.start >= self.split_duration_ns
        by_size = self.split_size and file.stream.tell() >= self.split_size
        if by_time or by_size:
            self._close_file(file)
            self._file = file = self._open_file()
        return file


__all__ = ['Recorder', 'default_bag_path', 'message_definition', 'qos_yaml',
           'type_hash']
