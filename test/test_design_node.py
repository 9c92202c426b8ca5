"""design_node: latched design, validated parameter updates, only what the scene needs."""
import subprocess
import sys

import pytest
from rclpy.parameter import Parameter

from planter_ros import interfaces
from planter_ros.design import from_json
from planter_ros.kinematics.errors import DesignError
from planter_ros.nodes.design_node import DesignNode

pytestmark = pytest.mark.realtime          # (test/conftest.py)

# every scene gives its nozzle's width (no default): the tomato scene's
NOZZLE = [Parameter('nozzle_width', value=0.04)]



def subscribe(ros, name):
    got = []
    interfaces.DESIGN.subscribe(ros.node(name), lambda m: got.append(from_json(m.data)))
    return got


def test_late_subscriber_gets_the_latched_design(ros):
    ros.add(DesignNode(context=ros.context, parameter_overrides=NOZZLE))
    ros.spin_for(0.2)                       # published long before anyone listens
    got = subscribe(ros, 'late_listener')
    assert ros.spin_until(lambda: got)
    d = got[-1]
    assert d.mechanism == 'five_bar' and d.plants_per_revolution == 1
    assert d.plant_spacing == 0.2 and d.planting_depth == 0.045
    assert d.l2 - d.l1 > 0 and d.assemblable is True
    assert d.nozzle_width == 0.04                     # for the monitor's holes
    assert abs(d.nominal_mechanism_speed - 2 * 3.141592653589793) < 1e-9


def test_infeasible_update_refused_with_reason_and_old_design_kept(ros):
    node = ros.add(DesignNode(context=ros.context, parameter_overrides=NOZZLE))
    got = subscribe(ros, 'listener')
    assert ros.spin_until(lambda: got)
    before = got[-1]
    result = node.set_parameters([Parameter('hole_ratio', value=1.9)])[0]
    assert not result.successful
    assert 'hole_ratio = 1.9 is out of range: allowed 0 < k <' in result.reason
    assert node.get_parameter('hole_ratio').value == 0.05
    ros.spin_for(0.2)
    assert got[-1] == before and len(got) == 1
    late = subscribe(ros, 'late_listener')            # what a restarted node would see
    assert ros.spin_until(lambda: late) and late[-1] == before


def test_out_of_descriptor_range_and_unknown_method_are_refused(ros):
    node = ros.add(DesignNode(context=ros.context, parameter_overrides=NOZZLE))
    assert not node.set_parameters([Parameter('planting_depth', value=5.0)])[0].successful
    res = node.set_parameters([Parameter('design_method', value='magic')])[0]
    assert not res.successful and 'exact or paper' in res.reason
    res = node.set_parameters([Parameter('dyad_ratios', value=[0.2, 0.2, 3.0])])[0]
    assert not res.successful and 'dyad' in res.reason
    assert node.design.method == 'exact'


def test_feasible_update_publishes_new_design(ros):
    node = ros.add(DesignNode(context=ros.context, parameter_overrides=NOZZLE))
    got = subscribe(ros, 'listener')
    assert ros.spin_until(lambda: got)
    assert node.set_parameters([Parameter('plant_spacing', value=0.3)])[0].successful
    assert ros.spin_until(lambda: len(got) == 2)
    assert got[-1].plant_spacing == 0.3 and got[-1].l1 != got[0].l1


def test_parameters_have_descriptions_and_ranges(ros):
    node = ros.add(DesignNode(context=ros.context, parameter_overrides=NOZZLE))
    for name in ('planting_depth', 'plant_spacing', 'hole_ratio', 'nominal_ground_speed'):
        desc = node.describe_parameter(name)
        assert desc.description and desc.floating_point_range[0].to_value > 0
    assert node.describe_parameter('mechanism').description


def test_three_arm_scene_is_routed_to_the_three_arm_model(ros):
    node = ros.add(DesignNode(context=ros.context, parameter_overrides=NOZZLE))
    res = node.set_parameters([Parameter('mechanism', value='three_arm')])[0]
    assert not res.successful                     # five-bar scene: no three-arm parameters
    assert 'control_radii' in res.reason
    assert node.design.mechanism == 'five_bar'


def test_three_arm_scene_declares_its_parameters(ros):
    overrides = NOZZLE + [Parameter('mechanism', value='three_arm')]
    with pytest.raises(DesignError, match='control_radii'):
        DesignNode(context=ros.context, parameter_overrides=overrides)


def test_five_bar_scene_never_imports_the_gear_train():
    code = ('import sys; from planter_ros.scene import load_scene; '
            'from planter_ros.design import design_for_scene; '
            'design_for_scene(load_scene("config/tomato_five_bar.yaml")); '
            'print(sorted(m for m in sys.modules if "three_arm" in m or m == "scipy"))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         cwd=str(__import__('pathlib').Path(__file__).parents[1]), timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == '[]'


def test_a_scene_without_its_nozzle_width_is_refused_naming_it(ros):
    with pytest.raises(DesignError, match='nozzle_width is required: allowed number 0..0.5 m'):
        DesignNode(context=ros.context)
