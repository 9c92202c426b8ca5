"""design_node: scene parameters -> design (core library) -> latched `design` topic (JSON).

Every parameter update is validated by computing the design first: an infeasible one is refused
with the core's one-line reason and the last good design stays published. A five-bar scene
never imports the three-arm gear train; the three-arm parameters are declared only when the
scene's `mechanism` is three_arm.
"""

import json
import sys

import rclpy
from rclpy.exceptions import ParameterException, ParameterUninitializedException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from std_msgs.msg import String

from planter_ros import interfaces
from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.scene_design import design_for_scene
from planter_ros.nodes.qos import DESIGN_QOS


def _range(lo, hi):
    return [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]


# name -> (default, description, floating point range or None); SI units
SCENE_PARAMETERS = {
    'crop': ('tomato', 'crop name, for people and recordings', None),
    'mechanism': ('five_bar', 'planting mechanism: five_bar (1 plant/rev) or three_arm '
                  '(3 plants/rev)', None),
    'planting_depth': (0.045, 'planting depth D (m)', _range(0.001, 0.5)),
    'plant_spacing': (0.2, 'plant spacing d along the row (m)', _range(0.05, 2.0)),
    'hole_ratio': (0.05, 'hole entry-exit distance over depth, k = t/D (five-bar); feasible '
                   'while k·D < d and l1 > 0', _range(1e-4, 2.0)),
    'design_method': ('exact', "five-bar reverse design: 'exact' or 'paper' (the paper's "
                      'cube-root approximation)', None),
    'dyad_ratios': ([1.4, 1.5, 1.3], 'five-bar passive dyad l3, l4, l5 over (l1 + l2)', None),
    'nominal_ground_speed': (0.2, 'nominal ground speed v (m/s): reported mechanism speed '
                             '2πv/(n·d)', _range(0.01, 3.0)),
}


# declared only for a three-arm scene (names of planter_ros.kinematics.three_arm); no
# defaults: a scene that lacks one is refused by the model, naming it
THREE_ARM_PARAMETERS = {
    'control_radii': (Parameter.Type.DOUBLE_ARRAY, 'pitch-curve control radii r_i (m)', None),
    'control_angles': (Parameter.Type.DOUBLE_ARRAY, 'pitch-curve control angles θ_i (rad)',
                       None),
    'interpolant': (Parameter.Type.STRING, 'pitch-curve interpolant between control points '
                    '(periodic_cubic by default)', None),
    'carrier_initial_angle': (Parameter.Type.DOUBLE, 'carrier initial angle (rad)', None),
    'arm_initial_angle': (Parameter.Type.DOUBLE, 'planting arm initial angle (rad)', None),
    'arm_length': (Parameter.Type.DOUBLE, 'planting arm length (m)', _range(0.01, 1.0)),
    'pusher_offset': (Parameter.Type.DOUBLE, 'pusher offset H1 from the arm line (m)',
                      _range(0.0, 0.5)),
    'planet_carrier_angle': (Parameter.Type.DOUBLE, 'planet-carrier angle (rad)', None),
    'seedling_height': (Parameter.Type.DOUBLE, 'seedling height (m), for the design goals',
                        _range(0.01, 1.0)),
    'arm_width': (Parameter.Type.DOUBLE, 'planting arm width (m), for the design goals',
                  _range(0.001, 0.2)),
}

ARRAY_PARAMETERS = ('dyad_ratios', 'control_radii', 'control_angles')


class DesignNode(Node):
    """Publishes the design of the scene in its parameters; refuses infeasible updates."""

    def __init__(self, **kwargs):
        super().__init__('design_node', **kwargs)
        for name, (default, description, fp_range) in SCENE_PARAMETERS.items():
            descriptor = ParameterDescriptor(description=description)
            if fp_range:
                descriptor.floating_point_range = fp_range
            self.declare_parameter(name, default, descriptor)
        self._names = list(SCENE_PARAMETERS)
        if self.get_parameter('mechanism').value == 'three_arm':
            for name, (ptype, description, fp_range) in THREE_ARM_PARAMETERS.items():
                descriptor = ParameterDescriptor(description=description)
                if fp_range:
                    descriptor.floating_point_range = fp_range
                self.declare_parameter(name, ptype, descriptor)
                self._names.append(name)
        self._publisher = self.create_publisher(String, interfaces.DESIGN, DESIGN_QOS)
        self.design = design_for_scene(self._values())      # DesignError: bad scene at start
        self._pending = None
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._publish_pending)
        self._publish(self.design)
        self.get_logger().info(f"{self.design['mechanism']} design for "
                               f"{self.design['crop'] or 'unnamed crop'} published")

    def _values(self):
        values = {}
        for name in self._names:
            try:
                value = self.get_parameter(name).value
            except ParameterUninitializedException:       # a three-arm value the scene lacks
                continue
            values[name] = list(value) if name in ARRAY_PARAMETERS else value
        return values

    def _validate(self, parameters):
        values = self._values()
        changed = False
        for p in parameters:
            if p.name in self._names:
                values[p.name] = list(p.value) if p.name in ARRAY_PARAMETERS else p.value
                changed = True
        if not changed:
            return SetParametersResult(successful=True)
        try:
            design = design_for_scene(values)
        except DesignError as exc:
            self.get_logger().warning(f'parameter update refused: {exc}')
            return SetParametersResult(successful=False, reason=str(exc))
        self._pending = design
        return SetParametersResult(successful=True)

    def _publish_pending(self, _parameters):
        if self._pending is not None:
            self.design, self._pending = self._pending, None
            self._publish(self.design)
            self.get_logger().info('design updated and published')

    def _publish(self, design):
        self._publisher.publish(String(data=json.dumps(design, sort_keys=True)))


def main(args=None):
    rclpy.init(args=args)
    node = None
    try:
        node = DesignNode(namespace=interfaces.NAMESPACE)
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (DesignError, ParameterException) as exc:
        print(f'design_node: error: {str(exc).splitlines()[0]}', file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
