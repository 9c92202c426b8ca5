"""A scene resolved: read strictly (scene.schema), then what each node gets from it, the design
it makes, its rows and where its GNSS antenna sits.

`open_scene(path)` is the one way the command line, the demo and the bench read a scene;
`load_scene(path, node)` is the flat parameter dict one node gets from it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from planter_ros.config import ConfigError, as_dict, from_mapping
from planter_ros.design import Design, design_for_scene
from planter_ros.geo import AntennaSettings
from planter_ros.plausibility import PlausibilityError, check
from planter_ros.rows import Row, rows_from_scene
from planter_ros.shipped import shipped_file

from .files import ParameterFile, SceneError, read_parameter_file
from .schema import check_scene, merged_parameters, node_parameters, shared_entry

if TYPE_CHECKING:          # loaded when used (acceptance)
    from planter_ros.prediction import AcceptanceLimits

__all__ = ['Scene', 'default_scene_path', 'load_scene', 'open_scene', 'scene_limits']

DEFAULT_SCENE = 'tomato_five_bar.yaml'


@dataclass(frozen=True)
class Scene:
    """A checked scene file; `warnings`: its unusual but possible values
    (planter_ros.plausibility), for the caller to show."""

    file: ParameterFile
    warnings: tuple[str, ...] = ()

    @property
    def path(self) -> Path:
        return self.file.path

    def parameters(self, node: str | None = None) -> dict[str, Any]:
        """The flat parameters `node` (design_node, sync_node, monitor_node) gets, as rcl
        gives them to it (its own entries win over shared ones); None: the shared entries'."""
        if node is None:
            out: dict[str, Any] = {}
            for entry in self.file.entries:
                if shared_entry(entry.pattern):
                    out.update(entry.params)
            return out
        return merged_parameters(self.file, node)

    def node_overrides(self, node: str) -> list[tuple[str, Any]]:
        """(name, value) of every parameter of `node` the scene sets, each of the type the node
        declares: a node started in-process takes these as its parameter overrides."""
        return node_parameters(node, self.parameters(node))

    def design(self) -> Design:
        """The scene's design (planter_ros.design); DesignError (one line) if it has none."""
        return design_for_scene(self.parameters('design_node'))

    def rows(self, default_node_id: int | None = None) -> list[Row]:
        """The machine's rows (planter_ros.rows.Row) as the sync node reads them; ConfigError
        naming the file for a bad row."""
        try:
            return rows_from_scene(self.parameters('sync_node'), default_node_id)
        except ConfigError as exc:
            raise SceneError(f'scene {self.path}: {exc}') from None

    def acceptance(self) -> 'AcceptanceLimits':
        """The crop's acceptance limits (prediction.AcceptanceLimits) as the monitor reads
        them; the defaults for what the scene does not set."""
        # lazy: prediction/ is 9 modules the sync node, which reads scenes, never uses
        # (as schema.node_classes)
        from planter_ros.prediction import AcceptanceLimits
        try:
            return from_mapping(AcceptanceLimits, self.parameters('monitor_node'))
        except ConfigError as exc:
            raise SceneError(f'scene {self.path}: {exc}') from None

    def antenna(self) -> AntennaSettings:
        """The GNSS antenna on the machine (geo.AntennaSettings) as the monitor reads it."""
        try:
            return from_mapping(AntennaSettings, self.parameters('monitor_node'))
        except ConfigError as exc:
            raise SceneError(f'scene {self.path}: {exc}') from None


def open_scene(path: str | Path) -> Scene:
    """Read and check a scene file (SceneError, one line, for anything the nodes would not
    take: see scene.schema, or the machine could not run: planter_ros.plausibility)."""
    pfile = read_parameter_file(path)
    if not any(entry.params for entry in pfile.entries):
        raise SceneError(f'scene file {pfile.path} has no ros__parameters under /** or a '
                         'planter node')
    check_scene(pfile)
    try:
        warnings = check({**merged_parameters(pfile, 'design_node'),
                          **merged_parameters(pfile, 'sync_node')},
                         where=f'scene file {pfile.path}: ')
    except PlausibilityError as exc:
        raise SceneError(str(exc)) from None
    return Scene(pfile, tuple(warnings))


def scene_limits(path: str | Path) -> dict[str, Any]:
    """The crop's acceptance limits a scene file sets (the defaults for the rest), as a
    mapping (prediction.AcceptanceLimits' fields)."""
    return as_dict(open_scene(path).acceptance())


def load_scene(path: str | Path, node: str | None = None) -> dict[str, Any]:
    """The flat parameter dict `node` gets from a checked scene file (None: the shared
    entries', `/**`)."""
    return open_scene(path).parameters(node)


def default_scene_path(name: str = DEFAULT_SCENE) -> Path:
    """A shipped scene (config/<name>) of this clone or the installed package."""
    return shipped_file(name)
