"""The rice three-arm scene (paper 2's parameter set) and its mechanism, shared by the three-arm
test modules (built once per module that imports them)."""
import pytest

from planter_ros.kinematics.three_arm import ThreeArmMechanism
from planter_ros.scene import load_scene

from cli_helpers import REPO


@pytest.fixture(scope='module')
def params():
    return load_scene(REPO / 'config' / 'rice_three_arm.yaml')


@pytest.fixture(scope='module')
def mech(params):
    return ThreeArmMechanism.from_parameters(params)
