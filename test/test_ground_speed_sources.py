"""Ground speed from real sources (sensing.ground_speed_sources, nodes.ground_speed_node).

ISOBUS reference frames are built here with struct, straight from ISO 11783-7's parameter
definitions (bytes 1-2 speed 0.001 m/s per bit, bytes 3-6 distance 0.001 m per bit, byte 8
bits 1-2 direction 00 reverse / 01 forward; 29-bit identifier priority·2^26 + PGN·2^8 + source
address), independently of the shipped DBC and of cantools, which the product decodes with."""
import math
import struct
import time

import pytest

from planter_ros import diagnostics
from planter_ros.config import ConfigError
from planter_ros.sensing.ground_speed_sources import (
    CourseYawRate, GroundSpeedSourceConfig, IsobusSpeedDecoder, PulseSpeed, SourceSelector,
    SpeedSample, gnss_speed, imu_yaw_rate)
from ros_fixtures import unique_channel

pytestmark = pytest.mark.realtime          # (test/conftest.py)


def frame_id(pgn, source_address=0x80, priority=3):
    return (priority << 26) | (pgn << 8) | source_address


def speed_frame(pgn, speed, distance=12.345, direction=1, byte7=0xFF, rest=0xFC):
    """The 8 data bytes of a speed message: speed m/s, distance m, direction (2 bits) in byte
    8's low bits and the other bits of byte 8 (`rest`), byte 7 as given."""
    raw = speed if isinstance(speed, int) else round(speed / 0.001)
    return struct.pack('<HIBB', raw, round(distance / 0.001), byte7, (rest & 0xFC) | direction)


PGNS = {65097: 'isobus_ground', 65096: 'isobus_wheel', 61474: 'isobus_selected'}


@pytest.mark.parametrize('pgn', sorted(PGNS))
@pytest.mark.parametrize('speed', [0.0, 0.001, 0.2, 0.72 / 3.6, 1.234, 5.0, 64.255])
def test_each_isobus_speed_message_decodes_to_the_reference_value(pgn, speed):
    decoder = IsobusSpeedDecoder()
    sample = decoder.decode(1.5, frame_id(pgn), speed_frame(pgn, speed))
    assert sample == SpeedSample(1.5, pytest.approx(speed, abs=5e-4), PGNS[pgn])


@pytest.mark.parametrize('pgn', sorted(PGNS))
def test_reverse_is_negative_and_any_source_address_or_priority_is_read(pgn):
    decoder = IsobusSpeedDecoder()
    sample = decoder.decode(0.0, frame_id(pgn, 0x26, priority=6), speed_frame(pgn, 0.5,
                                                                               direction=0))
    assert sample.speed == pytest.approx(-0.5) and sample.source == PGNS[pgn]
    # "not available" direction: taken as forward
    assert decoder.decode(0.0, frame_id(pgn), speed_frame(pgn, 0.5, direction=3)).speed == 0.5


@pytest.mark.parametrize('raw, reason', [(0xFFFF, 'not_available'), (0xFE00, 'not_available'),
                                         (0xFB00, 'not_available')])
def test_error_and_not_available_values_give_no_sample(raw, reason):
    decoder = IsobusSpeedDecoder()
    assert decoder.decode(0.0, frame_id(65097), speed_frame(65097, raw)) is None
    assert decoder.decode(0.0, frame_id(65097), speed_frame(65097, 1.0, direction=2)) is None
    assert decoder.rejected[reason] == 1 and decoder.rejected['direction_error'] == 1
    assert decoder.decode(0.0, frame_id(65097), speed_frame(65097, 0xFAFF)).speed == 64.255


def test_other_frames_are_ignored():
    decoder = IsobusSpeedDecoder()
    assert decoder.decode(0.0, frame_id(65265), bytes(8)) is None          # CCVS, a truck's
    assert decoder.decode(0.0, 0x123, bytes(8), is_extended_id=False) is None
    assert decoder.decode(0.0, frame_id(65097), bytes(4)) is None          # short frame
    assert decoder.ignored == 2 and decoder.rejected['short_frame'] == 1


