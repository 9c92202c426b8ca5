"""CDR field decoding rows: replay's bulk decoder (planter_ros.recording.cdr) against decoding
every message with rosbags' `deserialize_cdr` or rclpy's `deserialize_message` and reading the
same fields off the message objects.

Input: JointStates and TwistStampeds of the layout the graph publishes (the sync node's
`name=['sun_bar']`, one position and velocity, no effort; ground speed with frame_id
'base_link') with varying stamps and values, serialised by rclpy (uninitialised padding
included) and cut to their DDS wire size, as the live monitor records them. (rclpy's
serialize_message leaves 4 bytes more after such a JointState — the recorder's write_message
stores them — and rosbags 0.11.9's deserialize_cdr refuses a message with more than 3 bytes
after its end, so uncut it could not be measured.) Every method produces the same arrays:
stamp (ns), and position + velocity or linear.x + angular.z.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
import os
from typing import Any

from geometry_msgs.msg import TwistStamped
import numpy as np
from numpy.typing import NDArray
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore
from sensor_msgs.msg import JointState

from planter_ros.kinematics.arrays import FloatArray
from planter_ros.recording.cdr import decode_joint_states, decode_twist

from ..registry import BenchContext, Row, bench_case

# (stamps ns, then two float fields) of decoded messages
Fields = tuple[NDArray[np.int64], FloatArray, FloatArray]

JOINT = 'sun_bar'
JOINT_STATE = 'sensor_msgs/msg/JointState'
TWIST_STAMPED = 'geometry_msgs/msg/TwistStamped'
OURS = 'bulk numpy (planter_ros.recording.cdr)'
ROSBAGS = 'rosbags deserialize_cdr + fields'
RCLPY = 'rclpy deserialize_message + fields'
ERROR_OF = ('max |decoded − rosbags deserialize_cdr| over the float fields (position rad, '
            'velocity rad/s; linear.x m/s, angular.z rad/s), absolute; stamps must be identical '
            '(checked); — for rosbags itself')


def _messages(n: int, seed: int, typestore: Typestore
              ) -> tuple[list[bytes], list[bytes], list[bytes]]:
    """n rclpy-serialised JointStates (as serialize_message leaves them, and cut) and
    TwistStampeds (cut) with varying stamps and values; cut = to the size rosbags' serializer
    gives the same message (the wire size)."""
    rng = np.random.default_rng(seed)
    pos, vel, lx, az = rng.normal(size=(4, n)) * np.array([[100.0], [10.0], [2.0], [0.5]])
    stamps = 1_795_325_092_000_000_000 + np.cumsum(rng.integers(9_000_000, 11_000_000, n))
    joints: list[bytes] = []
    twists: list[bytes] = []
    js, tw = JointState(name=[JOINT]), TwistStamped()
    tw.header.frame_id = 'base_link'
    for k in range(n):
        sec, nsec = divmod(int(stamps[k]), 1_000_000_000)
        js.header.stamp.sec = tw.header.stamp.sec = sec
        js.header.stamp.nanosec = tw.header.stamp.nanosec = nsec
        js.position, js.velocity = [float(pos[k])], [float(vel[k])]
        tw.twist.linear.x, tw.twist.angular.z = float(lx[k]), float(az[k])
        joints.append(serialize_message(js))
        twists.append(serialize_message(tw))
    return (joints, _cut(joints, _wire_size(typestore, JOINT_STATE, '', [JOINT])),
            _cut(twists, _wire_size(typestore, TWIST_STAMPED, 'base_link')))


def _wire_size(typestore: Typestore, typename: str, frame_id: str,
               names: Sequence[str] = ()) -> int:
    """Bytes rosbags serialises such a message to (values do not change the size)."""
    t = typestore.types
    header = t['std_msgs/msg/Header'](
        stamp=t['builtin_interfaces/msg/Time'](sec=0, nanosec=0), frame_id=frame_id)
    if typename == JOINT_STATE:
        zeros = np.zeros(len(names))
        msg = t[typename](header=header, name=list(names), position=zeros, velocity=zeros,
                          effort=np.zeros(0))
    else:
        v = t['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)
        msg = t[typename](header=header, twist=t['geometry_msgs/msg/Twist'](linear=v, angular=v))
    return len(typestore.serialize_cdr(msg, typename))


def _cut(raws: Sequence[bytes], size: int) -> list[bytes]:
    if any(len(r) < size for r in raws):
        raise RuntimeError(f'rclpy serialised a message to fewer than the {size} bytes of rosbags')
    return [r[:size] for r in raws]


def _joint_fields(msgs: Sequence[Any], name: str, stamp_of: Callable[[Any], int]) -> Fields:
    """(stamp, position, velocity) of the named joint from message objects (the same rule as
    the bulk decoder: first of that name, or the only position of a nameless JointState)."""
    n = len(msgs)
    stamps = np.empty(n, dtype=np.int64)
    pos, vel = np.full(n, np.nan), np.full(n, np.nan)
    for k, m in enumerate(msgs):
        stamps[k] = stamp_of(m)
        names = list(m.name)
        i = names.index(name) if name in names else (
            0 if not names and len(m.position) == 1 else None)
        if i is not None:
            if i < len(m.position):
                pos[k] = m.position[i]
            if i < len(m.velocity):
                vel[k] = m.velocity[i]
    return stamps, pos, vel


def _twist_fields(msgs: Sequence[Any], stamp_of: Callable[[Any], int]) -> Fields:
    stamps = np.fromiter((stamp_of(m) for m in msgs), dtype=np.int64, count=len(msgs))
    lx = np.fromiter((m.twist.linear.x for m in msgs), dtype=float, count=len(msgs))
    az = np.fromiter((m.twist.angular.z for m in msgs), dtype=float, count=len(msgs))
    return stamps, lx, az


def _stamp(m: Any) -> int:              # a decoded message (rclpy's or rosbags' class)
    return m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec


def _error(got: Fields, ref: Fields, label: str) -> float:
    if not np.array_equal(got[0], ref[0]):
        raise RuntimeError(f'{label}: stamps differ from rosbags')
    for a, b in zip(got[1:], ref[1:]):
        if not np.array_equal(np.isnan(a), np.isnan(b)):
            raise RuntimeError(f'{label}: absent values (NaN) differ from rosbags')
    return float(max(np.max(np.abs(a - b), initial=0.0, where=~np.isnan(b))
                     for a, b in zip(got[1:], ref[1:])))


@bench_case('CDR field decoding')
def cdr_decoding(ctx: BenchContext) -> Iterator[Row]:
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    ts = get_typestore(Stores.ROS2_JAZZY)
    n = ctx.n(100_000, 2_000)
    ctx.progress(f'  serialising {n} JointState and {n} TwistStamped messages with rclpy ...')
    uncut, joints, twists = _messages(n, ctx.seed, ts)

    def joint_fields(msgs: Sequence[Any]) -> Fields:
        return _joint_fields(msgs, JOINT, _stamp)

    def twist_fields(msgs: Sequence[Any]) -> Fields:
        return _twist_fields(msgs, _stamp)
    kinds = {
        'JointState (stamp, position, velocity of one joint)': [
            (OURS, f'{len(joints[0])} bytes', lambda: decode_joint_states(joints, JOINT)),
            (OURS + ', uncut', f'{len(uncut[0])} bytes: as Recorder.write_message stores '
             'it; rosbags refuses these', lambda: decode_joint_states(uncut, JOINT)),
            (ROSBAGS, f'{len(joints[0])} bytes',
             lambda: joint_fields([ts.deserialize_cdr(r, JOINT_STATE) for r in joints])),
            (RCLPY, f'{len(joints[0])} bytes',
             lambda: joint_fields([deserialize_message(r, JointState) for r in joints]))],
        'TwistStamped (stamp, linear.x, angular.z)': [
            (OURS, f'{len(twists[0])} bytes', lambda: decode_twist(twists)),
            (ROSBAGS, f'{len(twists[0])} bytes',
             lambda: twist_fields([ts.deserialize_cdr(r, TWIST_STAMPED) for r in twists])),
            (RCLPY, f'{len(twists[0])} bytes',
             lambda: twist_fields([deserialize_message(r, TwistStamped) for r in twists]))]}
    for label, methods in kinds.items():
        timings, results = {}, {}
        for method, _, fn in methods:
            ctx.progress(f'  {label}: {method} ...')
            results[method] = fn()
            timings[method] = ctx.measure(fn, repeats=5, min_time=0.0)
        base = timings[ROSBAGS].median
        for method, note, _ in methods:
            t = timings[method]
            error = None if method == ROSBAGS else _error(results[method], results[ROSBAGS],
                                                         method)
            yield Row(f'CDR decode: {label}', method, n, 'message', t, error=error,
                      error_of=ERROR_OF,
                      note=f'{n / t.median / 1e3:.0f} k messages/s, {base / t.median:.2g}× '
                           f'rosbags; messages of {note}',
                      extra={'messages_per_s': n / t.median, 'times_rosbags': base / t.median})
