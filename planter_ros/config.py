"""Configuration fields declared once: default, unit, range, description, read-only.

Every configuration dataclass of planter_ros (the drive, the sync law, the ground-speed limits,
the monitor's prediction and recording settings, the scene) declares each field with
`setting(...)`. From that one declaration

* `check(instance)` validates the values (type, finite, range, choices) with one-line
  messages naming the value and a non-empty allowed range;
* `planter_ros.nodes.parameters` declares the fields as ROS parameters with descriptors;
* `coerce(cls, name, value)` turns a scene file's or a recording's value into the field's type
  (an integer 1 for a float field, the string '0.02' of a recorded setting).

Ranges are inclusive and in the field's SI unit. Pure Python: no ROS import.
"""

from collections.abc import Callable, Mapping
from dataclasses import MISSING, dataclass, field, fields, replace
import math
from typing import TYPE_CHECKING, Any, NoReturn, TypeVar, overload

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

from planter_ros.errors import PlanterError

_T = TypeVar('_T')
_D = TypeVar('_D', bound='DataclassInstance')
# what a caller raises for a bad value (ConfigError, DesignError.from_message, ...)
ErrorFactory = Callable[[str], Exception]

# list = a list of the Spec's `item`: float (a ROS double array) or str (a ROS string array)
KINDS = (float, int, bool, str, list)


class ConfigError(PlanterError, ValueError):
    """A configuration value outside its allowed domain; the message is one line."""


def one_line(text: str) -> str:
    """`text` as one printable line: a newline or an undecodable byte from the user's own
    arguments (surrogate escapes) is shown escaped, never printed raw."""
    return ''.join(c if c.isprintable() else repr(c)[1:-1] for c in text)


@dataclass(frozen=True)
class Spec:
    """What one configuration field means and allows."""

    name: str
    kind: type
    default: object            # MISSING: the value must be given (no default)
    description: str
    unit: str = ''
    low: float | None = None
    high: float | None = None
    choices: tuple[object, ...] = ()
    read_only: bool = False
    item: type = float         # element type of a list field: float or str

    @property
    def required(self) -> bool:
        return self.default is MISSING

    def allowed(self) -> str:
        """The allowed values in words, never empty ('0.01..5 s', 'exact | paper', ...)."""
        unit = f' {self.unit}' if self.unit else ''
        if self.choices:
            words = [str(c) for c in self.choices]
            return words[0] if len(words) == 1 else ', '.join(words[:-1]) + ' or ' + words[-1]
        if self.kind is bool:
            return 'true or false'
        if self.kind is list and self.item is str:
            return 'list of names'
        what = {int: 'integer', float: 'number', str: 'text', list: 'list of numbers'}[self.kind]
        if self.low is not None and self.high is not None:
            return f'{what} {_fmt(self.low)}..{_fmt(self.high)}{unit}'
        if self.low is not None:
            return f'{what} >= {_fmt(self.low)}{unit}'
        if self.high is not None:
            return f'{what} <= {_fmt(self.high)}{unit}'
        return f'finite {what}{unit}' if self.kind in (int, float, list) else what

    def describe(self) -> str:
        """Description for people and ROS descriptors: the text, the unit and the range."""
        return f'{self.description} [{self.allowed()}]'


_Range = tuple[float | None, float | None] | None


@overload
def setting(default: _T, description: str = '', *, unit: str = '', range: _Range = None,
            read_only: bool = False, kind: type | None = None) -> _T: ...


@overload
def setting(*, description: str = '', unit: str = '', range: _Range = None,
            read_only: bool = False, kind: type[_T]) -> _T: ...


def setting(default: object = MISSING, description: str = '', *, unit: str = '',
            range: _Range = None, read_only: bool = False, kind: type | None = None) -> Any:
    """A dataclass field carrying its Spec (the one place a configuration value is defined).

    `range=(low, high)` is inclusive; either end may be None. `kind` defaults to the type of
    `default` (a list default means a list of numbers). A text taking one of a few values is a
    `choice`, a list of names a `name_list`.
    """
    if kind is None:
        if default is MISSING:
            raise TypeError('setting() without a default needs kind=')
        kind = type(default)
    low, high = range if range is not None else (None, None)
    return _field(default, Spec('', kind, default, description, unit=unit, low=low, high=high,
                                read_only=read_only))


def choice(default: str, description: str, choices: tuple[str, ...], *,
           read_only: bool = False) -> str:
    """A text setting taking one of `choices` (a dataclass field carrying its Spec)."""
    return _field(default, Spec('', str, default, description, choices=tuple(choices),
                                read_only=read_only))


def name_list(default: list[str], description: str, *,
              read_only: bool = False) -> list[str]:
    """A list of names (a ROS string array; a dataclass field carrying its Spec)."""
    return _field(default, Spec('', list, default, description, read_only=read_only, item=str))


def _field(default: object, declared: Spec) -> Any:
    """The dataclass field of a setting: its default (a list: a fresh copy per instance) and
    its Spec as the field's metadata, named and given its default by `specs` (the field's name
    is known only there)."""
    if declared.kind not in KINDS:
        raise TypeError(f'setting kind {declared.kind!r} is not one of {KINDS}')
    meta = {'spec': declared}
    if isinstance(default, list):
        return field(default_factory=lambda: list(default), metadata=meta)
    if default is MISSING:
        return field(metadata=meta)
    return field(default=default, metadata=meta)


