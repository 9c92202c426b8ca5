"""What a node sees of the ROS graph, as plain data for the pure core."""

from planter_ros.design_sources import Endpoint, gid_text


def full_name(name, namespace):
    """'/planter/design_node' from a node's name and namespace."""
    return f"{namespace.rstrip('/')}/{name}"


def publishers(node, topic):
    """The Endpoints publishing `topic` (an interfaces.Topic) as `node` sees the graph now."""
    return [Endpoint(full_name(info.node_name, info.node_namespace),
                     gid_text(info.endpoint_gid))
            for info in node.get_publishers_info_by_topic(node.resolve_topic_name(topic.name))]
