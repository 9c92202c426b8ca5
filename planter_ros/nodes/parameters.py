"""Config dataclasses as ROS parameters: the one bridge from `planter_ros.config` specs to rclpy.

`ParameterGroup(node, classes, build, on_change, prefix)` declares every field of the classes as
a parameter with a descriptor (description with unit and range, floating point or integer range,
read-only flag), builds the initial value, and follows updates the way the rclpy examples do:

* on-set callback: builds the candidate from the current values plus the update and refuses
  the update with the one-line reason if that fails. It only checks; the node keeps its state.
* post-set callback: the update is in; build (reusing the checked candidate) and hand the new
  value to `on_change`.

A `prefix` declares the fields as `<prefix><field>`: one row's settings are the parameters
`<row>.lateral_offset`, ... (a parameter file's nested block `<row>: {lateral_offset: ...}`),
and `declare_rows` reads a scene's rows that way.

`refuse_undeclared(node, arguments)` refuses what rclpy would silently ignore: a parameter the
node was given (in a parameter file or as an override) that it does not declare.
"""

from collections.abc import Sequence

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter

from planter_ros import config
from planter_ros.rows import RowLayout, RowSettings, rows_from_settings
from planter_ros.scene.files import SceneError, read_parameter_file
from planter_ros.scene.schema import check_node_file, closest

_TYPES = {float: Parameter.Type.DOUBLE, int: Parameter.Type.INTEGER, bool: Parameter.Type.BOOL,
          str: Parameter.Type.STRING, list: Parameter.Type.DOUBLE_ARRAY}


def _type(spec):
    if spec.kind is list and spec.item is str:
        return Parameter.Type.STRING_ARRAY
    return _TYPES[spec.kind]


def descriptor(spec):
    """ParameterDescriptor of a config Spec (ROS enforces the range and read-only itself)."""
    d = ParameterDescriptor(description=spec.describe(), read_only=spec.read_only)
    if spec.kind is float and spec.low is not None and spec.high is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(spec.low),
                                                     to_value=float(spec.high), step=0.0)]
    elif spec.kind is int and spec.low is not None and spec.high is not None:
        d.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high),
                                        step=1)]
    return d


def declare(node, spec, prefix=''):
    """Declare one spec's parameter (named `prefix` + field name); returns its value (None if
    not given and required, or with an empty list as default: ROS cannot type an empty list)."""
    name = prefix + spec.name
    default = _type(spec) if spec.required or spec.default == [] else spec.default
    node.declare_parameter(name, default, descriptor(spec))
    try:
        return _plain(node.get_parameter(name).value)
    except ParameterUninitializedException:
        return None


def _plain(value):
    return list(value) if not isinstance(value, (str, bytes)) and hasattr(value, '__len__') \
        else value


class ParameterGroup:
    """The parameters of one or more config dataclasses on a node (see the module doc)."""

    def __init__(self, node, classes, build=None, on_change=None, prefix=''):
        self.node = node
        self.classes = tuple(classes) if isinstance(classes, (tuple, list)) else (classes,)
        self.prefix = prefix
        self.names = []                    # parameter names (with the prefix)
        for cls in self.classes:
            for spec in config.specs(cls):
                if not node.has_parameter(prefix + spec.name):   # shared with a group before
                    declare(node, spec, prefix)
                self.names.append(prefix + spec.name)
        self._build = build or self._build_dataclass
        self._on_change = on_change
        self._checked = None               # (values key, built value) of the last check
        self.value = self._build(self.values())
        node.add_on_set_parameters_callback(self._check)
        node.add_post_set_parameters_callback(self._apply)

    def values(self, update=None):
        """The group's values by field name (uninitialised ones left out), with `update`
        (by field name) applied."""
        out = {}
        for name in self.names:
            try:
                out[name[len(self.prefix):]] = _plain(self.node.get_parameter(name).value)
            except ParameterUninitializedException:
                continue
        out.update(update or {})
        return out

    def _build_dataclass(self, values):
        built = tuple(config.from_mapping(cls, values, prefix=self.prefix)
                      for cls in self.classes)
        return built[0] if len(built) == 1 else built

    @staticmethod
    def _key(values):
        return tuple(sorted((k, repr(v)) for k, v in values.items()))

    def _check(self, parameters):
        update = {p.name[len(self.prefix):]: _plain(p.value) for p in parameters
                  if p.name in self.names}
        if not update:
            return SetParametersResult(successful=True)
        values = self.values(update)
        try:
            built = self._build(values)
        except config.ConfigError as exc:
            self.node.get_logger().warning(f'parameter update refused: {exc}')
            return SetParametersResult(successful=False, reason=str(exc))
        self._checked = (self._key(values), built)
        return SetParametersResult(successful=True)

    def _apply(self, parameters):
        if not any(p.name in self.names for p in parameters):
            return
        values = self.values()
        key = self._key(values)
        checked, self._checked = self._checked, None
        self.value = checked[1] if checked and checked[0] == key else self._build(values)
        if self._on_change is not None:
            self._on_change(self.value)


def declare_rows(node, default_node_id=None):
    """The scene's rows from `node`'s parameters: `rows` (names) and each row's `<row>.<field>`
    (planter_ros.rows.RowSettings); one implicit row when the scene names none. Raises
    ConfigError (one line) for a bad name, a missing or out-of-range field, a node id twice."""
    layout = ParameterGroup(node, RowLayout).value
    sensor = next(spec for spec in config.specs(RowSettings) if spec.name == 'seedling_sensor')
    for name in layout.rows:      # a row's sensor defaults to the scene's seedling_sensor
        if not node.has_parameter(f'{name}.seedling_sensor'):
            node.declare_parameter(f'{name}.seedling_sensor', layout.seedling_sensor,
                                   descriptor(sensor))
    settings = {name: ParameterGroup(node, RowSettings, prefix=f'{name}.').value
                for name in layout.rows}
    return rows_from_settings(layout.rows, settings, default_node_id, layout.seedling_sensor)


def params_files(arguments: Sequence[str] | None) -> list[str]:
    """The `--params-file` paths among a process's arguments (every `--ros-args` section)."""
    files, ros, args = [], False, list(arguments or ())
    for i, arg in enumerate(args):
        if arg == '--ros-args':
            ros = True
        elif arg == '--' and ros:
            ros = False
        elif ros and arg == '--params-file' and i + 1 < len(args):
            files.append(args[i + 1])
    return files


def refuse_undeclared(node: Node, arguments: Sequence[str] | None = None) -> None:
    """Refuse (scene.SceneError, one line) a parameter `node` was given but does not declare,
    which rclpy would ignore: a key of a parameter file that is not what the scene's rule allows
    (planter_ros.scene.schema: keys under the node's own entry must be its parameters, keys
    under a shared entry such as `/**` a parameter of some planter node), or an override (`-p`,
    an in-process node's `parameter_overrides`) it does not declare. Call it once every
    parameter is declared; `arguments`: the process's arguments (the files are read from
    them)."""
    declared = set(node._parameters)
    shared = set()
    for path in params_files(arguments):
        shared |= check_node_file(read_parameter_file(path), node.get_name(),
                                  node.get_fully_qualified_name(), declared)
    for name in node._parameter_overrides:        # rclpy keeps what it was given here
        if name not in declared and name not in shared:
            raise SceneError(f'parameter {name} given to {node.get_name()} is not one it '
                             f'declares: did you mean `{closest(name, sorted(declared))}`?')
