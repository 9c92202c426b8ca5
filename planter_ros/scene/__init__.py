"""Scenes: one ROS 2 parameter file per crop and mechanism (config/*.yaml) for the three planter
nodes, read strictly, resolved and written here.

* `files`: reading a parameter file (bounded size and YAML aliases), `SceneError`;
* `schema`: which parameters each node declares and the rule of which entry may set what; an
  unknown key or a value out of range is refused naming the key, the file and the closest
  valid key. The nodes check the files they are started with by the same rule;
* `resolve`: a checked scene (`open_scene`), what each node gets from it, its design, rows
  antenna and acceptance limits; `load_scene` for one node's flat parameters;
* `writer`: writing a scene (the optimiser's result);
* `design_sources`: who may set the design: the publisher of every design a node accepts.
* `machine_file`: the machine file (one per tractor and planter: its bus, rows, drives and lever
  arms; doc/machine_file.md), read as strictly; `machine_setting`: the sync node's parameter
  naming it.
"""

from .files import MAX_ALIAS_NODES, MAX_SCENE_BYTES, SceneError, read_parameter_file
from .resolve import Scene, default_scene_path, load_scene, open_scene, scene_limits
from .writer import write_scene

__all__ = ['MAX_ALIAS_NODES', 'MAX_SCENE_BYTES', 'Scene', 'SceneError', 'default_scene_path',
           'load_scene', 'open_scene', 'read_parameter_file', 'scene_limits', 'write_scene']
