"""Write a scene dict as a ROS 2 parameter file (the format scene.files reads)."""

from pathlib import Path
from typing import Any, Mapping

import yaml

__all__ = ['write_scene']


def write_scene(path: str | Path, params: Mapping[str, Any], comment: str = '') -> None:
    """Write `params` under `/**: ros__parameters:`; floats keep full precision."""
    data = {'/**': {'ros__parameters': {k: _plain(v) for k, v in params.items()}}}
    text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)
    head = ''.join(f'# {line}\n' for line in comment.splitlines()) if comment else ''
    Path(path).write_text(head + text)


def _plain(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if hasattr(value, 'item'):          # numpy scalars
        return value.item()
    return value
