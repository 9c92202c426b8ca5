"""The few CDR fields replay needs, decoded in bulk with numpy.

Replay reads tens of thousands of TwistStamped and JointState messages per bag but needs only a
stamp and one or two float64s from each. Messages of one layout (same length, same bytes where
the layout is decided: encapsulation header, frame_id, joint names, array counts; padding bytes
are not compared, rclpy leaves them uninitialised) share their byte offsets, so the first one of
each layout is walked and the rest are decoded as columns of a byte matrix.
"""

import struct

import numpy as np

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
