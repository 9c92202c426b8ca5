"""monitor_node parameters: declared with ranges, bad updates refused, last good state kept."""
import math

import pytest
import rclpy
from rclpy.parameter import Parameter

from planter_ros.nodes.monitor_node import MonitorNode

pytestmark = pytest.mark.realtime          # (test/conftest.py)


@pytest.fixture
def node():
    context = rclpy.Context()
    rclpy.init(context=context)
    n = MonitorNode(context=context, parameter_overrides=[Parameter('record', value=False)])
    yield n
    n.destroy_node()
    rclpy.try_shutdown(context=context)


def test_parameters_have_descriptions_and_ranges(node):
    for name in ('upright_threshold', 'window', 'split_size', 'split_duration', 'flush_period',
                 'bag_path', 'record', 'track_length', 'fix_window', 'max_fix_sigma',
                 'max_fix_age', 'antenna_position'):
        assert node.describe_parameter(name).description
    d = node.describe_parameter('upright_threshold').floating_point_range[0]
    assert d.from_value == 0.0 and d.to_value == pytest.approx(math.pi / 2)
    assert node.settings.upright_threshold == pytest.approx(math.radians(30))


def test_invalid_updates_are_refused_and_the_last_good_settings_stay(node):
    results = node.set_parameters([Parameter('upright_threshold', value=2.5),
                                   Parameter('window', value=0),
                                   Parameter('bag_path', value='elsewhere')])
    assert not any(r.successful for r in results)
    assert node.settings.upright_threshold == pytest.approx(math.radians(30))
    assert node.settings.window == 20
    ok = node.set_parameters([Parameter('upright_threshold', value=0.7)])
    assert ok[0].successful and node.settings.upright_threshold == 0.7
