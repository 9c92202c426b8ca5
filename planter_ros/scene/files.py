"""Scene files: ROS 2 parameter files (config/*.yaml) read without ROS, for the command line, the
demo and the nodes' own check of the files they are given.

The same file works as `--ros-args --params-file FILE` on a ROS machine. A file maps node-name
patterns (`/**`, `/planter/sync_node`, `/**/monitor_node`, ...) to `ros__parameters`; nested
blocks are flattened to dotted names as ROS does (`left: {lateral_offset: 0.75}` is the
parameter `left.lateral_offset`). Which names an entry may hold is the schema's rule
(scene.schema).

A scene is small: files over MAX_SCENE_BYTES are refused unread, and YAML aliases may expand to
at most MAX_ALIAS_NODES nodes (no recursive alias), so a hostile file (an "alias bomb") costs
neither memory nor a giant error message (planter_ros.safe_yaml).
"""

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from planter_ros.config import ConfigError
from planter_ros.safe_yaml import MAX_ALIAS_NODES, YamlError, load_yaml

__all__ = ['MAX_ALIAS_NODES', 'MAX_SCENE_BYTES', 'Entry', 'ParameterFile', 'SceneError',
           'read_parameter_file', 'read_small_yaml']

MAX_SCENE_BYTES = 1 << 20          # 1 MiB; the shipped scenes are about 1 kB


class SceneError(ConfigError):
    """A scene or parameter file that cannot be used; the message is one line naming the file
    and what is wrong (the command line exits 2 with it, a node refuses to start)."""


@dataclass(frozen=True)
class Entry:
    """One node-name pattern of a parameter file and its parameters (dotted names)."""

    pattern: str
    params: dict[str, Any]


@dataclass(frozen=True)
class ParameterFile:
    """A parameter file as written: its entries in file order."""

    path: Path
    entries: tuple[Entry, ...]

    @property
    def name(self) -> str:
        """How messages name the file."""
        return f'scene file {self.path}'


def read_small_yaml(path: Path, what: str, error: type[Exception]) -> str:
    """The text of the YAML file at `path` (`what` names it in messages: 'scene file'), read
    only when it is a regular file of at most MAX_SCENE_BYTES; `error` (one line) if it is
    missing, not a regular file, too big or unreadable."""
    try:
        if path.exists() and not path.is_file():
            raise error(f'{what} {path} is not a regular file: allowed a YAML file')
        size = path.stat().st_size
        if size > MAX_SCENE_BYTES:
            raise error(f'{what} {path} is {size} bytes: allowed at most {MAX_SCENE_BYTES} '
                        'bytes')
        return path.read_text()
    except FileNotFoundError:
        raise error(f'{what} {path} does not exist') from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f'{what} {path} is not readable YAML: {str(exc).splitlines()[0]}') from None


def read_parameter_file(path: str | Path) -> ParameterFile:
    """Read a ROS 2 parameter file (bounded size and aliases, every entry a ros__parameters
    mapping); SceneError (one line) if it is not one. Names are not checked here."""
    path = Path(path)
    text = read_small_yaml(path, 'scene file', SceneError)
    try:
        data = load_yaml(text, f'scene file {path}')
    except YamlError as exc:
        raise SceneError(str(exc)) from None
    if not isinstance(data, dict):
        raise SceneError(f'scene file {path} is not a ROS 2 parameter file (top level must map '
                         'node names to ros__parameters)')
    entries = []
    for pattern, entry in data.items():
        if not isinstance(entry, dict) or not isinstance(entry.get('ros__parameters'), dict):
            raise SceneError(f'scene file {path}: entry {pattern} has no ros__parameters mapping')
        extra = [str(k) for k in entry if k != 'ros__parameters']
        if extra:
            raise SceneError(f'scene file {path}: entry {pattern} has {extra[0]} beside '
                             'ros__parameters: allowed ros__parameters only')
        entries.append(Entry(str(pattern), _flatten(entry['ros__parameters'])))
    return ParameterFile(path, tuple(entries))


def _flatten(mapping: dict, prefix: str = '') -> dict[str, Any]:
    out = {}
    for key, value in mapping.items():
        if isinstance(value, dict) and value:
            out.update(_flatten(value, f'{prefix}{key}.'))
        else:
            out[f'{prefix}{key}'] = value
    return out
