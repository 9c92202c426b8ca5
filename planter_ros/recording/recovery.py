"""Reading everything intact in an MCAP file the fast reader refused: a file without its summary
(a killed recorder) or with damaged bytes anywhere.

* With an intact summary (footer, summary CRC), the chunk index says where every chunk is and
  which log times it holds: each chunk is read and its CRC checked on its own, a damaged one is
  skipped and reported with its exact time range.
* Without one, the records are read in file order; after a damaged record the reader
  resynchronises on the next chunk whose header is consistent and whose CRC matches, and the
  loss is the time between the last intact message before and the first one after.
* A file with no valid record in its first SCAN_LIMIT bytes is refused, so a file of garbage is
  turned down in well under a second whatever its size.

Chunks hold the schema and channel records of a file without summary (the mcap writer puts them
in the chunk open when they are registered, i.e. the first): if that chunk is damaged, the
messages of later chunks cannot be given a topic and are counted as lost.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import io
import mmap
from pathlib import Path
import struct
from typing import TYPE_CHECKING, TypedDict

from isal.isal_zlib import crc32

from .errors import BagDamagedError, BagUnreadableError

if TYPE_CHECKING:                 # mcap is imported where a file is read
    from mcap.records import Channel, Chunk, ChunkIndex, McapRecord, MetadataIndex

Data = bytes | bytearray | memoryview | mmap.mmap        # a file's bytes (mapped), or a copy
Searchable = bytes | bytearray | mmap.mmap               # ... that can be searched (find)

SCAN_LIMIT = 16 << 20          # bytes searched for a first valid record
MAX_CHUNK = 1 << 30            # a chunk header claiming more than this is not believed
COMPRESSIONS = ('', 'zstd', 'lz4')
_OPCODES = range(0x01, 0x10)
_SUMMARY_KINDS = (0x03, 0x04, 0x08, 0x0D)   # schema, channel, chunk index, metadata index
_FOOTER_LENGTH = 20            # summary_start u64, summary_offset_start u64, summary_crc u32
_MAGIC_SIZE = 8


@dataclass
class Loss:
    """Messages a damaged or missing part of a bag held: log times (ns, None = unknown)."""

    start: int | None
    end: int | None
    what: str


@dataclass
class Recovered:
    """What a careful read found: channels {id: (topic, schema name)}, messages [(channel id,
    log time ns, CDR bytes)], metadata {record name: {key: value}}, and the losses."""

    channels: dict[int, tuple[str, str]] = field(default_factory=dict)
    messages: list[tuple[int, int, bytes]] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    losses: list[Loss] = field(default_factory=list)
    _schemas: dict[int, str] = field(default_factory=dict)

    def add(self, record: McapRecord) -> None:
        from mcap.records import Channel, Message, Metadata, Schema
        if isinstance(record, Schema):
            self._schemas[record.id] = record.name
        elif isinstance(record, Channel):
            self.channels[record.id] = (record.topic, self._schemas.get(record.schema_id, ''))
        elif isinstance(record, Message):
            self.messages.append((record.channel_id, record.log_time, record.data))
        elif isinstance(record, Metadata):
            self.metadata[record.name] = dict(record.metadata)

    def last_time(self) -> int | None:
        return max((m[1] for m in self.messages[-1000:]), default=None)


@dataclass
class OpenedChunk:
    """A chunk record and the records it holds (read out, its CRC checked)."""

    chunk: Chunk
    records: list[McapRecord]


class Summary(TypedDict):
    """What a file's summary section indexes."""

    schemas: dict[int, str]               # schema id -> name
    channels: dict[int, Channel]
    chunks: list[ChunkIndex]
    metadata: list[MetadataIndex]


def one_line(exc: BaseException) -> str:
    """`Type: first line of the message` of an exception, for a warning."""
    text = str(exc).strip().splitlines()
    return f'{type(exc).__name__}: {text[0]}' if text else type(exc).__name__


def read_records(file: str | Path) -> Recovered:
    """Read every intact record of `file` (see the module doc): a Recovered.
    BagUnreadableError if no valid record is found at all."""
    with open(file, 'rb') as f:
        size = f.seek(0, 2)
        if size <= _MAGIC_SIZE:
            raise BagUnreadableError(f'{file} holds no MCAP record (file of {size} bytes)')
        with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
            summary = read_summary(data)
            if summary is not None and summary['chunks']:
                out = _read_indexed(data, summary)
            else:
                out = _scan(data, file)
    known = set(out.channels)
    orphans = sum(1 for m in out.messages if m[0] not in known)
    if orphans:
        out.losses.append(Loss(None, None, f'{orphans} messages whose channel definitions were '
                                           'in a damaged part'))
    return out


