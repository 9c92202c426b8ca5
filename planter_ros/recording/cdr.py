"""Bulk decoding of a few fields from raw CDR messages (replay's inner loop), with numpy.

Why: replay needs a handful of numbers (a stamp and one or two float64) from tens of thousands
of TwistStamped / JointState messages (and a few fields of each NavSatFix: the as-planted
map). Deserialising each message into an object (rosbags, rclpy) costs far more than reading
those fields, so this module reads them straight from the bytes, most messages at once.

How: messages of one *layout* share their byte offsets. Two messages have the same layout when
they have the same length and the same bytes wherever the walk to the wanted fields reads a
size or a name: the representation identifier (encapsulation bytes 0-1, which say CDR and the
byte order), the frame_id length, and for a JointState the joint-name count, every name's length
and text (they decide which index the wanted joint has) and the array counts. The frame_id text
is not compared (only its length moves the fields after it), nor the two encapsulation option
bytes, nor any alignment padding: serialisers leave padding uninitialised (rclpy does), so it
holds garbage that differs from message to message. The first message of each layout is walked
field by field in Python; every other message of that layout is then read with one strided numpy
view per field. The walk's checks (does every count and length fit in the message?) depend only
on bytes the layout fixes, so they hold for the whole layout. A batch of many one-off layouts
falls back to walking messages one by one, so it does not cost layouts × messages.

CDR here is what rosbag2 stores for plain ROS 2 types (XCDR1, "CDR_BE"/"CDR_LE"): a 4-byte
encapsulation header (byte 0 = 0; byte 1 = 1 little endian, 0 big endian; bytes 2-3 options),
then the fields, each aligned to its own size (4 for counts and string lengths, 8 for float64)
*relative to the end of the header* — i.e. absolute offset 4 + a multiple of the size. A string
is a uint32 length counting its NUL terminator, then the bytes and the NUL; a sequence is a
uint32 count, then (only if the count is non-zero) padding to the element alignment and the
elements. Other representations (XCDR2, parameter lists: byte 0 ≠ 0 or byte 1 > 1) are refused.

Rules shared by the bulk decoders:
* A message whose own structure does not fit in its bytes (truncated, a count or length larger
  than the message, an unknown encapsulation) is left out: stamp 0 and NaN values, no exception.
  Bytes after the structure are allowed (rclpy's serialize_message leaves up to 8 there).
* Stamps are header.stamp in integer nanoseconds (sec * 1e9 + nanosec, int64).
* Input is any sequence of bytes-like objects (bytes, bytearray, memoryview); order is kept.

decode_string (one message, std_msgs/String) is strict instead: it raises DecodeError
(recording.errors), with a one-line message, for anything that is not a well-formed CDR string.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import struct
from typing import Any, Protocol, overload

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from planter_ros.kinematics.arrays import FloatArray

from .errors import DecodeError

Raw = bytes | bytearray | memoryview                 # one message's CDR bytes
Ranges = list[tuple[int, int]]                      # byte ranges that fix a layout
# where a value lies in a message: a float64's offset, (offset, numpy type code) for another
# number ('i1', 'u1'), or None where the message lacks it
Offset = int | tuple[int, str] | None


class RosMessage(Protocol):
    """A generated ROS 2 message (rosidl): its fields and their IDL types by name."""

    @classmethod
    def get_fields_and_field_types(cls) -> dict[str, str]: ...


class Packed(Sequence[memoryview]):
    """Messages lying in one buffer, message i = data[start[i]:end[i]] (what the indexed reader
    gives: the records of a decompressed chunk, no object per message). A sequence of memoryviews
    to whoever iterates it; the bulk decoders read its messages of one length straight from the
    buffer (a row gather, no join)."""

    __slots__ = ('data', 'start', 'end')

    def __init__(self, data: bytes, start: NDArray[np.int64], end: NDArray[np.int64]) -> None:
        self.data = data
        self.start = np.asarray(start, dtype=np.int64)
        self.end = np.asarray(end, dtype=np.int64)

    def __len__(self) -> int:
        return int(self.start.size)

    @overload
    def __getitem__(self, i: int) -> memoryview: ...
    @overload
    def __getitem__(self, i: slice) -> Packed: ...
    def __getitem__(self, i: int | slice) -> memoryview | Packed:
        if isinstance(i, slice):
            return Packed(self.data, self.start[i], self.end[i])
        return memoryview(self.data)[int(self.start[i]):int(self.end[i])]

    def take(self, idx: NDArray[np.intp]) -> Packed:
        """The messages `idx`, in that order (no copy of their bytes)."""
        return Packed(self.data, self.start[idx], self.end[idx])

    def lengths(self) -> NDArray[np.int64]:
        return self.end - self.start

    def block(self, idx: NDArray[np.intp], size: int) -> NDArray[np.uint8]:
        """(len(idx), size) bytes: the first `size` bytes of the messages `idx` (each at least
        that long), one row each."""
        head = np.frombuffer(self.data, dtype=np.uint8)
        return sliding_window_view(head, size)[self.start[idx]]


def take(raws: Sequence[Raw], idx: NDArray[np.intp]) -> Sequence[Raw]:
    """The messages `idx` of `raws`, in that order (a Packed stays packed)."""
    if isinstance(raws, Packed):
        return raws.take(np.asarray(idx, dtype=np.intp))
    return [raws[i] for i in np.asarray(idx).tolist()]

HEADER = 4                  # encapsulation header bytes; alignment counts from its end
STAMP = 4                   # header.stamp.sec (int32) at 4, header.stamp.nanosec (uint32) at 8
FRAME_ID = 12               # header.frame_id length (uint32) at 12, its bytes from 16

# Matching a layout costs one pass over the messages still undecoded. After this many layouts
# in a row that each took less than 1/_WORTH of them, messages are walked one by one, with a
# match tried again after 1, 2, 4, ... such walks (so a long run of one layout is still found).
_UNPRODUCTIVE = 16
_WORTH = 256


# ----------------------------------------------------------------------------- walking

def _align(pos: int, size: int) -> int:
    """pos rounded up to 4 + a multiple of `size` (XCDR1: aligned after the header)."""
    return pos + (-(pos - HEADER) % size)


def _byte_order(raw: Raw, what: str) -> str:
    """'<' or '>' from the encapsulation header; DecodeError for anything but plain CDR."""
    if len(raw) < HEADER:
        raise DecodeError(f'{what}: {len(raw)} bytes, shorter than the 4-byte CDR encapsulation '
                          'header')
    if raw[0] != 0 or raw[1] > 1:
        raise DecodeError(f'{what}: encapsulation {bytes(raw[:2]).hex()} is not plain CDR '
                          '(0000 big endian or 0001 little endian)')
    return '<' if raw[1] else '>'


def _u32(raw: Raw, pos: int, e: str, what: str, field: str) -> int:
    if pos + 4 > len(raw):
        raise DecodeError(f'{what}: truncated at {field} (needs bytes {pos}-{pos + 3}, message '
                          f'has {len(raw)})')
    return struct.unpack_from(e + 'I', raw, pos)[0]


def _need(raw: Raw, end: int, what: str, field: str) -> None:
    if end > len(raw):
        raise DecodeError(f'{what}: truncated in {field} (needs {end} bytes, message has '
                          f'{len(raw)})')


def _string_end(raw: Raw, pos: int, e: str, what: str, field: str) -> int:
    """End of the CDR string whose length is at pos (checked to fit, length >= 1)."""
    n = _u32(raw, pos, e, what, f'{field} length')
    if n == 0:
        raise DecodeError(f'{what}: {field} has length 0 (a CDR string holds at least its NUL)')
    _need(raw, pos + 4 + n, what, field)
    return pos + 4 + n


def _float64_sequence(raw: Raw, pos: int, e: str, what: str,
                      field: str) -> tuple[int, int, int, tuple[int, int]]:
    """(count, offset of element 0, end, count's byte range) of the float64 sequence whose
    count is at pos (after alignment)."""
    pos = _align(pos, 4)
    count = _u32(raw, pos, e, what, f'{field} count')
    data = _align(pos + 4, 8) if count else pos + 4
    end = data + 8 * count
    _need(raw, end, what, f'{field} ({count} values)')
    return count, data, end, (pos, pos + 4)


def _header(raw: Raw, what: str) -> tuple[str, int, Ranges]:
    """(byte order, end of std_msgs/Header, layout-defining byte ranges so far)."""
    e = _byte_order(raw, what)
    end = _string_end(raw, FRAME_ID, e, what, 'header.frame_id')
    return e, end, [(0, 2), (FRAME_ID, FRAME_ID + 4)]


def _twist_layout(raw: Raw) -> tuple[str, tuple[int, int], Ranges]:
    """TwistStamped: (byte order, (linear.x offset, angular.z offset), layout byte ranges).
    twist is six float64 in a row: linear x y z, angular x y z."""
    what = 'TwistStamped'
    e, pos, ranges = _header(raw, what)
    linear_x = _align(pos, 8)
    _need(raw, linear_x + 48, what, 'twist')
    return e, (linear_x, linear_x + 40), ranges


def _navsatfix_layout(raw: Raw) -> tuple[str, tuple[tuple[int, str] | int, ...], Ranges]:
    """NavSatFix: (byte order, offsets of status.status (int8), latitude, longitude,
    position_covariance[0] and [4] (east and north variance, ENU), position_covariance_type
    (uint8), layout byte ranges). After the header: status int8, service uint16, three float64,
    nine float64 (a fixed array: no count), uint8."""
    what = 'NavSatFix'
    e, pos, ranges = _header(raw, what)
    status = pos
    latitude = _align(_align(status + 1, 2) + 2, 8)
    covariance = latitude + 24
    kind = covariance + 72
    _need(raw, kind + 1, what, 'position_covariance_type')
    return e, ((status, 'i1'), latitude, latitude + 8, covariance, covariance + 32,
               (kind, 'u1')), ranges


def _joint_layout(raw: Raw, joints: Sequence[bytes | None]
                  ) -> tuple[str, tuple[int | None, ...], Ranges]:
    """JointState: (byte order, (position offset, velocity offset) of each joint named in
    `joints` (bytes, or None) one after the other, layout byte ranges); an offset is None where
    that value is absent.

    A joint is the first one of its name; a JointState with no names and exactly one position
    is taken to be that joint (a single-joint publisher that leaves names out)."""
    what = 'JointState'
    e, pos, ranges = _header(raw, what)
    pos = _align(pos, 4)
    count = _u32(raw, pos, e, what, 'name count')
    if count > (len(raw) - pos - 4) // 5:           # each name: 4-byte length + at least NUL
        raise DecodeError(f'{what}: name count {count} does not fit in {len(raw)} bytes')
    ranges.append((pos, pos + 4))
    pos += 4
    index: dict[bytes, int] = {}
    for i in range(count):
        pos = _align(pos, 4)
        end = _string_end(raw, pos, e, what, f'name[{i}]')
        ranges.append((pos, end))                   # length and text: they fix the index
        index.setdefault(bytes(raw[pos + 4:end - 1]), i)
        pos = end
    n_pos, pos_data, pos, span = _float64_sequence(raw, pos, e, what, 'position')
    ranges.append(span)
    n_vel, vel_data, pos, span = _float64_sequence(raw, pos, e, what, 'velocity')
    ranges.append(span)
    _, _, _, span = _float64_sequence(raw, pos, e, what, 'effort')   # only: does it fit
    ranges.append(span)
    offsets: list[int | None] = []
    for joint in joints:
        k = index.get(joint) if joint is not None else None
        if k is None and count == 0 and n_pos == 1:
            k = 0
        offsets.append(pos_data + 8 * k if k is not None and k < n_pos else None)
        offsets.append(vel_data + 8 * k if k is not None and k < n_vel else None)
    return e, tuple(offsets), ranges


# ----------------------------------------------------------------------------- bulk

def _bulk(raws: Sequence[Raw],
          layout_of: Callable[[Raw], tuple[str, tuple[Offset, ...], Ranges]],
          n_values: int) -> tuple[NDArray[np.int64], FloatArray]:
    """Decode messages grouped by layout. layout_of(raw) -> (byte order, offsets, ranges),
    raising DecodeError for a message it cannot walk; an offset is a float64's, or (offset, numpy
    type code) for another number ('i1', 'u1'). Returns (stamp ns int64 [n], values float64
    [n_values, n]); a left-out message has stamp 0 and NaN values, an absent value (offset
    None) is NaN."""
    count = len(raws)
    stamps = np.zeros(count, dtype=np.int64)
    values = np.full((n_values, count), np.nan)
    if not count:
        return stamps, values
    lengths = raws.lengths() if isinstance(raws, Packed) else np.fromiter(
        map(len, raws), dtype=np.int64, count=count)
    order = np.argsort(lengths, kind='stable')
    cuts = np.flatnonzero(np.diff(lengths[order])) + 1
    for idx in np.split(order, cuts):               # one group per message length
        size = int(lengths[idx[0]])
        if size < FRAME_ID + 4:                     # not even a header: all left out
            continue
        if isinstance(raws, Packed):                # rows gathered from the chunk buffer
            block = raws.block(idx, size)
        else:
            # one length (the usual case): idx is 0..n-1 in order (stable sort), join as given
            buf = b''.join(raws if idx.size == count else [raws[i] for i in idx])
            block = np.frombuffer(buf, dtype=np.uint8).reshape(idx.size, size)
        pending = np.arange(idx.size)               # rows of `block` not yet decided
        unproductive = backoff = alone = 0
        while pending.size:
            first = int(pending[0])
            try:
                e, offsets, ranges = layout_of(raws[int(idx[first])])
            except DecodeError:
                pending = pending[1:]               # left out; others may still decode
                continue
            if alone:                               # one-off layouts: walk each by itself
                rows, pending = pending[:1], pending[1:]
                alone -= 1
            else:
                match = _same_layout(block, pending, first, ranges)
                rows = pending[match]
                if rows.size * _WORTH < pending.size:
                    unproductive += 1
                    if unproductive >= _UNPRODUCTIVE:
                        backoff = max(1, 2 * backoff)
                        alone = backoff
                else:
                    unproductive = backoff = 0
                pending = pending[~match]
            # every message at once in order (one length, one layout): no row gathered
            everything = idx.size == count and rows.size == count
            _read(block, idx, None if everything else rows, (e, offsets), (stamps, values))
    return stamps, values


def _same_layout(block: NDArray[np.uint8], rows: NDArray[np.intp], first: int,
                 ranges: Ranges) -> NDArray[np.bool_]:
    """Which of `rows` of `block` hold row `first`'s bytes in every byte range of `ranges`:
    the rows compared a machine word at a time (the words holding such bytes), the bytes
    outside the ranges masked off."""
    n, size = block.shape
    word = next(w for w in (8, 4, 2, 1) if size % w == 0)
    mask = np.zeros(size, dtype=np.uint8)
    for lo, hi in ranges:
        mask[lo:hi] = 0xFF
    words, mask = block.view(f'u{word}'), mask.view(f'u{word}')
    held = np.flatnonzero(mask)
    sub = words[:, held] if rows.size == n else words[rows[:, None], held]
    mask = mask[held]
    return np.all((sub & mask) == (words[first, held] & mask), axis=1)


def _field(block: NDArray[np.uint8], rows: NDArray[np.intp] | None, offset: int,
           dtype: str) -> np.ndarray:
    """The value at `offset` of each of `rows` of `block` (messages of equal length, one per
    row, C order; None: all of them): a strided view, then the rows."""
    n, size = block.shape
    view = np.ndarray((n,), dtype=dtype, buffer=block, offset=offset, strides=(size,))
    return view if rows is None else view[rows]


def _read(block: NDArray[np.uint8], idx: NDArray[np.intp], rows: NDArray[np.intp] | None,
          layout: tuple[str, tuple[tuple[int, str] | int | None, ...]],
          out_columns: tuple[NDArray[np.int64], FloatArray]) -> None:
    """Stamps and values of `rows` (all of one `layout`: byte order, offsets) into the
    outputs `out_columns` (stamps, values) at idx[rows]; rows None: every message, block row i
    being message i."""
    e, offsets = layout
    stamps, values = out_columns
    out = slice(None) if rows is None else idx[rows]
    sec = _field(block, rows, STAMP, e + 'i4').astype(np.int64)
    nsec = _field(block, rows, STAMP + 4, e + 'u4').astype(np.int64)
    stamps[out] = sec * 1_000_000_000 + nsec
    for k, offset in enumerate(offsets):
        if offset is None:
            continue
        offset, kind = offset if isinstance(offset, tuple) else (offset, 'f8')
        values[k, out] = _field(block, rows, offset, e + kind)


# ----------------------------------------------------------------------------- public

def decode_twist(raws: Sequence[Raw]) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """(stamp ns int64, twist.linear.x, twist.angular.z float64) of TwistStamped CDR messages;
    a message that cannot be decoded has stamp 0 and NaN values."""
    stamps, values = _bulk(raws, _twist_layout, 2)
    return stamps, values[0], values[1]


def decode_ground_speed(raws: Sequence[Raw]) -> tuple[NDArray[np.int64], FloatArray]:
    """(stamp ns int64, twist.linear.x m/s float64) of TwistStamped CDR messages."""
    stamps, linear_x, _ = decode_twist(raws)
    return stamps, linear_x


def decode_navsatfix(raws: Sequence[Raw]) -> tuple[NDArray[np.int64], FloatArray, FloatArray,
                                                  FloatArray, FloatArray, FloatArray,
                                                  FloatArray]:
    """(stamp ns int64, status, latitude, longitude, east variance, north variance, covariance
    type) of sensor_msgs/NavSatFix CDR messages, the integers as float64; a message that
    cannot be decoded has stamp 0 and NaN values (NaN status: not a fix)."""
    stamps, values = _bulk(raws, _navsatfix_layout, 6)
    return (stamps, *values)


def decode_joint_states(raws: Sequence[Raw], joint_name: str | None
                        ) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """(stamp ns int64, position, velocity float64) of the joint `joint_name` in JointState CDR
    messages. NaN where the message lacks that joint (NaN position) or its velocity (NaN
    velocity), or cannot be decoded (stamp 0 too). A message with no names and exactly one
    position counts as that joint; joint_name None matches only such messages."""
    stamps, positions, velocities = decode_joints(raws, [joint_name])
    return stamps, positions[0], velocities[0]


def decode_joints(raws: Sequence[Raw], joint_names: Sequence[str | None]
                  ) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """decode_joint_states of several joints in one pass: (stamp ns int64 [n], positions
    [joints, n], velocities [joints, n]), row k for joint_names[k]."""
    joints = [None if name is None else name.encode('utf-8') for name in joint_names]
    stamps, values = _bulk(raws, lambda raw: _joint_layout(raw, joints), 2 * len(joints))
    return stamps, values[0::2], values[1::2]


def decode_string(raw: Raw) -> str:
    """The text of one std_msgs/String CDR message. Raises DecodeError with a
    one-line message for an empty, truncated, unterminated or non-UTF-8 payload."""
    what = 'std_msgs/String'
    e = _byte_order(raw, what)
    end = _string_end(raw, HEADER, e, what, 'data')
    if raw[end - 1] != 0:
        raise DecodeError(f'{what}: data is not NUL-terminated (byte {end - 1} is '
                          f'0x{raw[end - 1]:02x})')
    try:
        return bytes(raw[HEADER + 4:end - 1]).decode('utf-8')
    except UnicodeDecodeError as exc:
        raise DecodeError(f'{what}: data is not UTF-8 ({exc.reason} at byte '
                          f'{HEADER + 4 + exc.start})') from None


# ----------------------------------------------------------------------------- encoding

# primitive type -> (struct format, size = alignment)
_PRIMITIVES = {'bool': ('?', 1), 'boolean': ('?', 1), 'byte': ('B', 1), 'octet': ('B', 1),
               'char': ('B', 1), 'int8': ('b', 1), 'uint8': ('B', 1), 'int16': ('h', 2),
               'uint16': ('H', 2), 'int32': ('i', 4), 'uint32': ('I', 4), 'int64': ('q', 8),
               'uint64': ('Q', 8), 'float': ('f', 4), 'double': ('d', 8)}
_ENCAPSULATION = b'\x00\x01\x00\x00'          # CDR little endian, no options


def encode_message(msg: RosMessage) -> bytes:
    """The CDR bytes (XCDR1 little endian, rosbag2's `cdr`) of an rclpy message, written
    deterministically: every alignment padding byte 0 and nothing after the last field.

    rclpy's serialize_message leaves padding uninitialised and can end a message with 4 bytes
    past its last field (a JointState: rosbags refuses it with "CDR message size mismatch"), so
    two recordings of the same messages differ. This encoder walks the message's own field
    types (`get_fields_and_field_types`): primitives, strings, nested messages, fixed arrays and
    (bounded) sequences of any of them; wide strings are refused (ValueError). The walk of a
    message class's types is made once (`_message_encoder`), not per message."""
    out = bytearray(_ENCAPSULATION)
    _encode_fields(out, msg)
    return bytes(out)


def _pad(out: bytearray, size: int) -> None:
    extra = (len(out) - HEADER) % size
    if extra:
        out.extend(b'\x00' * (size - extra))


_Encoder = Callable[[bytearray, Any], None]

# message class -> the encoder of its fields, in order
_MESSAGE_ENCODERS: dict[type, _Encoder] = {}


def _encode_fields(out: bytearray, msg: RosMessage) -> None:
    encoder = _MESSAGE_ENCODERS.get(type(msg))
    if encoder is None:
        encoder = _MESSAGE_ENCODERS[type(msg)] = _message_encoder(msg)
    encoder(out, msg)


def _message_encoder(msg: RosMessage) -> _Encoder:
    """The encoder of every field of `msg`'s class (the generated classes' field types are
    the class's own, the same for every message of it)."""
    fields = tuple((name, _value_encoder(kind))
                   for name, kind in msg.get_fields_and_field_types().items())

    def encode(out: bytearray, value: Any) -> None:
        for name, encode_field in fields:
            encode_field(out, getattr(value, name))
    return encode


def _element(kind: str) -> tuple[str, int | None]:
    """(element type, fixed length or None for a sequence) of an array or sequence type."""
    if kind.startswith('sequence<'):
        inner = kind[len('sequence<'):-1]
        return inner.split(',')[0].strip(), None
    base, _, count = kind.rpartition('[')
    return base, int(count.rstrip(']'))


def _value_encoder(kind: str) -> _Encoder:
    """The encoder of a field of type `kind`, chosen once: a field's value as the message
    holds it (the generated message classes declare no types)."""
    if kind.startswith('sequence<') or kind.endswith(']'):
        return _array_encoder(kind)
    primitive = _PRIMITIVES.get(kind)
    if primitive is not None:
        fmt, size = primitive
        packer = struct.Struct('<' + fmt).pack

        def encode_primitive(out: bytearray, value: Any) -> None:
            _pad(out, size)
            if fmt == 'B' and not isinstance(value, int):
                value = ord(value) if isinstance(value, (str, bytes)) else int(value)
            out.extend(packer(value))
        return encode_primitive
    if kind == 'string' or kind.startswith('string<'):
        return _encode_string
    if kind.startswith('wstring'):
        def refuse(out: bytearray, value: Any) -> None:
            raise ValueError(f'CDR encoding of {kind} is not supported: allowed primitives, '
                             'strings, messages, arrays and sequences of them')
        return refuse
    return _encode_fields


def _encode_string(out: bytearray, value: Any) -> None:
    data = value.encode('utf-8') + b'\x00'
    _pad(out, 4)
    out.extend(_U32(len(data)))
    out.extend(data)


_U32 = struct.Struct('<I').pack


def _array_encoder(kind: str) -> _Encoder:
    element, count = _element(kind)
    primitive = _PRIMITIVES.get(element)

    def items_of(out: bytearray, value: Any) -> list[Any]:
        items = list(value)
        if count is None:
            _pad(out, 4)
            out.extend(_U32(len(items)))
        return items
    if primitive is not None:
        fmt, size = primitive

        def encode_primitives(out: bytearray, value: Any) -> None:
            items = items_of(out, value)
            if not items:
                return
            _pad(out, size)
            if fmt == 'B':
                items = [v if isinstance(v, int) else ord(v) for v in items]
            out.extend(struct.pack(f'<{len(items)}{fmt}', *items))
        return encode_primitives
    encode_element = _value_encoder(element)

    def encode_elements(out: bytearray, value: Any) -> None:
        for item in items_of(out, value):
            encode_element(out, item)
    return encode_elements
