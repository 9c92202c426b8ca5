"""design_node: scene parameters -> design (core library) -> latched `design` topic (JSON).

Every parameter update is validated by computing the design first: an infeasible one is refused
with the core's one-line reason and the last good design stays published. A five-bar scene
never imports the three-arm gear train; the three-arm parameters are declared only when the
scene's `mechanism` is three_arm. The parameters are the scene's (kinematics.design_inputs).
"""

import sys

from rclpy.node import Node
from std_msgs.msg import String

from planter_ros import interfaces
from planter_ros.config import spec_of
from planter_ros.kinematics.design_inputs import DesignInputs, input_classes
from planter_ros.design import design_for_scene, to_json
from planter_ros.nodes.parameters import ParameterGroup, declare, refuse_undeclared
from planter_ros.nodes.run import run_node
from planter_ros.plausibility import unusual


class DesignNode(Node):
    """Publishes the design of the scene in its parameters; refuses infeasible updates."""

    def __init__(self, arguments=None, **kwargs):
        super().__init__('design_node', **kwargs)
        mechanism = declare(self, spec_of(DesignInputs, 'mechanism'))
        self._publisher = interfaces.DESIGN.publisher(self)
        # a bad scene raises ConfigError here, at start-up
        scene = ParameterGroup(self, input_classes(mechanism), build=self._checked_design,
                               on_change=self._publish)
        self.design = scene.value
        refuse_undeclared(self, arguments)       # a name the scene got wrong: refused
        self._publish(self.design)
        self.get_logger().info(f'{self.design.mechanism} design for '
                               f"{self.design.crop or 'unnamed crop'} published")

    def _checked_design(self, values):
        """The design of a candidate set of values (DesignError refuses the update, the last
        good design stays); its unusual values logged as warnings (planter_ros.plausibility: the
        mechanism's checks; the speed, acceleration and bus checks need the sync node's
        limits)."""
        design = design_for_scene(values)
        for warning in unusual(design):
            self.get_logger().warning(warning)
        return design

    def _publish(self, design):
        self.design = design
        self._publisher.publish(String(data=to_json(design)))


def main(args=None):
    return run_node('design_node', lambda arguments: DesignNode(
        namespace=interfaces.NAMESPACE, arguments=arguments), args)


if __name__ == '__main__':
    sys.exit(main())