# ----------------------------------------------------------------------------- records

def record_at(data: Data, pos: int,
              end: int | None = None) -> tuple[int, McapRecord | OpenedChunk | None, int]:
    """(opcode, record or None for an unknown/ignored kind, end offset) of the record at pos;
    BagDamagedError if it is not a whole, valid record. Chunks are opened and CRC-checked."""
    end = len(data) if end is None else end
    if pos + 9 > end:
        raise BagDamagedError('record header cut off', at=pos)
    opcode = data[pos]
    (length,) = struct.unpack_from('<Q', data, pos + 1)
    if opcode not in _OPCODES:
        raise BagDamagedError(f'no record opcode (0x{opcode:02X})', at=pos)
    stop = pos + 9 + length
    if stop > end:
        raise BagDamagedError('record runs past the end of the file', at=pos)
    if opcode == 0x08:               # the summary holds one per chunk: read without a stream
        return opcode, _chunk_index(data, pos, stop), stop
    if opcode in (0x03, 0x04):       # and one per topic and type: the same
        return opcode, (_schema if opcode == 0x03 else _channel)(data, pos, stop), stop
    from mcap.data_stream import ReadDataStream
    from mcap.records import (
        Channel, Chunk, DataEnd, Footer, Header, Message, Metadata, MetadataIndex, Schema,
        Statistics)
    kinds: dict[int, type[Header | Footer | Schema | Channel | Metadata | Statistics
                          | MetadataIndex | DataEnd]] = {
        0x01: Header, 0x02: Footer, 0x03: Schema, 0x04: Channel, 0x0C: Metadata,
        0x0B: Statistics, 0x0D: MetadataIndex, 0x0F: DataEnd}
    stream = ReadDataStream(io.BytesIO(data[pos + 9:stop]))
    record: McapRecord | OpenedChunk | None
    try:
        if opcode == 0x06:
            check_chunk_header(data, pos, length)
            chunk = Chunk.read(stream)
            record = OpenedChunk(chunk, _chunk_records(chunk))
        elif opcode == 0x05:
            record = Message.read(stream, length)
        elif opcode in kinds:
            record = kinds[opcode].read(stream)
        else:                        # message/attachment indexes, attachments: not needed
            record = None
    except BagDamagedError as exc:   # the chunk header's own check
        raise BagDamagedError(exc.reason, at=pos) from None
    except Exception as exc:         # struct, zstd, CRC, UTF-8, mcap's EndOfFile, ...
        reason = 'CRC mismatch' if type(exc).__name__ == 'CRCValidationError' else one_line(exc)
        raise BagDamagedError(reason, at=pos) from None
    return opcode, record, stop


