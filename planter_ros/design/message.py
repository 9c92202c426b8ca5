"""The design as the `design` topic carries it (std_msgs/String, JSON, SI units), both ways.

`to_json(design)` is what the design node publishes; `from_json(text)` is how the sync node,
the monitor, the demo's observer and replay read it. A message that is not a planter design
(not JSON, not an object, no or an unknown mechanism, a required field missing, a value out
of range) is refused with a one-line `DesignMessageError` naming the field. Fields a newer
publisher adds are ignored; fields an older one lacked are None (model.py).

The JSON keys are the dataclass fields; a five-bar's also carry `depth` and `spacing` (the
same D and d, as the mechanism model names them), so the message is what it always was.
"""

from dataclasses import MISSING, asdict, fields
import json
import math
from typing import Any

from planter_ros.config import ConfigError, coerce, spec_of
from planter_ros.kinematics.errors import DesignError
from planter_ros.kinematics.design_inputs import DesignInputs
from planter_ros.kinematics.mechanisms import PLANTS_PER_REVOLUTION

from .model import Design, FiveBar, GoalResult, ThreeArm, TipPath

__all__ = ['DesignMessageError', 'MECHANISM_CLASSES', 'from_dict', 'from_json', 'to_dict',
           'to_json']

MECHANISM_CLASSES: dict[str, type[Design]] = {cls.mechanism: cls for cls in (FiveBar, ThreeArm)}
_ALIASES = {'planting_depth': 'depth', 'plant_spacing': 'spacing'}   # older five-bar keys
_POSITIVE = ('plant_spacing', 'planting_depth', 'l1', 'l2')          # finite and > 0 (m)


class DesignMessageError(DesignError):
    """A `design` message that is not a usable planter design (one line)."""

    def __init__(self, text: str) -> None:
        ConfigError.__init__(self, f'design message: {text}')
        self.parameter = self.value = self.allowed = None


def to_dict(design: Design) -> dict[str, Any]:
    """The JSON-ready dict of a design (lists for tuples; fields that are None left out)."""
    out: dict[str, Any] = {'mechanism': design.mechanism}
    for f in fields(design):
        value = getattr(design, f.name)
        if value is None:
            continue
        if isinstance(value, TipPath):
            value = {'angle': list(value.angle), 'x': list(value.x), 'y': list(value.y)}
        elif f.name == 'goals':
            value = [{k: v for k, v in asdict(goal).items() if k != 'basis' or v is not None}
                     for goal in value]
        elif isinstance(value, tuple):
            value = list(value)
        out[f.name] = value
    if isinstance(design, FiveBar):
        out.update(depth=design.planting_depth, spacing=design.plant_spacing)
    return out


def to_json(design: Design) -> str:
    """The `design` topic's text of a design (keys sorted: the same design, the same text)."""
    return json.dumps(to_dict(design), sort_keys=True, allow_nan=False)


def from_json(text: str) -> Design:
    """The design a `design` message carries; DesignMessageError if it carries none."""
    try:
        data = json.loads(text)
    except (TypeError, ValueError) as exc:
        raise DesignMessageError(f'not JSON: allowed a JSON object ({_short(exc)})') from None
    return from_dict(data)


def from_dict(data: Any) -> Design:
    """The design of the `design` topic's JSON object (already parsed)."""
    if not isinstance(data, dict):
        raise DesignMessageError(f'design = {type(data).__name__} is out of range: allowed a '
                                 'JSON object')
    mechanism = data.get('mechanism')
    if not isinstance(mechanism, str) or mechanism not in MECHANISM_CLASSES:
        shown = 'missing' if mechanism is None else repr(mechanism)[:40]
        raise DesignMessageError(f'mechanism = {shown} is out of range: allowed '
                                 f'{" or ".join(MECHANISM_CLASSES)}')
    cls = MECHANISM_CLASSES[mechanism]
    values: dict[str, object] = {}
    for f in fields(cls):
        value = data.get(f.name)
        if value is None and f.name in _ALIASES and cls is FiveBar:
            value = data.get(_ALIASES[f.name])
        if value is not None:
            values[f.name] = value
    if 'plants_per_revolution' not in values:
        values['plants_per_revolution'] = PLANTS_PER_REVOLUTION[mechanism]
    required = [f.name for f in fields(cls)
                if f.default is MISSING and f.default_factory is MISSING]
    for name in required:
        if name not in values:
            raise DesignMessageError(f'{mechanism} without {name}: allowed {_ALLOWED[name]}')
    # each value checked by _value against its field: a field's type, known to _value only
    checked: dict[str, Any] = {name: _value(name, value) for name, value in values.items()}
    return cls(**checked)


def _value(name: str, value: object) -> object:
    """One field's value checked and made immutable (tuples for lists)."""
    if name in _POSITIVE:
        return _positive(name, value)
    if name == 'plants_per_revolution':
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise DesignMessageError(f'{name} = {_shown(value)} is out of range: allowed an '
                                     'integer >= 1')
        return value
    if name in ('nozzle_width', 'nominal_ground_speed', 'top_ground_speed'):
        spec = spec_of(DesignInputs, name)
        if name == 'top_ground_speed':          # resolved: never 0
            spec = spec_of(DesignInputs, 'nominal_ground_speed')
        try:
            return coerce(spec, value)
        except ConfigError as exc:
            raise DesignMessageError(str(exc).replace(spec.name, name, 1)) from None
    if name == 'tip_path':
        return _tip_path(value)
    if name == 'goals':
        if not isinstance(value, list) or not all(isinstance(g, dict) for g in value):
            raise DesignMessageError('goals is not a list of objects: allowed [{name, value, '
                                     'lower, upper, unit, passed}, ...]')
        known = {f.name for f in fields(GoalResult)}
        try:
            return tuple(GoalResult(**{k: v for k, v in g.items() if k in known})
                         for g in value)
        except TypeError as exc:            # a goal without one of its required fields
            raise DesignMessageError(f'goals: {_short(exc)}') from None
    if isinstance(value, list):
        return tuple(value)
    return value


def _positive(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and value > 0):
        raise DesignMessageError(f'{name} = {_shown(value)} is out of range: allowed finite '
                                 'and > 0 m')
    return float(value)


def _tip_path(value: object) -> TipPath:
    allowed = 'tip_path = {angle, x, y} (rad, m, m) of one nozzle tip per revolution'
    if not isinstance(value, dict) or not all(
            isinstance(value.get(k), list) for k in ('angle', 'x', 'y')):
        raise DesignMessageError(f'tip_path is not usable: allowed {allowed}')
    columns = [value[k] for k in ('angle', 'x', 'y')]
    if len({len(c) for c in columns}) != 1 or len(columns[0]) < 8 or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for c in columns for v in c):
        raise DesignMessageError(f'tip_path is not usable: allowed {allowed}, at least 8 '
                                 'finite samples of each, as many of each')
    return TipPath(*(tuple(float(v) for v in c) for c in columns))


def _shown(value: object) -> str:
    text = f'{value:.6g}' if isinstance(value, float) else repr(value)
    return text if len(text) <= 40 else text[:37] + '...'


def _short(exc: BaseException) -> str:
    return ' '.join(str(exc).split())[:120]


_ALLOWED = {'plant_spacing': 'plant_spacing (m)', 'planting_depth': 'planting_depth (m)',
            'l1': 'l1 and l2 (m)', 'l2': 'l1 and l2 (m)',
            'tip_path': 'tip_path = {angle, x, y} (rad, m, m) of one nozzle tip per revolution'}
