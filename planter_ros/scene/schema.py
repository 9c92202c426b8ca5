"""Which parameters a scene may set, and where: the one rule the command line, the demo and the
nodes apply to a parameter file.

One scene file serves the three planter nodes (design_node, sync_node and monitor_node, all in
the `/planter` namespace). Each node declares the fields of its configuration classes as ROS
parameters (nodes.parameters); `node_classes()` says which classes, so a scene knows every name a
node takes, with its unit and range (config.setting). ROS ignores a name no node declares;
here it is refused:

* an entry's node-name pattern follows rcl's matching (`*` one name token, `**` any number);
  an entry whose last token is a wildcard (`/**`, `/planter/*`) is *shared*: each of its keys
  must be a parameter of some planter node. An entry naming a node (`/planter/sync_node`,
  `/**/sync_node`) is that node's *own*: each key must be one that node declares. An entry
  that reaches no planter node (`sync_node` alone means `/sync_node`; `/other/*`) is refused;
* a row's block (`left: {lateral_offset: ...}`) only for a row named in `rows`, holding only
  row settings (rows.RowSettings); `rows` and the blocks are parameters of sync_node and
  monitor_node;
* three-arm settings only in a three-arm scene (design_node declares them only then);
* ROS's own parameters (use_sim_time, start_type_description_service) anywhere;
* every value is checked against its field's Spec: type, finite, unit and range, choices.

A refusal is a SceneError of one line naming the file, the key and the closest valid key
("did you mean `plant_spacing`?"). A node checks the files it was started with the same way
(`check_node_file`), with its own declared parameters for its own entries.
"""

from difflib import SequenceMatcher
from functools import cache
from typing import Any, Iterable, NoReturn

from planter_ros import interfaces
from planter_ros.config import ConfigError, Spec, coerce, specs
from planter_ros.kinematics.design_inputs import DesignInputs, ThreeArmInputs
from planter_ros.rows import RowLayout, RowSettings

from .files import ParameterFile, SceneError

__all__ = ['NODES', 'ROS_PARAMETERS', 'check_node_file', 'check_scene', 'closest', 'matches',
           'merged_parameters', 'node_classes', 'node_parameters', 'node_specs',
           'scene_mechanism', 'scene_rows', 'shared_entry']

NODES = ('design_node', 'sync_node', 'monitor_node')
NAMESPACE = '/' + interfaces.NAMESPACE.strip('/')

# parameters every rclpy node declares by itself
ROS_PARAMETERS = {
    'use_sim_time': Spec('use_sim_time', bool, False, 'ROS: take the time from /clock'),
    'start_type_description_service': Spec('start_type_description_service', bool, True,
                                           'ROS: offer the type description service'),
}


@cache
def node_classes() -> dict[str, tuple[type, ...]]:
    """node -> the configuration classes whose fields it declares as parameters (besides its
    rows). The design node's three-arm settings are declared only in a three-arm scene. Made
    on first use: the classes come from every layer below."""
    # lazy: a node that reads only its own parameters (sync_node) would otherwise load
    # prediction/, recording/, geo and sensing's plant map (14 modules) it never uses, the
    # monitor node the control laws and drive settings (8 modules, 10 ms measured)
    from planter_ros.control.loop_timing import SyncLoopConfig
    from planter_ros.control.machine_law import TurnConfig  # lazy: as above
    from planter_ros.control.phase_lock import PhaseLockConfig  # lazy: as above
    from planter_ros.drive.config import DriveConfig  # lazy: as above
    from planter_ros.geo import AntennaSettings  # lazy: as above
    from planter_ros.prediction import AcceptanceLimits, PredictionSettings  # lazy: as above
    from planter_ros.recording.recorder import RecorderConfig  # lazy: as above
    from planter_ros.scene.machine_setting import MachineFileSetting  # lazy: as above
    from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits  # lazy: as above
    from planter_ros.sensing.plant_map import MapSettings  # lazy: as above
    from planter_ros.sensing.row_speed import YawRateLimits  # lazy: as above
    return {
        'design_node': (DesignInputs, ThreeArmInputs),
        'sync_node': (DriveConfig, SyncLoopConfig, RowLayout, PhaseLockConfig,
                      GroundSpeedLimits, YawRateLimits, TurnConfig, MachineFileSetting),
        'monitor_node': (RecorderConfig, PredictionSettings, MapSettings, AntennaSettings,
                         AcceptanceLimits, RowLayout),
    }


