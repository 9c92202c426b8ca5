"""Reading a recorded bag's messages as raw CDR: which files, which topics, fast or careful.

A bag is a .mcap file or a rosbag2 bag directory of split files `<name>_<n>.mcap`. Topics are
found by their name's last part and their type (the contract in planter_ros.interfaces), in any
namespace, preferring the default one. Finalised files are read through their indexes, only the
wanted channels' messages (recording.indexed); a file without its summary (a killed recorder) or
with damaged bytes is read chunk by chunk, every intact chunk kept (recording.recovery).
Whatever is lost - a damaged chunk, a cut-off end, a split file missing from a bag directory -
is reported as a warning with the log-time range it covered, relative to the bag's first
message.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
import re

import numpy as np
from numpy.typing import NDArray

from planter_ros import interfaces

from .cdr import Raw
from .errors import BagUnreadableError
from .indexed import IndexedFile
from .recovery import Loss, one_line, read_records

MAGIC = b'\x89MCAP0\r\n'
# one channel's messages: log times (ns) and raw CDR, as lists or as read from a chunk (an int64
# array and a cdr.Packed)
LogTimes = Sequence[int] | NDArray[np.int64]
Blocks = dict[int, tuple[LogTimes, Sequence[Raw]]]


def bag_files(path: str | Path) -> list[Path]:
    """The .mcap files of a bag: the file itself, or a directory's files in split order."""
    return _bag_parts(path)[0]


def _bag_parts(path: str | Path) -> tuple[list[Path], list[tuple[int, Loss]]]:
    """(files present in split order, [(index in that order, Loss)] for missing split files).

    A directory's metadata.yaml (rosbag2) lists its files and their time ranges; without it,
    a hole in the numbering `<name>_<n>.mcap` is a missing file whose range lies between its
    neighbours' messages (filled in by read_recording)."""
    path = Path(path)
    if not path.exists():
        raise BagUnreadableError(f'bag {path} does not exist')
    if not path.is_dir():
        return [path], []
    files = sorted(path.glob('*.mcap'), key=_split_index)
    if not files:
        raise BagUnreadableError(f'bag directory {path} holds no .mcap files')
    missing = []
    listed = _listed_files(path)
    if listed:
        present = {f.name for f in files}
        order = {name: i for i, (name, _, _) in enumerate(listed)}
        files.sort(key=lambda f: (order.get(f.name, len(order)), _split_index(f)))
        for name, start, end in listed:
            if name not in present:
                before = sum(1 for f in files if order.get(f.name, len(order)) < order[name])
                missing.append((before, Loss(start, end, f'split file {name} is missing')))
        return files, missing
    numbered = [(_split_index(f)[0], f) for f in files]
    indexes = [n for n, _ in numbered if n >= 0]
    if indexes:
        stem = re.sub(r'_\d+$', '', numbered[-1][1].stem)
        have = set(indexes)
        for n in range(0, max(indexes)):
            if n not in have:
                before = sum(1 for i, _ in numbered if i < n)
                missing.append((before, Loss(None, None, f'split file {stem}_{n}.mcap is '
                                                         'missing')))
    return files, missing


def _listed_files(directory: Path) -> list[tuple[str, int | None, int | None]]:
    """[(file name, start ns, end ns)] from a rosbag2 metadata.yaml, or [] (none, unreadable)."""
    # lazy: PyYAML costs 18 ms and only a bag directory has a metadata.yaml; a single .mcap
    # file is read without it
    from planter_ros.safe_yaml import YamlError, load_yaml
    meta = directory / 'metadata.yaml'
    try:
        if not meta.is_file() or meta.stat().st_size > (1 << 20):
            return []
        info = load_yaml(meta.read_text(), str(meta)).get('rosbag2_bagfile_information', {})
        times = {}
        for entry in info.get('files') or ():
            start = int(entry['starting_time']['nanoseconds_since_epoch'])
            times[entry['path']] = (start, start + int(entry['duration']['nanoseconds']))
        return [(Path(str(name)).name, *times.get(name, (None, None)))
                for name in info.get('relative_file_paths') or ()]
    except (OSError, UnicodeDecodeError, YamlError, AttributeError, KeyError, TypeError,
            ValueError):
        return []


def _split_index(path: Path) -> tuple[int, str]:
    m = re.search(r'_(\d+)$', path.stem)
    return (int(m.group(1)) if m else -1, path.name)


def check_magic(path: str | Path) -> bool:
    """True if `path` is a finalised MCAP file (magic at both ends); BagUnreadableError if it
    is not MCAP."""
    try:
        with open(path, 'rb') as f:
            head = f.read(len(MAGIC))
            f.seek(0, 2)
            size = f.tell()
            f.seek(max(size - len(MAGIC), 0))
            tail = f.read(len(MAGIC))
    except OSError as exc:
        raise BagUnreadableError(f'cannot read {path}: {exc.strerror or exc}') from None
    if head != MAGIC:
        raise BagUnreadableError(f'{path} is not an MCAP file (no MCAP magic at its start)')
    return size > 2 * len(MAGIC) and tail == MAGIC


@dataclass
class TopicMessages:
    """One contract topic's messages in a bag: its recorded name, log times (ns), raw CDR.
    One finalised file gives them as read (an int64 array and a cdr.Packed: no object per
    message); several files or a careful read, as lists."""

    topic: interfaces.Topic
    name: str
    log: LogTimes = field(default_factory=list)
    raw: Sequence[Raw] = field(default_factory=list)

    def add(self, logs: LogTimes, raws: Sequence[Raw]) -> None:
        """Messages of the next file (in file order after the ones held)."""
        if not len(self.raw):
            self.log, self.raw = logs, raws
            return
        self.log = [*np.asarray(self.log, dtype=np.int64).tolist(),
                    *np.asarray(logs, dtype=np.int64).tolist()]
        self.raw = [*self.raw, *raws]


