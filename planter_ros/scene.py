"""Scenes: ROS 2 parameter files (config/*.yaml) read without ROS, for the CLI and the demo.

The same file works as `--ros-args --params-file FILE` on a ROS machine. Parameters are taken
from the `/**` wildcard entry merged with the entry of the node asked for (node entries win).
Nested blocks are flattened to dotted names as ROS does (`left: {lateral_offset: 0.75}` is the
parameter `left.lateral_offset`).
"""

from pathlib import Path


class SceneError(ValueError):
    """A scene file that cannot be used; the message is one line."""


def load_scene(path, node_name=None):
    """Return the flat parameter dict of a ROS 2 parameter file."""
    import yaml
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise SceneError(f'scene file {path} does not exist') from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise SceneError(f'scene file {path} is not readable YAML: '
                         f'{str(exc).splitlines()[0]}') from None
    if not isinstance(data, dict):
        raise SceneError(f'scene file {path} is not a ROS 2 parameter file (top level must map '
                         'node names to ros__parameters)')
    params = {}
    for key in ('/**', '**'):
        params.update(_params_of(data.get(key), path, key))
    if node_name:
        for key in (node_name, '/' + node_name.lstrip('/')):
            params.update(_params_of(data.get(key), path, key))
    if not params:
        raise SceneError(f'scene file {path} has no ros__parameters under /**'
                         + (f' or {node_name}' if node_name else ''))
    return params


def _params_of(entry, path, key):
    if entry is None:
        return {}
    if not isinstance(entry, dict) or not isinstance(entry.get('ros__parameters'), dict):
        raise SceneError(f'scene file {path}: entry {key} has no ros__parameters mapping')
    return _flatten(entry['ros__parameters'])


def _flatten(mapping, prefix=''):
    out = {}
    for key, value in mapping.items():
        if isinstance(value, dict):
            out.update(_flatten(value, f'{prefix}{key}.'))
        else:
            out[f'{prefix}{key}'] = value
    return out