def node_specs(node: str, mechanism: str | None = None,
               rows: Iterable[str] = ()) -> dict[str, Spec]:
    """Every parameter `node` declares, by name: its classes' fields, the settings of each row
    in `rows` (`<row>.<field>`, nodes with rows), ROS's own. `mechanism` None: any scene's."""
    out = dict(ROS_PARAMETERS)
    for cls in node_classes()[node]:
        if cls is ThreeArmInputs and mechanism not in (None, 'three_arm'):
            continue
        out.update({spec.name: spec for spec in specs(cls)})
    if RowLayout in node_classes()[node]:
        for row in rows:
            out.update({f'{row}.{spec.name}': spec for spec in specs(RowSettings)})
    return out


def node_parameters(node: str, params: dict[str, Any]) -> list[tuple[str, Any]]:
    """The (name, value) pairs of a flat scene dict that `node` declares, each value of its
    declared type (YAML writes 1 for 1.0): what a caller hands the node as overrides."""
    known = node_specs(node, scene_mechanism(params), scene_rows(params))
    out = []
    for name, value in params.items():
        spec = known.get(name)
        if spec is not None:
            out.append((name, coerce(spec, value)))
    return out


def scene_mechanism(params: dict[str, Any]) -> str:
    """The mechanism a flat scene dict names (the design settings' default without one)."""
    mechanism = params.get('mechanism')
    if isinstance(mechanism, str):
        return mechanism
    return str(next(s.default for s in specs(DesignInputs) if s.name == 'mechanism'))


def scene_rows(params: dict[str, Any]) -> list[str]:
    """The row names a flat scene dict gives in `rows` (none if it gives no list of names)."""
    rows = params.get('rows')
    if isinstance(rows, list) and all(isinstance(r, str) for r in rows):
        return list(rows)
    return []


def matches(pattern: str, fqn: str) -> bool:
    """Does rcl apply a parameter file entry `pattern` to the node named `fqn`
    (`/planter/sync_node`)? Tokens between slashes; `*` is one token, `**` any number; a
    pattern without a leading slash is taken from the root (`sync_node` is `/sync_node`)."""
    want = [t for t in pattern.strip('/').split('/') if t] or ['']
    have = [t for t in fqn.strip('/').split('/') if t]

    def match(i: int, j: int) -> bool:
        if i == len(want):
            return j == len(have)
        if want[i] == '**':
            return any(match(i + 1, k) for k in range(j, len(have) + 1))
        if j == len(have):
            return False
        return (want[i] == '*' or want[i] == have[j]) and match(i + 1, j + 1)
    return match(0, 0)


def shared_entry(pattern: str) -> bool:
    """Is an entry shared by several nodes (its node name a wildcard: `/**`, `/planter/*`)?"""
    return pattern.rstrip('/').rsplit('/', 1)[-1] in ('*', '**')


def _fqn(node: str) -> str:
    return f'{NAMESPACE}/{node}'


def closest(name: str, candidates: Iterable[str]) -> str:
    """The candidate most like `name` (difflib's ratio; ties: the first in order)."""
    best, score = '', -1.0
    for candidate in candidates:
        ratio = SequenceMatcher(None, name, candidate).ratio()
        if ratio > score:
            best, score = candidate, ratio
    return best


def merged_parameters(pfile: ParameterFile, node: str) -> dict[str, Any]:
    """What `node` gets from the file: shared entries, then its own (own entries win)."""
    out: dict[str, Any] = {}
    fqn = _fqn(node)
    for own in (False, True):
        for entry in pfile.entries:
            if shared_entry(entry.pattern) != own and matches(entry.pattern, fqn):
                out.update(entry.params)
    return out


def check_scene(pfile: ParameterFile) -> None:
    """A scene file's every entry and key against the rule of the module doc; SceneError."""
    mechanism = scene_mechanism(merged_parameters(pfile, 'design_node'))
    rows = sorted(set(scene_rows(merged_parameters(pfile, 'sync_node')))
                  | set(scene_rows(merged_parameters(pfile, 'monitor_node'))))
    for entry in pfile.entries:
        reached = [node for node in NODES if matches(entry.pattern, _fqn(node))]
        if not reached:
            _no_node(pfile, entry.pattern)
        if shared_entry(entry.pattern):
            _check_keys(pfile, entry.params, reached, mechanism, rows)
        else:
            _check_keys(pfile, entry.params, reached, mechanism, rows, own=True)