def _chunk_index(data: Data, pos: int, stop: int) -> ChunkIndex:
    """The ChunkIndex record at `pos` (its end `stop`), read with struct: the fields mcap's
    reader gives, the same checks (nothing past the record, UTF-8)."""
    from mcap.records import ChunkIndex
    at = pos + 9
    try:
        start_time, end_time, chunk_start, chunk_length, size = struct.unpack_from(
            '<QQQQI', data, at)
        at += 36
        if size % 10 or at + size + 12 > stop:
            raise BagDamagedError('chunk index offsets run past the record', at=pos)
        pairs = struct.unpack_from('<' + 'HQ' * (size // 10), data, at)
        at += size
        index_length, n = struct.unpack_from('<QI', data, at)
        at += 12
        if at + n + 16 > stop:
            raise BagDamagedError('chunk index runs past the record', at=pos)
        compression = bytes(data[at:at + n]).decode('utf-8')
        compressed, uncompressed = struct.unpack_from('<QQ', data, at + n)
    except (struct.error, UnicodeDecodeError) as exc:
        raise BagDamagedError(one_line(exc), at=pos) from None
    return ChunkIndex(message_index_offsets=dict(zip(pairs[0::2], pairs[1::2])),
                      chunk_start_offset=chunk_start, chunk_length=chunk_length,
                      compression=compression, compressed_size=compressed,
                      message_end_time=end_time, message_index_length=index_length,
                      message_start_time=start_time, uncompressed_size=uncompressed)


def _strings(data: Data, at: int, stop: int, count: int, pos: int) -> tuple[list[str], int]:
    """`count` length-prefixed UTF-8 strings from `at` (none past `stop`), and where they end."""
    out = []
    for _ in range(count):
        if at + 4 > stop:
            raise BagDamagedError('string length runs past the record', at=pos)
        (n,) = struct.unpack_from('<I', data, at)
        if at + 4 + n > stop:
            raise BagDamagedError('string runs past the record', at=pos)
        try:
            out.append(bytes(data[at + 4:at + 4 + n]).decode('utf-8'))
        except UnicodeDecodeError as exc:
            raise BagDamagedError(one_line(exc), at=pos) from None
        at += 4 + n
    return out, at


def _schema(data: Data, pos: int, stop: int) -> McapRecord:
    """The Schema record at `pos` (its end `stop`), read with struct: mcap's fields."""
    from mcap.records import Schema
    if pos + 11 > stop:
        raise BagDamagedError('schema record cut off', at=pos)
    (schema_id,) = struct.unpack_from('<H', data, pos + 9)
    (name, encoding), at = _strings(data, pos + 11, stop, 2, pos)
    if at + 4 > stop:
        raise BagDamagedError('schema data length runs past the record', at=pos)
    (n,) = struct.unpack_from('<I', data, at)
    if at + 4 + n > stop:
        raise BagDamagedError('schema data runs past the record', at=pos)
    return Schema(id=schema_id, name=name, encoding=encoding, data=bytes(data[at + 4:at + 4 + n]))


def _channel(data: Data, pos: int, stop: int) -> McapRecord:
    """The Channel record at `pos` (its end `stop`), read with struct: mcap's fields."""
    from mcap.records import Channel
    if pos + 13 > stop:
        raise BagDamagedError('channel record cut off', at=pos)
    channel_id, schema_id = struct.unpack_from('<HH', data, pos + 9)
    (topic, encoding), at = _strings(data, pos + 13, stop, 2, pos)
    if at + 4 > stop:
        raise BagDamagedError('channel metadata length runs past the record', at=pos)
    (n,) = struct.unpack_from('<I', data, at)
    at, end = at + 4, at + 4 + n
    if end > stop:
        raise BagDamagedError('channel metadata runs past the record', at=pos)
    metadata = {}
    while at < end:
        (key, value), at = _strings(data, at, end, 2, pos)
        metadata[key] = value
    return Channel(id=channel_id, topic=topic, message_encoding=encoding, metadata=metadata,
                   schema_id=schema_id)


def check_chunk_header(data: Data, pos: int, length: int) -> None:
    """Cheap consistency of a chunk header (before anything is decompressed)."""
    body = pos + 9
    if length < 8 + 8 + 8 + 4 + 4 + 8:
        raise BagDamagedError('chunk too short')
    start, end, uncompressed = struct.unpack_from('<QQQ', data, body)
    (n,) = struct.unpack_from('<I', data, body + 28)
    if start > end or uncompressed > MAX_CHUNK or n > 8 or body + 32 + n + 8 > pos + 9 + length:
        raise BagDamagedError('inconsistent chunk header')
    if bytes(data[body + 32:body + 32 + n]).decode('ascii', 'replace') not in COMPRESSIONS:
        raise BagDamagedError('unknown chunk compression')
    (records,) = struct.unpack_from('<Q', data, body + 32 + n)
    if body + 32 + n + 8 + records > pos + 9 + length:
        raise BagDamagedError('chunk records run past the chunk')


def _chunk_records(chunk: Chunk) -> list[McapRecord]:
    """The chunk's records, its CRC checked (a chunk written without CRC must at least parse)."""
    from mcap.stream_reader import breakup_chunk
    return breakup_chunk(chunk, validate_crc=True)


# ----------------------------------------------------------------------------- with summary

def read_summary(data: Data) -> Summary | None:
    """The summary section's schemas, channels, chunk and metadata indexes, if the footer and
    the summary CRC are intact; else None (then the file is scanned)."""
    from mcap.records import Channel, ChunkIndex, Footer, MetadataIndex, Schema
    size = len(data)
    footer_at = size - _MAGIC_SIZE - 9 - _FOOTER_LENGTH
    if footer_at < _MAGIC_SIZE or bytes(data[size - _MAGIC_SIZE:]) != b'\x89MCAP0\r\n':
        return None
    try:
        _, footer, _ = record_at(data, footer_at, size - _MAGIC_SIZE)
    except BagDamagedError:
        return None
    if not isinstance(footer, Footer) or not _MAGIC_SIZE <= footer.summary_start < footer_at:
        return None
    if footer.summary_crc and crc32(data[footer.summary_start:footer_at + 9 + 16]) \
            != footer.summary_crc:
        return None
    out: Summary = {'schemas': {}, 'channels': {}, 'chunks': [], 'metadata': []}
    pos = footer.summary_start
    try:
        while pos < footer_at:
            if pos + 9 <= footer_at and data[pos] not in _SUMMARY_KINDS:
                # statistics, summary offsets, ...: not needed, only checked to fit
                (length,) = struct.unpack_from('<Q', data, pos + 1)
                if data[pos] not in _OPCODES or pos + 9 + length > footer_at:
                    return None
                pos += 9 + length
                continue
            _, record, pos = record_at(data, pos, footer_at)
            if isinstance(record, Schema):
                out['schemas'][record.id] = record.name
            elif isinstance(record, Channel):
                out['channels'][record.id] = record
            elif isinstance(record, ChunkIndex):
                out['chunks'].append(record)
            elif isinstance(record, MetadataIndex):
                out['metadata'].append(record)
    except BagDamagedError:
        return None
    return out


def _read_indexed(data: Data, summary: Summary) -> Recovered:
    from mcap.records import Metadata
    out = Recovered()
    out._schemas.update(summary['schemas'])
    for cid, channel in summary['channels'].items():
        out.channels[cid] = (channel.topic, summary['schemas'].get(channel.schema_id, ''))
    for index in sorted(summary['chunks'], key=lambda c: c.chunk_start_offset):
        try:
            _, chunk, _ = record_at(data, index.chunk_start_offset)
            if not isinstance(chunk, OpenedChunk):
                raise BagDamagedError('not a chunk', at=index.chunk_start_offset)
        except BagDamagedError as exc:
            out.losses.append(Loss(index.message_start_time, index.message_end_time,
                                   f'damaged chunk at byte {index.chunk_start_offset} '
                                   f'({exc.reason})'))
            continue
        for record in chunk.records:
            out.add(record)
    for meta_index in summary['metadata']:
        try:
            _, meta, _ = record_at(data, meta_index.offset)
        except BagDamagedError:
            meta = None
        if isinstance(meta, Metadata):
            out.add(meta)
        else:
            out.losses.append(Loss(None, None, f'metadata record {meta_index.name!r} damaged'))
    return out


# ----------------------------------------------------------------------------- without

def _scan(data: Searchable, file: str | Path) -> Recovered:
    """Records in file order; resynchronise on the next valid chunk after damage."""
    from mcap.records import DataEnd, Footer
    out = Recovered()
    size = len(data)
    pos = _MAGIC_SIZE
    valid = False
    while pos < size:
        try:
            _, record, stop = record_at(data, pos)
        except BagDamagedError as exc:
            before = out.last_time()
            limit = size if valid else min(size, _MAGIC_SIZE + SCAN_LIMIT)
            found = _next_chunk(data, pos + 1, limit)
            if found is None:
                if not valid:
                    raise BagUnreadableError(
                                             f'{file} holds no valid MCAP record in its first '
                        f'{min(size, _MAGIC_SIZE + SCAN_LIMIT)} bytes ({exc})') from None
                if pos < size - _MAGIC_SIZE or bytes(data[pos:]) != b'\x89MCAP0\r\n':
                    out.losses.append(Loss(before, None, f'cut off or damaged from byte {pos} '
                                                         f'({exc.reason})'))
                break
            start, opened = found
            out.losses.append(Loss(before, opened.chunk.message_start_time,
                                   f'damaged bytes {pos}..{start} ({exc.reason})'))
            pos = start
            continue
        valid = True
        if isinstance(record, OpenedChunk):
            for inner in record.records:
                out.add(inner)
        elif isinstance(record, (DataEnd, Footer)):
            break                    # the summary repeats what was read
        elif record is not None:
            out.add(record)
        pos = stop
    return out


def _next_chunk(data: Searchable, start: int, stop: int) -> tuple[int, OpenedChunk] | None:
    """(offset, chunk) of the first intact chunk at or after `start` and before `stop`."""
    while True:
        at = data.find(b'\x06', start, stop)
        if at < 0:
            return None
        try:
            _, record, _ = record_at(data, at)
        except BagDamagedError:
            record = None
        if isinstance(record, OpenedChunk):     # (a 0x06 opcode is always read as a chunk)
            return at, record
        start = at + 1