def specs(cls: 'DataclassInstance | type[DataclassInstance]') -> list[Spec]:
    """The Spec of every configured field of a dataclass (class or instance), in order."""
    out: list[Spec] = []
    for f in fields(cls):
        meta = f.metadata.get('spec')
        if meta is None:
            continue
        default = f.default
        if f.default_factory is not MISSING:
            default = f.default_factory()
        out.append(replace(meta, name=f.name, default=default))
    return out


def spec_of(cls: 'DataclassInstance | type[DataclassInstance]', name: str) -> Spec:
    for spec in specs(cls):
        if spec.name == name:
            return spec
    raise KeyError(name)


def names(cls: 'DataclassInstance | type[DataclassInstance]') -> list[str]:
    return [spec.name for spec in specs(cls)]


def coerce(spec: Spec, value: object, text: bool = True) -> Any:
    """`value` from a file, a recording or a parameter as the field's type, or ConfigError
    (text is parsed: a recording stores its settings as strings; `text` False: a file a
    person writes, where `"0.3"` for a number is a mistake to name, not to read)."""
    if isinstance(value, str) and spec.kind in (int, float, bool) and not text:
        raise ConfigError(f'{spec.name} = {value!r} is text: allowed {spec.allowed()} '
                          '(without quotes)')
    if isinstance(value, str) and spec.kind in (int, float):
        try:
            value = spec.kind(value)
        except ValueError:
            pass
    elif isinstance(value, str) and spec.kind is bool and value in ('True', 'False'):
        value = value == 'True'            # a recording's repr() of the value
    return _normalise(spec, value)


def _normalise(spec: Spec, value: Any) -> Any:
    """int -> float where a float belongs (YAML writes 1 for 1.0), then the checks."""
    if spec.kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if spec.kind is list and spec.item is float and isinstance(value, (list, tuple)):
        value = [float(v) if isinstance(v, int) and not isinstance(v, bool) else v
                 for v in value]
    elif spec.kind is list and isinstance(value, tuple):
        value = list(value)
    _check_value(spec, value)
    return value


def _check_value(spec: Spec, value: Any) -> None:
    def bad(shown: object = None) -> NoReturn:
        shown = value if shown is None else shown
        text = f'{shown:.6g}' if isinstance(shown, float) else f'{shown!r}' \
            if isinstance(shown, str) else f'{shown}'
        if len(text) > 60:          # a value from a file can be huge: the message stays short
            text = text[:57] + '...'
        raise ConfigError(f'{spec.name} = {text} is out of range: allowed {spec.allowed()}')

    kind = spec.kind
    if kind is bool:
        if not isinstance(value, bool):
            bad()
        return
    if kind is str:
        if not isinstance(value, str):
            bad()
        if spec.choices and value not in spec.choices:
            bad()
        return
    if kind is list:
        if not isinstance(value, (list, tuple)) or not all(
                isinstance(v, spec.item) for v in value):
            bad()
        if spec.item is float:
            for v in value:
                _check_number(spec, v, bad)
        return
    if kind is int and (isinstance(value, bool) or not isinstance(value, int)):
        bad()
    if kind is float and not isinstance(value, float):
        bad()
    _check_number(spec, value, bad)
    if spec.choices and value not in spec.choices:
        bad()


def _check_number(spec: Spec, value: Any, bad: Callable[[object], NoReturn]) -> None:
    if isinstance(value, float) and not math.isfinite(value):   # (a huge int overflows isfinite)
        bad(value)
    if spec.low is not None and value < spec.low:
        bad(value)
    if spec.high is not None and value > spec.high:
        bad(value)


def check(instance: 'DataclassInstance', error: ErrorFactory = ConfigError) -> None:
    """Validate every configured field of a dataclass instance; raise `error` (one line).

    Call it from `__post_init__`; a float field given an int stores the float."""
    for spec in specs(instance):
        value = getattr(instance, spec.name)
        if value is None and spec.required:
            raise error(f'{spec.name} is required: allowed {spec.allowed()}')
        try:
            value = _normalise(spec, value)
        except ConfigError as exc:
            raise error(str(exc)) from None
        object.__setattr__(instance, spec.name, value)


def from_mapping(cls: type[_D], values: Mapping[str, object], error: ErrorFactory = ConfigError,
                 strict: bool = False, prefix: str = '') -> _D:
    """Build `cls` from a mapping, coercing each known value; unknown keys are ignored unless
    `strict` (then the first one is an error, and so is text for a number: a file a person
    wrote). `prefix` is put before each field name in the messages (a row's fields are the
    parameters `<row>.<field>`)."""
    known = {spec.name: spec for spec in specs(cls)}
    for required in known.values():
        if required.required and values.get(required.name) is None:
            raise error(f'{prefix}{required.name} is required: allowed {required.allowed()}')
    kwargs: dict[str, object] = {}
    for key, value in values.items():
        spec = known.get(key)
        if spec is None:
            if strict:
                raise error(f'{key} is not a setting of {cls.__name__}: allowed '
                            f'{" | ".join(known)}')
            continue
        try:
            kwargs[key] = coerce(spec, value, text=not strict)
        except ConfigError as exc:
            raise error(prefix + str(exc)) from None
    return cls(**kwargs)


def as_dict(instance: 'DataclassInstance') -> dict[str, Any]:
    return {spec.name: getattr(instance, spec.name) for spec in specs(instance)}


def _fmt(x: float) -> str:
    if float(x).is_integer() and abs(x) < 1e15:
        return str(int(x))
    return f'{x:.6g}'