def test_the_dbc_agrees_with_the_reference_layout_on_every_field():
    """The wheel-based message's other fields and the selected speed's source, from the DBC."""
    import cantools
    from planter_ros.sensing.ground_speed_sources import default_dbc
    db = cantools.database.load_file(default_dbc())
    data = struct.pack('<HIBB', 2500, 987654, 42, 0b10_01_01_01)
    wbsd = db.get_message_by_name('WBSD').decode(data, decode_choices=False)
    assert wbsd == {'WheelBasedMachineSpeed': 2.5, 'WheelBasedMachineDistance': 987.654,
                    'MaximumTimeOfTractorPower': 42, 'WheelBasedMachineDirection': 1,
                    'KeySwitchState': 1, 'ImplementStartStopOperations': 1,
                    'OperatorDirectionReversed': 2}
    # machine selected speed: exit code 5 in byte 7, direction forward, source
    # navigation-based (2) in bits 3-5 and limit status 1 in bits 6-8 of byte 8
    data = struct.pack('<HIBB', 800, 1000, 5, 0b001_010_01)
    mss = db.get_message_by_name('MSS').decode(data, decode_choices=False)
    assert (mss['MachineSelectedSpeed'], mss['MachineSelectedSpeedExitReasonCode'],
            mss['MachineSelectedDirection'], mss['MachineSelectedSpeedSource'],
            mss['MachineSelectedSpeedLimitStatus']) == (0.8, 5, 1, 2, 1)


def test_gnss_speed_and_the_yaw_rate_from_its_course():
    """A machine on a 10 m circle at 1 m/s, counter-clockwise: 0.1 rad/s."""
    course = CourseYawRate(min_speed=0.3)
    rates = []
    for k in range(50):
        t = 0.1 * k
        heading = 0.1 * t + 3.0          # across ±π on the way
        east, north = math.cos(heading), math.sin(heading)
        assert gnss_speed(t, east, north).speed == pytest.approx(1.0)
        rates.append(course.update(t, east, north))
    assert rates[0] is None and all(r == pytest.approx(0.1) for r in rates[1:])
    assert course.update(5.0, 0.1, 0.0) is None               # too slow to have a course
    assert gnss_speed(0.0, math.nan, 0.0) is None


def test_imu_yaw_rate():
    assert imu_yaw_rate(0.25) == 0.25
    assert math.isnan(imu_yaw_rate(0.25, covariance0=-1.0))


def test_pulse_count_speed_with_the_counter_wrapping():
    pulses = PulseSpeed(pulses_per_metre=100.0, bits=16)
    assert pulses.update(0.0, 65_500) is None
    sample = pulses.update(0.5, 36)            # 72 pulses, through the wrap: 0.72 m in 0.5 s
    assert sample.speed == pytest.approx(1.44) and sample.source == 'pulses'
    with pytest.raises(ValueError, match='pulses_per_metre'):
        PulseSpeed(0.0)


def test_a_lost_isobus_source_falls_back_to_gnss_within_half_a_second():
    """ISOBUS every 100 ms until it stops at t = 5 s, GNSS at 10 Hz throughout: GNSS is used
    from within 0.5 s after the last ISOBUS sample, with the switch said; ISOBUS back, it is
    used again at once."""
    selector = SourceSelector(['isobus_selected', 'gnss'], timeout=0.3)
    published = []
    for k in range(100):
        t = 0.1 * k
        if t < 5.0 or t > 8.0:
            out = selector.offer(SpeedSample(t, 1.0, 'isobus_selected'))
            if out:
                published.append(out)
        out = selector.offer(SpeedSample(t + 0.05, 0.98, 'gnss'))
        if out:
            published.append(out)
    last_isobus = max(s.t for s in published if s.source == 'isobus_selected' and s.t < 6)
    first_gnss = min(s.t for s in published if s.source == 'gnss')
    assert 0.0 < first_gnss - last_isobus <= 0.5
    gap = max(b.t - a.t for a, b in zip(published, published[1:]))
    assert gap <= 0.5                                      # no hole in what is published
    texts = [text for _, text in selector.events]
    assert texts[0] == 'using isobus_selected'
    assert texts[1].startswith('isobus_selected lost (no sample for 0.3')
    assert texts[1].endswith('using gnss') and texts[2] == 'isobus_selected back: using ' \
                                                           'isobus_selected'
    assert not any(s.source == 'gnss' and s.t > 8.2 for s in published)


