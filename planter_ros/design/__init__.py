"""The typed design of a planting unit: one frozen dataclass per mechanism (`model`), built and
checked from a scene in one place (`build.design_for_scene`), turned into and read from the
`design` topic's JSON in one place (`message.to_json` / `message.from_json`). Every consumer
(the nodes, replay, the simulation, the demo, the bench) reads attributes, never string keys.
`text` prints the design commands' results for people.

The names below load their module on first use, so `planter design five-bar` (which needs only
`text`) loads nothing else; the mechanism models are imported only while a design is built
(the three-arm gear train for a three-arm scene only).
"""

from importlib import import_module
from typing import Any

__all__ = ['Design', 'DesignMessageError', 'FiveBar', 'GoalResult', 'ThreeArm', 'TipPath',
           'design_for_scene', 'from_dict', 'from_json', 'to_dict', 'to_json']

_HOME = {'Design': 'model', 'FiveBar': 'model', 'GoalResult': 'model', 'ThreeArm': 'model',
         'TipPath': 'model', 'DesignMessageError': 'message', 'from_dict': 'message',
         'from_json': 'message', 'to_dict': 'message', 'to_json': 'message',
         'design_for_scene': 'build'}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    return getattr(import_module(f'{__name__}.{_HOME[name]}'), name)


def __dir__() -> list[str]:
    return sorted(__all__)
