"""CAN bus load: worst-case frame lengths, the load of a machine's configuration, and the refusal
above 70 % (one line naming rows, periods and bit rate), also by the sync node at start-up."""
from dataclasses import replace

import pytest
from rclpy.parameter import Parameter

from planter_ros.drive.bus_load import LIMIT, BusTiming, bus_load, check_bus_load, frame_bits
from planter_ros.drive.errors import DriveConfigError

pytestmark = pytest.mark.realtime          # (test/conftest.py)

DEFAULTS = BusTiming(control_period=0.02, ground_speed_rate=50.0, feedback_period=0.01,
                     drive_heartbeat_period=0.1, heartbeat_period=0.1)


def csp_at(sync_period):
    return replace(DEFAULTS, sync_period=sync_period)


def test_worst_case_frame_lengths_of_can_2_0a():
    # 47 + 8n bits, plus a stuff bit after every 4 of the 34 + 8n stuffed bits
    assert frame_bits(0) == 47 + 8
    assert frame_bits(1) == 55 + 10
    assert frame_bits(6) == 95 + 20           # the RPDO
    assert frame_bits(8) == 111 + 24
    with pytest.raises(ValueError):
        frame_bits(9)


def test_load_of_a_four_row_machine_counts_every_frame():
    load = bus_load(4, 500_000, DEFAULTS)
    per_row = 100 * 115 + 100 * 95 + 100 * 135 + 10 * 65      # RPDO, TPDO1, TPDO2, heartbeat
    assert load.bits_per_second == pytest.approx(4 * per_row + 10 * 65)
    assert load.frames_per_second == pytest.approx(4 * 310 + 10)
    assert load.load == pytest.approx((4 * per_row + 650) / 500_000)
    assert dict(load.values())['bus load'] == f'{100 * load.load:.1f} %'


def test_eight_rows_fit_500_kbit_and_are_refused_at_250_kbit():
    check_bus_load(bus_load(8, 500_000, DEFAULTS), [], DEFAULTS)      # 56 %
    load = bus_load(8, 250_000, DEFAULTS)
    assert load.load > LIMIT
    names = [f'row{i}' for i in range(8)]
    with pytest.raises(DriveConfigError) as info:
        check_bus_load(load, names, DEFAULTS)
    message = str(info.value)
    assert '\n' not in message
    for word in ('CAN bus load 112.7 % is out of range', 'allowed <= 70 %', 'row0, row1',
                 '250000 bit/s', 'control_period = 20 ms', '50 Hz', 'feedback_period = 10 ms',
                 'at most 4 rows fit'):
        assert word in message


def test_the_sync_node_refuses_an_overloaded_bus_at_start_up(ros):
    from planter_ros.nodes.sync_node import SyncNode
    rows = [f'r{i}' for i in range(6)]
    params = [Parameter('can_bitrate', value=125_000), Parameter('rows', value=rows)]
    for i, name in enumerate(rows):
        params += [Parameter(f'{name}.lateral_offset', value=0.5 * i),
                   Parameter(f'{name}.drive_node_id', value=i + 1)]
    with pytest.raises(DriveConfigError, match=r'CAN bus load .* \(r0, r1, r2, r3, r4, r5 at '
                                               r'125000 bit/s'):
        SyncNode(context=ros.context, parameter_overrides=params)


def test_csp_counts_a_sync_and_per_row_an_rpdo_and_two_tpdos_every_period():
    load = bus_load(8, 500_000, csp_at(0.01), csp=True)
    per_period = 55 + 8 * (115 + 95 + 135)                  # SYNC + per row RPDO, TPDO1, TPDO2
    heartbeats = (8 * 10 + 10) * 65                         # per second
    assert load.bits_per_second == pytest.approx(100 * per_period + heartbeats)
    assert load.csp and load.load == pytest.approx(0.575, abs=0.001)      # fits at 10 ms
    # 8 RPDOs alone take 1.84 ms of a 500 kbit/s bus; with the feedback 5.6 ms per period
    assert 8 * 115 / 500_000 == pytest.approx(1.84e-3)
    assert load.wire_per_period == pytest.approx(5.75e-3, abs=0.01e-3)


def test_a_csp_machine_over_the_limit_is_refused_naming_the_knobs_that_fix_it():
    names = [f'row{i}' for i in range(8)]
    load = bus_load(8, 500_000, csp_at(0.004), csp=True)
    with pytest.raises(DriveConfigError) as info:
        check_bus_load(load, names, DEFAULTS)
    message = str(info.value)
    assert '\n' not in message
    for word in ('CAN bus load 141.9 % is out of range', 'cyclic synchronous position',
                 'sync_period = 4 ms', 'at most 3 rows fit', 'lengthen sync_period',
                 'raise can_bitrate', 'second bus'):
        assert word in message, word
    # the knobs do fix it: 1 Mbit/s at 4 ms is still over, 1 Mbit/s at 5 ms fits
    assert bus_load(8, 1_000_000, csp_at(0.004), csp=True).load > LIMIT
    check_bus_load(bus_load(8, 1_000_000, csp_at(0.005), csp=True), names,
                   DEFAULTS)