@dataclass
class Recording:
    """Raw messages of the topics asked for, plus what the bag says about itself."""

    files: list[Path]
    topics: dict[interfaces.Topic, TopicMessages]   # the found topics only
    all_topics: dict[str, str]    # name -> type, everything in the bag
    metadata: dict[str, dict[str, str]]     # MCAP metadata records: name -> {key: value}
    warnings: list[str]
    message_count: int = 0
    losses: list[str] = field(default_factory=list)   # one line per lost part (also warnings)


def pick_topics(channels: Mapping[int, tuple[str, str]], wanted: Iterable[interfaces.Topic]
                ) -> dict[interfaces.Topic, tuple[int, str]]:
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


def read_recording(path: str | Path, wanted: Sequence[interfaces.Topic]) -> Recording:
    """Read the `wanted` topics (interfaces.Topic) of a bag as raw CDR, in file order."""
    files, missing = _bag_parts(path)
    topics: dict[interfaces.Topic, TopicMessages] = {}
    all_topics: dict[str, str] = {}
    metadata: dict[str, dict[str, str]] = {}
    warnings: list[str] = []
    losses: list[tuple[Loss, Path]] = []      # each loss and the file (or bag) it is in
    spans: list[tuple[int | None, int | None]] = []   # (first, last) log time of the wanted
    count = 0                                         # messages per file
    for file in files:
        channels: dict[int, tuple[str, str]]
        blocks: Blocks
        file_metadata: dict[str, dict[str, str]]
        fast = None
        file_losses: list[Loss] = []
        if check_magic(file):
            try:
                fast = _read_fast(file, wanted)
            except Exception as exc:           # a damaged file: say so, read what is intact
                warnings.append(f'{file}: {one_line(exc)}; reading every intact chunk')
        else:
            warnings.append(f'{file} is not finalised (recorder killed?): reading every intact '
                            'chunk')
        if fast is not None:
            channels, blocks, file_metadata = fast
        else:
            try:
                found = read_records(file)
            except BagUnreadableError as exc:
                if len(files) == 1:
                    raise
                warnings.append(f'{exc}: file skipped')
                found = None
            if found is not None:
                channels, blocks = found.channels, _blocks(found.messages)
                file_metadata, file_losses = found.metadata, found.losses
            else:
                channels, blocks, file_metadata = {}, {}, {}
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
        first: int | None = None
        last: int | None = None
        for cid, (logs, raws) in blocks.items():
            owner = by_channel.get(cid)
            if owner is not None and len(logs):
                topics[owner].add(logs, raws)
                count += len(logs)
                lo, hi = int(np.min(logs)), int(np.max(logs))
                first = lo if first is None else min(first, lo)
                last = hi if last is None else max(last, hi)
        spans.append((first, last))
        losses += [(loss, file) for loss in file_losses]
    for before, loss in missing:     # a missing split file lies between its neighbours
        if loss.start is None:
            loss.start = next((s[1] for s in reversed(spans[:before]) if s[1] is not None),
                              None)
        if loss.end is None:
            loss.end = next((s[0] for s in spans[before:] if s[0] is not None), None)
        losses.append((loss, Path(path)))
    times = [s[0] for s in spans if s[0] is not None] + \
        [t for loss, _ in losses for t in (loss.start, loss.end) if t is not None]
    t0 = min(times) if times else None
    lost = [f'{where}: {loss.what}; {_lost_range(loss, t0)}' for loss, where in losses]
    return Recording(files, topics, all_topics, metadata, warnings + lost, count, lost)


def _lost_range(loss: Loss, t0: int | None) -> str:
    """The log times a loss covered, in s after the bag's first message, for people."""
    def at(ns: int) -> str:
        return f'{(ns - t0) * 1e-9:.3f} s' if t0 is not None else f'{ns * 1e-9:.3f} s (epoch)'
    if loss.start is not None and loss.end is not None:
        return f'messages logged {at(loss.start)} to {at(loss.end)} after the start are lost'
    if loss.start is not None:
        return f'messages logged after {at(loss.start)} are lost'
    if loss.end is not None:
        return f'messages logged before {at(loss.end)} are lost'
    return 'the time range lost is unknown'


def _read_fast(file: Path, wanted: Iterable[interfaces.Topic]
               ) -> tuple[dict[int, tuple[str, str]], Blocks, dict[str, dict[str, str]]]:
    """A finalised file through its indexes: (channels {id: (topic, type)}, {id: (log times,
    raw CDR)} of the wanted topics' channels, metadata records). Raises on anything damaged."""
    with IndexedFile(file) as indexed:
        ids = {cid for cid, _ in pick_topics(indexed.channels, wanted).values()}
        blocks: Blocks = dict(indexed.messages(ids))
        return indexed.channels, blocks, indexed.metadata()


def _blocks(messages: Iterable[tuple[int, int, Raw]]) -> Blocks:
    """[(channel id, log time, raw)] in file order -> {channel id: (log times, raws)}."""
    out: dict[int, tuple[list[int], list[Raw]]] = {}
    for cid, log_time, data in messages:
        logs, raws = out.setdefault(cid, ([], []))
        logs.append(log_time)
        raws.append(data)
    return dict(out)