def test_the_source_settings_are_checked():
    with pytest.raises(ConfigError, match='sources = .* allowed a list of'):
        GroundSpeedSourceConfig(sources=['radar'])
    with pytest.raises(ConfigError, match='pulses_per_metre = 0'):
        GroundSpeedSourceConfig(sources=['pulses'])
    with pytest.raises(ConfigError, match='yaw_rate_source'):
        GroundSpeedSourceConfig(yaw_rate_source='compass')


def test_the_node_falls_back_from_isobus_to_gnss_with_a_diagnostic(ros):
    """ground_speed_node on a virtual ISOBUS: frames every 100 ms, then none; GNSS velocity
    published beside them. The node's ground_speed switches to GNSS within 0.5 s of the last
    ISOBUS frame and /diagnostics says so."""
    import can
    from geometry_msgs.msg import TwistWithCovarianceStamped
    from rclpy.parameter import Parameter

    from planter_ros import interfaces
    from planter_ros.nodes.ground_speed_node import GroundSpeedNode
    channel = unique_channel('isobus')
    node_bus = can.Bus(interface='virtual', channel=channel)
    tractor = can.Bus(interface='virtual', channel=channel)
    try:
        node = ros.add(GroundSpeedNode(
            bus=node_bus, context=ros.context, namespace='/gs_test',
            parameter_overrides=[Parameter('sources', value=['isobus_ground', 'gnss']),
                                 Parameter('yaw_rate_source', value='gnss')]))
        probe = ros.node('probe')
        speeds, reports = [], []
        probe.create_subscription(
            interfaces.GROUND_SPEED.msg_class(), '/gs_test/ground_speed',
            lambda m: speeds.append((time.monotonic(), m.header.frame_id, m.twist.linear.x)),
            interfaces.GROUND_SPEED.qos.profile())
        probe.create_subscription(interfaces.DIAGNOSTICS.msg_class(), '/diagnostics',
                                  reports.append, interfaces.DIAGNOSTICS.qos.profile())
        gnss = probe.create_publisher(TwistWithCovarianceStamped, '/gs_test/gnss/vel',
                                      interfaces.GNSS_VELOCITY.qos.profile())
        last_frame = None
        ros.spin_for(0.5)                       # discovery settles before the run
        start = time.monotonic()
        next_gnss = next_frame = start
        while time.monotonic() - start < 3.0:
            now = time.monotonic()
            if now >= next_frame and now - start < 1.5:
                tractor.send(can.Message(arbitration_id=frame_id(65097), is_extended_id=True,
                                         data=speed_frame(65097, 0.5)))
                last_frame, next_frame = now, next_frame + 0.1
            if now >= next_gnss:
                msg = TwistWithCovarianceStamped()
                msg.twist.twist.linear.x, msg.twist.twist.linear.y = 0.3, 0.4
                gnss.publish(msg)
                next_gnss += 0.1
            ros.executor.spin_once(timeout_sec=0.005)
        ros.spin_until(lambda: any(diagnostics.values(s).get('source') == 'gnss'
                                   for r in reports for s in r.status), timeout=2.0)
    finally:
        tractor.shutdown()
    isobus = [s for s in speeds if s[1] == 'isobus_ground']
    assert isobus and all(s[2] == pytest.approx(0.5) for s in isobus)
    # after the last ISOBUS sample: GNSS, within 0.5 s of the last frame sent
    last = max(i for i, s in enumerate(speeds) if s[1] == 'isobus_ground')
    fallback = speeds[last + 1:]
    assert fallback and all(s[1] == 'gnss' for s in fallback)
    assert all(s[2] == pytest.approx(0.5) for s in fallback)        # |(0.3, 0.4)| m/s
    assert 0.0 < fallback[0][0] - last_frame <= 0.5, fallback[0][0] - last_frame
    print(f'ISOBUS -> GNSS fallback {fallback[0][0] - last_frame:.3f} s after the last frame')
    # while ISOBUS talked it was used (GNSS only before its first frame was heard)
    first = min(i for i, s in enumerate(speeds) if s[1] == 'isobus_ground')
    assert sum(s[1] == 'gnss' for s in speeds[first:last]) <= 2
    status = [s for r in reports for s in r.status if diagnostics.values(s).get('source')
              == 'gnss'][-1]
    assert diagnostics.level_of(status) == diagnostics.WARN
    assert 'isobus_ground lost' in ' '.join(diagnostics.values(status).values())
    node_bus.shutdown()
    assert node.published >= len(isobus)
