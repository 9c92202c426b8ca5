"""Scenes: ROS 2 parameter files (config/*.yaml) read without ROS, for the CLI and the demo.

The same file works as `--ros-args --params-file FILE` on a ROS machine. Parameters are taken
from the `/**` wildcard entry merged with the entry of the node asked for (node entries win).

A scene is small: files over MAX_SCENE_BYTES are refused unread, and YAML aliases may expand to
at most MAX_ALIAS_NODES nodes (no recursive alias), so a hostile file (an "alias bomb") costs
neither memory nor a giant error message. Nested blocks are flattened to dotted names as ROS
does (`left: {lateral_offset: 0.75}` is the parameter `left.lateral_offset`).
"""

from pathlib import Path

MAX_SCENE_BYTES = 1 << 20          # 1 MiB; the shipped scenes are about 1 kB
MAX_ALIAS_NODES = 10_000           # nodes all alias uses of a document may expand to


class SceneError(ValueError):
    """A scene file that cannot be used; the message is one line."""


def load_yaml(text, what):
    """safe_load with alias expansion bounded (SceneError naming `what` if it is not)."""
    import yaml
    try:
        return yaml.load(text, Loader=_bounded_loader())
    except _AliasError as exc:
        raise SceneError(f'{what}: {exc}') from None
    except RecursionError:
        raise SceneError(f'{what} is nested too deeply: allowed YAML nested a few hundred '
                         'levels at most') from None
    except yaml.YAMLError as exc:
        raise SceneError(f'{what} is not readable YAML: '
                         f'{" ".join(str(exc).split())[:200]}') from None


def load_scene(path, node_name=None):
    """Return the flat parameter dict of a ROS 2 parameter file."""
    path = Path(path)
    try:
        if path.exists() and not path.is_file():
            raise SceneError(f'scene file {path} is not a regular file: allowed a YAML file')
        size = path.stat().st_size
        if size > MAX_SCENE_BYTES:
            raise SceneError(f'scene file {path} is {size} bytes: allowed at most '
                             f'{MAX_SCENE_BYTES} bytes')
        text = path.read_text()
    except FileNotFoundError:
        raise SceneError(f'scene file {path} does not exist') from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f'scene file {path} is not readable YAML: '
                         f'{str(exc).splitlines()[0]}') from None
    data = load_yaml(text, f'scene file {path}')
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
    params = entry['ros__parameters']
    # a scene's only blocks are its rows' settings: any other block is a misplaced value
    rows = params.get('rows')
    rows = set(rows) if isinstance(rows, list) and all(isinstance(r, str) for r in rows) else set()
    for name, value in params.items():
        if isinstance(value, dict) and name not in rows:
            raise SceneError(f'scene file {path}: {name} is a block: allowed a value (blocks '
                             'only for the rows named in rows)')
    return _flatten(params)


class _AliasError(ValueError):
    pass


_LOADER = None


def _bounded_loader():
    """yaml.SafeLoader counting the nodes every alias use expands to (made once, on first use:
    PyYAML is imported only when a scene is read)."""
    global _LOADER
    if _LOADER is not None:
        return _LOADER
    import yaml

    class BoundedLoader(yaml.SafeLoader):
        def compose_document(self):
            self._open_anchors, self._sizes, self._expanded = set(), {}, 0
            return super().compose_document()

        def compose_node(self, parent, index):
            event = self.peek_event()
            anchor = event.anchor
            if isinstance(event, yaml.AliasEvent):
                if anchor in self._open_anchors:
                    raise _AliasError(f'alias *{anchor} refers to its own anchor: allowed '
                                      'aliases of finished nodes only')
                if anchor in self.anchors:
                    self._expanded += self._size(self.anchors[anchor])
                    if self._expanded > MAX_ALIAS_NODES:
                        raise _AliasError(f'aliases expand to over {MAX_ALIAS_NODES} nodes: '
                                          f'allowed at most {MAX_ALIAS_NODES}')
                return super().compose_node(parent, index)
            if anchor is None:
                return super().compose_node(parent, index)
            self._open_anchors.add(anchor)
            try:
                return super().compose_node(parent, index)
            finally:
                self._open_anchors.discard(anchor)

        def _size(self, node):
            """Nodes `node` stands for once every alias inside it is expanded (memoised)."""
            known = self._sizes.get(id(node))
            if known is not None:
                return known
            if isinstance(node, yaml.SequenceNode):
                size = 1 + sum(self._size(child) for child in node.value)
            elif isinstance(node, yaml.MappingNode):
                size = 1 + sum(self._size(k) + self._size(v) for k, v in node.value)
            else:
                size = 1
            self._sizes[id(node)] = size
            return size

    _LOADER = BoundedLoader
    return _LOADER


def _flatten(mapping, prefix=''):
    out = {}
    for key, value in mapping.items():
        if isinstance(value, dict):
            out.update(_flatten(value, f'{prefix}{key}.'))
        else:
            out[f'{prefix}{key}'] = value
    return out
