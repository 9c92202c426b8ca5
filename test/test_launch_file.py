"""launch/planter.launch.py: checked where the ROS launch packages exist (not in the PyPI venv)."""
import importlib.util
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
LAUNCH = REPO / 'launch' / 'planter.launch.py'


def console_scripts():
    return set(re.findall(r"'(\w+) = planter_ros\.nodes\.", (REPO / 'setup.py').read_text()))


def test_launch_file_starts_every_node_executable():
    pytest.importorskip('launch')
    pytest.importorskip('launch_ros')
    from launch_ros.actions import Node
    spec = importlib.util.spec_from_file_location('planter_launch', LAUNCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    nodes = [e for e in description.entities if isinstance(e, Node)]
    assert {n.node_executable for n in nodes} == console_scripts()
    names = {a.name for a in description.get_launch_arguments()}
    assert {'scene', 'can_interface', 'can_channel'} <= names


def test_launch_file_names_only_installed_executables():
    """Runs everywhere: the executables the launch file names are console scripts of setup.py."""
    text = LAUNCH.read_text()
    named = set(re.findall(r"executable='(\w+)'", text))
    assert named and named == console_scripts()