def check_node_file(pfile: ParameterFile, node: str, fqn: str,
                    declared: Iterable[str]) -> set[str]:
    """The entries of a parameter file a running node (named `fqn`) is given: shared ones as
    in a scene, its own ones against the parameters it `declared`. SceneError for a refused
    key; returns the names its shared entries set (other nodes' parameters among them)."""
    declared = set(declared)
    mechanism = None                 # a file that names none may hold either mechanism's
    for entry in pfile.entries:
        if isinstance(entry.params.get('mechanism'), str):
            mechanism = entry.params['mechanism']
    rows = set()
    for entry in pfile.entries:
        rows |= set(scene_rows(entry.params))
    rows |= {name.split('.', 1)[0] for name in declared if '.' in name}
    shared: set[str] = set()
    for entry in pfile.entries:
        if not matches(entry.pattern, fqn):
            continue
        if shared_entry(entry.pattern):
            _check_keys(pfile, entry.params, NODES, mechanism, sorted(rows))
            shared |= set(entry.params)
            continue
        for name in entry.params:
            if name not in declared:
                raise SceneError(f'{pfile.name}: {name} under {entry.pattern} is not a parameter '
                                 f'of {node}: did you mean `{closest(name, sorted(declared))}`?')
    return shared


def _no_node(pfile: ParameterFile, pattern: str) -> None:
    last = pattern.rstrip('/').rsplit('/', 1)[-1]
    if last in NODES:
        raise SceneError(f'{pfile.name}: entry {pattern} reaches no planter node (they run in '
                         f'{NAMESPACE}): did you mean `{NAMESPACE}/{last}`? (`/**/{last}` '
                         'reaches it too)')
    if last in ('*', '**'):
        raise SceneError(f'{pfile.name}: entry {pattern} reaches no planter node (they run in '
                         f'{NAMESPACE}): did you mean `/**`?')
    raise SceneError(f'{pfile.name}: entry {pattern} is not a planter node: did you mean '
                     f'`{NAMESPACE}/{closest(last, NODES)}`?')


def _check_keys(pfile: ParameterFile, params: dict[str, Any], nodes: Iterable[str],
                mechanism: str | None, rows: list[str], own: bool = False) -> None:
    """Every key of one entry names a parameter of one of `nodes` (`own`: the entry is that
    node's own) and every value is in its range."""
    nodes = list(nodes)
    allowed = {}
    for node in nodes:
        allowed.update(node_specs(node, mechanism, rows))
    for name, value in params.items():
        spec = allowed.get(name)
        if spec is None:
            _unknown(pfile, name, nodes, mechanism, rows, own)
        try:
            coerce(spec, value, text=False)
        except ConfigError as exc:
            text = str(exc)
            if name != spec.name and text.startswith(spec.name):   # a row's: name the row
                text = name + text[len(spec.name):]
            raise SceneError(f'{pfile.name}: {text}') from None


def _unknown(pfile: ParameterFile, name: str, nodes: list[str], mechanism: str | None,
             rows: list[str], own: bool) -> NoReturn:
    """Raise the one line for a key no node it reaches takes (the closest valid key)."""
    valid = []
    for node in nodes:
        valid += [n for n in node_specs(node, mechanism, rows) if n not in valid]
    owners = [node for node in NODES if name in node_specs(node, None, rows)]
    head = pfile.name
    if name in (spec.name for spec in specs(ThreeArmInputs)) and mechanism != 'three_arm':
        raise SceneError(f'{head}: {name} is a three-arm setting but the scene\'s mechanism is '
                         f'{mechanism}: allowed in a scene with mechanism three_arm')
    row = name.split('.', 1)[0]
    if '.' in name and row in valid:
        spec = next(node_specs(node, mechanism, rows)[row] for node in nodes
                    if row in node_specs(node, mechanism, rows))
        raise SceneError(f'{head}: {name}: {row} is a block: allowed a value, '
                         f'{spec.allowed()}')
    if '.' in name and row not in rows:
        if not rows:
            raise SceneError(f'{head}: {name}: {row} is a block but the scene names no rows: '
                             f'did you mean `rows: [{row}]`?')
        raise SceneError(f'{head}: {name}: {row} is a block but not a row named in rows: did '
                         f'you mean `{closest(name, valid)}`?')
    if own and owners:
        raise SceneError(f'{head}: {name} is not a parameter of {" or ".join(nodes)} (it is '
                         f'{", ".join(owners)}\'s): put it under /** or '
                         f'{NAMESPACE}/{owners[0]}')
    who = 'any planter node' if not own else ' or '.join(nodes)
    raise SceneError(f'{head}: {name} is not a parameter of {who}: did you mean '
                     f'`{closest(name, valid)}`?')
