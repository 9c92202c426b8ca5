"""YAML read safely: `yaml.safe_load` with alias expansion bounded, so a hostile file (an "alias
bomb") costs neither memory nor a giant error message, and a key given twice in one mapping
refused (PyYAML would keep the last silently). A plain number with an exponent (`1e9`,
`1.0e5`, `-2E3`) is a number, as ROS reads a parameter file (PyYAML's YAML 1.1 rules make it
text), so a quoted `"0.3"` is the only text that looks like a number. Used for scene files
and a bag's metadata (imported by those that read one: PyYAML with it)."""

from __future__ import annotations

from collections.abc import Hashable
import re
from typing import Any

import yaml

from planter_ros.errors import PlanterError

__all__ = ['MAX_ALIAS_NODES', 'YamlError', 'load_yaml']

MAX_ALIAS_NODES = 10_000           # nodes all alias uses of a document may expand to


class YamlError(PlanterError, ValueError):
    """A text that is not usable YAML; the message is one line naming `what` was read."""


def load_yaml(text: str, what: str) -> Any:
    """safe_load with alias expansion bounded (YamlError naming `what` if it is not)."""
    try:
        return yaml.load(text, Loader=_bounded_loader())
    except _Refused as exc:
        raise YamlError(f'{what}: {exc}') from None
    except RecursionError:
        raise YamlError(f'{what} is nested too deeply: allowed YAML nested a few hundred '
                        'levels at most') from None
    except yaml.YAMLError as exc:
        raise YamlError(f'{what} is not readable YAML: '
                        f'{" ".join(str(exc).split())[:200]}') from None


class _Refused(ValueError):
    pass


_LOADER: type[yaml.SafeLoader] | None = None


def _bounded_loader() -> type[yaml.SafeLoader]:
    """yaml.SafeLoader counting the nodes every alias use expands to (made once, on first use)."""
    global _LOADER
    if _LOADER is not None:
        return _LOADER

    class BoundedLoader(yaml.SafeLoader):
        _open_anchors: set[str]
        _sizes: dict[int, int]
        _expanded: int

        def compose_document(self) -> yaml.Node | None:
            self._open_anchors, self._sizes, self._expanded = set(), {}, 0
            return super().compose_document()

        def compose_node(self, parent: yaml.Node | None, index: int) -> yaml.Node | None:
            event = self.peek_event()
            anchor = event.anchor
            if isinstance(event, yaml.AliasEvent):
                if anchor in self._open_anchors:
                    raise _Refused(f'alias *{anchor} refers to its own anchor: allowed '
                                      'aliases of finished nodes only')
                if anchor in self.anchors:
                    self._expanded += self._size(self.anchors[anchor])
                    if self._expanded > MAX_ALIAS_NODES:
                        raise _Refused(f'aliases expand to over {MAX_ALIAS_NODES} nodes: '
                                          f'allowed at most {MAX_ALIAS_NODES}')
                return super().compose_node(parent, index)
            if anchor is None:
                return super().compose_node(parent, index)
            self._open_anchors.add(anchor)
            try:
                return super().compose_node(parent, index)
            finally:
                self._open_anchors.discard(anchor)

        def construct_mapping(self, node: yaml.MappingNode,
                              deep: bool = False) -> dict[Hashable, Any]:
            seen: set[str] = set()
            for key, _ in node.value:
                if isinstance(key, yaml.ScalarNode) and key.tag != 'tag:yaml.org,2002:merge':
                    if key.value in seen:
                        raise _Refused(f'{key.value} is given twice in one mapping (line '
                                       f'{key.start_mark.line + 1}): allowed each key once')
                    seen.add(key.value)
            return super().construct_mapping(node, deep=deep)


        def _size(self, node: yaml.Node) -> int:
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

    # numbers with an exponent and no dot or no exponent sign (YAML 1.2, strtod as rcl reads)
    BoundedLoader.add_implicit_resolver(
        'tag:yaml.org,2002:float',
        re.compile(r'^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$'),
        list('-+0123456789.'))
    _LOADER = BoundedLoader
    return _LOADER
