"""What a node sees of the ROS graph, as plain data for the pure core."""

import time

from rclpy.clock import Clock, ClockType

from planter_ros import interfaces
from planter_ros.scene.design_sources import Endpoint, gid_text


def full_name(name, namespace):
    """'/planter/design_node' from a node's name and namespace."""
    return f"{namespace.rstrip('/')}/{name}"


def publishers(node, topic):
    """The Endpoints publishing `topic` (an interfaces.Topic) as `node` sees the graph now."""
    return [Endpoint(full_name(info.node_name, info.node_namespace),
                     gid_text(info.endpoint_gid))
            for info in node.get_publishers_info_by_topic(node.resolve_topic_name(topic.name))]


def when_named(node, sources, attribution, write, wait=3.0, period=0.05):
    """Call write(attribution) once the graph names the node that published a design.

    A latched design can be delivered before discovery has told this node the publisher's
    name; then the graph is asked again every `period` (steady clock: simulated time may stand
    still) for at most `wait` seconds, and what is known by then is written."""
    if attribution.named:
        write(attribution)
        return
    deadline = time.monotonic() + wait
    timer = None

    def retry():
        sources.refresh(publishers(node, interfaces.DESIGN))
        named = sources.named(attribution)
        if named.named or time.monotonic() > deadline:
            node.destroy_timer(timer)
            write(named)

    timer = node.create_timer(period, retry, clock=Clock(clock_type=ClockType.STEADY_TIME))


def log_accepted_design(node, sources, what, effect):
    """Attribute a design `node` just accepted to its publisher (sources: DesignSources) and log
    it once the graph names that node: the first as info, a change as info, a change by another
    node than the first design's as a warning. `what` describes the design, `effect` says
    when the change takes effect."""
    source = sources.accepted(publishers(node, interfaces.DESIGN))
    changes = sources.changes

    def write(named):
        if named.first:
            node.get_logger().info(f'design from {named.text}: {what}')
            return
        text = f'design change {changes} from {named.text}: {what}; {effect}'
        if named.foreign:
            node.get_logger().warning(f'{text} (not the publisher of the first design, '
                                      f'{sources.first.text})')
        else:
            node.get_logger().info(text)

    when_named(node, sources, source, write)
