"""Reading a recorded bag's messages as raw CDR: which files, which topics, fast or careful.

A bag is a .mcap file or a rosbag2 bag directory of split files `<name>_<n>.mcap`. Topics are
found by their name's last part and their type (the contract in planter_ros.interfaces), in any
namespace, preferring the default one. Finalised files are read with `rosbags` (raw bytes, the
fastest reader here); a file without its summary (a killed recorder) or with a damaged chunk
is read record by record up to what is intact (recording.recovery), with a warning.
"""

from dataclasses import dataclass, field
from pathlib import Path
import re

from planter_ros import interfaces

from .recovery import one_line, read_records

MAGIC = b'\x89MCAP0\r\n'


class BagError(ValueError):
    """A bag that cannot be read (one line: the file and what is wrong)."""


def bag_files(path):
    """The .mcap files of a bag: the file itself, or a directory's files in split order."""
    path = Path(path)
    if not path.exists():
        raise BagError(f'bag {path} does not exist')
    if path.is_dir():
        files = sorted(path.glob('*.mcap'), key=_split_index)
        if not files:
            raise BagError(f'bag directory {path} holds no .mcap files')
        return files
    return [path]


def _split_index(path):
    m = re.search(r'_(\d+)$', path.stem)
    return (int(m.group(1)) if m else -1, path.name)


def check_magic(path):
    """True if `path` is a finalised MCAP file (magic at both ends); BagError if not MCAP."""
    try:
        with open(path, 'rb') as f:
            head = f.read(len(MAGIC))
            f.seek(0, 2)
            size = f.tell()
            f.seek(max(size - len(MAGIC), 0))
            tail = f.read(len(MAGIC))
    except OSError as exc:
        raise BagError(f'cannot read {path}: {exc.strerror or exc}') from None
    if head != MAGIC:
        raise BagError(f'{path} is not an MCAP file (no MCAP magic at its start)')
    return size > 2 * len(MAGIC) and tail == MAGIC


@dataclass
class TopicMessages:
    """One contract topic's messages in a bag: its recorded name, log times (ns), raw CDR."""

    topic: interfaces.Topic
    name: str
    log: list = field(default_factory=list)
    raw: list = field(default_factory=list)


@dataclass
class Recording:
    """Raw messages of the topics asked for, plus what the bag says about itself."""

    files: list
    topics: dict                  # interfaces.Topic -> TopicMessages (found topics only)
    all_topics: dict              # name -> type, everything in the bag
    metadata: dict                # MCAP metadata records: name -> {key: value}
    warnings: list
    message_count: int = 0


def pick_topics(channels, wanted):
    """channels {id: (name, type)} -> {Topic: (id, name)} for the wanted contract topics."""
    found = {}
    for topic in wanted:
        base = topic.name.strip('/').split('/')[-1]
        matches = [(cid, name) for cid, (name, t) in channels.items()
                   if t == topic.type_name and name.rstrip('/').split('/')[-1] == base]
        if len(matches) > 1:
            preferred = [m for m in matches if m[1] == topic.resolved()]
            matches = preferred or matches[:1]
        if matches:
            found[topic] = matches[0]
    return found


def read_recording(path, wanted):
    """Read the `wanted` topics (interfaces.Topic) of a bag as raw CDR, in file order."""
    files = bag_files(path)
    topics, all_topics, metadata, warnings = {}, {}, {}, []
    count = 0
    for file in files:
        channels = messages = None
        if check_magic(file):
            try:
                channels, messages, file_metadata = _read_fast(file, wanted)
            except Exception as exc:           # a damaged file: say so, read what is intact
                warnings.append(f'{file}: {one_line(exc)}; reading up to the last intact chunk')
        else:
            warnings.append(f'{file} is not finalised (recorder killed?): reading up to its '
                            'last intact chunk')
        if channels is None:
            channels, messages, file_metadata = read_records(file, warnings)
        all_topics.update({name: t for name, t in channels.values()})
        metadata.update(file_metadata)
        picked = pick_topics(channels, wanted)
        by_channel = {cid: topic for topic, (cid, _) in picked.items()}
        for topic, (_, name) in picked.items():
            known = topics.get(topic)
            if known is None:
                topics[topic] = TopicMessages(topic, name)
            elif known.name != name:          # another namespace in a later split: not ours
                by_channel = {c: t for c, t in by_channel.items() if t is not topic}
        for cid, log_time, data in messages:
            topic = by_channel.get(cid)
            if topic is not None:
                topics[topic].log.append(log_time)
                topics[topic].raw.append(data)
                count += 1
    return Recording(files, topics, all_topics, metadata, warnings, count)


def _read_fast(file, wanted):
    """rosbags' reader: only the wanted channels' messages, plus the metadata records."""
    from rosbags.rosbag2 import Reader
    with Reader(file) as reader:
        channels = {c.id: (c.topic, c.msgtype) for c in reader.connections}
        ids = {cid for cid, _ in pick_topics(channels, wanted).values()}
        conns = [c for c in reader.connections if c.id in ids]
        # an empty selection means "every message" to rosbags: ask only when there is one
        messages = [(conn.id, log_time, raw) for conn, log_time, raw in
                    reader.messages(connections=conns)] if conns else []
    return channels, messages, _read_metadata(file)


def _read_metadata(file):
    from mcap.reader import make_reader
    try:
        with open(file, 'rb') as f:
            return {r.name: dict(r.metadata) for r in make_reader(f).iter_metadata()}
    except Exception:        # metadata is optional: a file without it replays with defaults
        return {}
