"""Reading a few channels of a finalised MCAP file through its indexes (replay's fast path).

A finalised file (this package's recorder, rosbag2's) ends with a summary: where every chunk is
and, per chunk, where each of its channels' message index lies (pairs of log time and offset of
the message record in the uncompressed chunk). Replay needs three of the nine channels a
monitor records, so only the chunks holding them are decompressed, and in those only the wanted
channels' records are touched: their offsets come from the message indexes, their lengths and
log times are read for all of them at once with numpy, and each message is a memoryview slice of
its decompressed chunk (no copy). No other record is parsed (nor any topic's QoS YAML), so the
cost follows the messages wanted, not the bag's size in records. Every chunk read has its CRC
checked (MCAP's CRC-32, the zlib one, computed by ISA-L through `isal`: about five times zlib's
speed here, it was a quarter of the reading).

The summary is parsed by recovery.read_summary (footer and summary CRC checked). Anything
inconsistent - no intact summary, a chunk header, a CRC, an index pointing outside its chunk or
at a record of another kind or channel - raises BagDamagedError (recording.errors) or the
decompressor's error: the caller then reads the file carefully (recovery.read_records), which
finds and reports exactly what is damaged. A chunk written without message indexes is read
record by record (mcap's parser).
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
import mmap
from pathlib import Path
import struct

from isal.isal_zlib import crc32
from mcap.records import ChunkIndex, Message, Metadata
import numpy as np
from numpy.typing import NDArray
import zstandard

from .cdr import Packed, Raw
from .errors import BagDamagedError
from .recovery import OpenedChunk, check_chunk_header, read_summary, record_at

_MESSAGE = 0x05
_MESSAGE_INDEX = 0x07
# a message record: opcode u8, length u64, channel id u16, sequence u32, log time u64,
# publish time u64, then the data
_DATA = 1 + 8 + 2 + 4 + 8 + 8


class IndexedFile:
    """A finalised MCAP file opened through its summary (a context manager)."""

    def __init__(self, path: str | Path) -> None:
        self.path = path
        self._zstd: zstandard.ZstdDecompressor | None = None    # made for the first zstd chunk
        self._file = open(path, 'rb')
        try:
            self._data = mmap.mmap(self._file.fileno(), 0, access=mmap.ACCESS_READ)
            summary = read_summary(self._data)
        except BaseException:
            self.close()
            raise
        if summary is None or not summary['chunks']:
            self.close()
            raise BagDamagedError(f'{path}: no intact summary with a chunk index')
        self._summary = summary
        self.channels = {cid: (c.topic, summary['schemas'].get(c.schema_id, ''))
                         for cid, c in summary['channels'].items()}

    def close(self) -> None:
        data = getattr(self, '_data', None)       # (absent if mapping the file failed)
        if data is not None:
            data.close()                         # then any read raises ValueError
        self._file.close()

    def __enter__(self) -> IndexedFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def metadata(self) -> dict[str, dict[str, str]]:
        """{record name: {key: value}} of the metadata records the summary indexes."""
        out = {}
        for index in self._summary['metadata']:
            _, record, _ = record_at(self._data, index.offset)
            if not isinstance(record, Metadata):
                raise BagDamagedError(f'metadata index {index.name!r} points at no metadata')
            out[record.name] = dict(record.metadata)
        return out

    def messages(self, ids: Collection[int]
                 ) -> dict[int, tuple[NDArray[np.int64], Sequence[Raw]]]:
        """{channel id: (log times ns, raw CDR)} of the channels `ids`, each in file order
        (chunk by chunk, then by position in the chunk): the log times an int64 array, the
        messages a cdr.Packed over the decompressed chunks (a list of memoryviews for a file
        written without message indexes)."""
        out: dict[int, tuple[NDArray[np.int64], Sequence[Raw]]] = {
            cid: (np.zeros(0, dtype=np.int64), Packed(b'', np.zeros(0, dtype=np.int64),
                                                      np.zeros(0, dtype=np.int64)))
            for cid in ids}
        chunks = sorted(self._summary['chunks'], key=lambda c: c.chunk_start_offset)
        if not ids:
            return out
        if any(index.message_index_length == 0 for index in chunks):
            lists: dict[int, tuple[list[int], list[Raw]]] = {cid: ([], []) for cid in ids}
            for index in chunks:                  # a writer without message indexes
                self._whole_chunk(index, lists)
            return {cid: (np.asarray(logs, dtype=np.int64), raws)
                    for cid, (logs, raws) in lists.items()}
        # the chunks holding wanted channels, decompressed into one buffer, and every wanted
        # message's offset in it: then one vectorised pass over all the wanted channels
        buffers, size = [], 0
        pieces = []                           # each chunk's message index pairs per channel
        owner, start, chunk, count = [], [], [], []     # of each piece: channel, its chunk's
        for index in chunks:                  # start in the buffer and size, pairs
            mine = [cid for cid in ids if cid in index.message_index_offsets]
            if not mine:
                continue
            records = self._chunk_records(index)
            for cid in mine:
                pairs = self._index_pairs(index, cid)
                pieces.append(pairs)
                owner.append(cid)
                start.append(size)
                chunk.append(len(records))
                count.append(len(pairs) // 16)
            buffers.append(records)
            size += len(records)
        if not pieces:
            return out
        data = b''.join(buffers)
        head = np.frombuffer(data, dtype=np.uint8)
        # a record may not run past its own chunk: past the next chunk's start at most
        bounds = np.cumsum([len(b) for b in buffers])
        # the pieces channel by channel, each channel's in chunk order
        by_channel = sorted(range(len(pieces)), key=owner.__getitem__)
        counts = np.array(count, dtype=np.int64)[by_channel]
        channel_of = np.repeat(np.array(owner, dtype=np.int64)[by_channel], counts)
        # every offset inside its chunk, then all of them in the buffer, sorted by channel and
        # position (chunks follow each other in it: sorting orders each chunk's and keeps
        # their order; the writers' indexes are in order already, then nothing is sorted)
        offset = np.frombuffer(b''.join([pieces[k] for k in by_channel]), dtype='<u8')[1::2]
        inside = offset < np.uint64(1 << 62)              # no wrap-around below
        offset = offset.astype(np.int64)
        _refuse(~inside | (offset + _DATA > np.repeat(np.array(chunk)[by_channel], counts)),
                channel_of, 'points outside its chunk')
        at = offset + np.repeat(np.array(start, dtype=np.int64)[by_channel], counts)
        if np.any((at[1:] <= at[:-1]) & (channel_of[1:] == channel_of[:-1])):
            order = np.lexsort((at, channel_of))
            at, channel_of = at[order], channel_of[order]
        _refuse(at + _DATA > head.size, channel_of, 'points past its chunks')
        fields = np.lib.stride_tricks.sliding_window_view(head, _DATA)[at]
        length = fields[:, 1:9].copy().view('<u8')[:, 0].astype(np.int64)
        channel = fields[:, 9:11].copy().view('<u2')[:, 0]
        end = at + 9 + length
        limit = bounds[np.searchsorted(bounds, at, side='right')]
        _refuse((fields[:, 0] != _MESSAGE) | (channel != channel_of) | (length < _DATA - 9)
                | (end > limit), channel_of, 'does not match its records')
        logs = fields[:, 15:23].copy().view('<u8')[:, 0].astype(np.int64)
        for cid in ids:
            lo, hi = np.searchsorted(channel_of, [cid, cid + 1])
            if hi > lo:
                out[cid] = (logs[lo:hi], Packed(data, at[lo:hi] + _DATA, end[lo:hi]))
        return out

    def _chunk_records(self, index: ChunkIndex) -> bytes:
        """The uncompressed records of the chunk `index` points at, CRC checked."""
        data, pos = self._data, index.chunk_start_offset
        if pos + 9 > len(data) or data[pos] != 0x06:
            raise BagDamagedError(f'chunk index points at byte {pos}, not at a chunk')
        (length,) = struct.unpack_from('<Q', data, pos + 1)
        if pos + 9 + length > len(data):
            raise BagDamagedError(f'chunk at byte {pos} runs past the end of the file')
        check_chunk_header(data, pos, length)
        body = pos + 9
        _, _, size, crc, n = struct.unpack_from('<QQQII', data, body)
        compression = bytes(data[body + 32:body + 32 + n]).decode('ascii')
        (stored,) = struct.unpack_from('<Q', data, body + 32 + n)
        raw = data[body + 40 + n:body + 40 + n + stored]
        if compression == 'zstd':
            if self._zstd is None:            # one per file: a context costs as much as a chunk
                self._zstd = zstandard.ZstdDecompressor()
            records = self._zstd.decompress(raw, max_output_size=size)
        elif compression == 'lz4':
            # lazy: lz4 is optional (requirements: only for bags with lz4 chunks)
            import lz4.frame
            records = lz4.frame.decompress(raw)
        else:
            records = raw
        if len(records) != size or (crc and crc32(records) != crc):
            raise BagDamagedError(f'chunk at byte {pos}: CRC mismatch')
        return records

    def _index_pairs(self, index: ChunkIndex, cid: int) -> bytes:
        """The (log time, offset) pairs (u64 each) of channel `cid`'s message index in the
        chunk of `index`, its record checked."""
        data, pos = self._data, index.message_index_offsets[cid]
        if pos + 15 > len(data) or data[pos] != _MESSAGE_INDEX:
            raise BagDamagedError(f'message index of channel {cid} points at byte {pos}, not at a '
                                  'message index')
        (length,) = struct.unpack_from('<Q', data, pos + 1)
        channel, count = struct.unpack_from('<HI', data, pos + 9)
        if channel != cid or count % 16 or 6 + count > length or pos + 9 + length > len(data):
            raise BagDamagedError(f'message index at byte {pos} is inconsistent')
        return data[pos + 15:pos + 15 + count]

    def _whole_chunk(self, index: ChunkIndex,
                     out: dict[int, tuple[list[int], list[Raw]]]) -> None:
        _, chunk, _ = record_at(self._data, index.chunk_start_offset)
        if not isinstance(chunk, OpenedChunk):
            raise BagDamagedError(f'chunk index points at byte {index.chunk_start_offset}, not at '
                                  'a chunk')
        for record in chunk.records:
            if isinstance(record, Message) and record.channel_id in out:
                logs, raws = out[record.channel_id]
                logs.append(record.log_time)
                raws.append(record.data)


def _refuse(bad: NDArray[np.bool_], channel_of: NDArray[np.int64], what: str) -> None:
    """BagDamagedError naming the channel of the first message index entry that is `bad`."""
    if np.any(bad):
        raise BagDamagedError(f'message index of channel {channel_of[np.argmax(bad)]} {what}')
