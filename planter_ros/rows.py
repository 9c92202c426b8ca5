"""The machine's planting units (rows), declared once: names, lateral offsets, drives.

A scene names its rows in the string array `rows` and gives each row a block of `RowSettings`
(in a ROS 2 parameter file a nested block `<row>: {lateral_offset: ..., drive_node_id: ...}`,
which ROS and `planter_ros.scene.load_scene` flatten to the parameters `<row>.lateral_offset`,
...). All rows share the scene's one design (crop, mechanism, spacing).

A scene without `rows` has one implicit row: name '' (its joint keeps the mechanism's plain name
`sun_bar` / `carrier`, its services have no prefix, so single-row scenes, tests and recordings
stay as they were), lateral offset 0, driven by the drive config's `drive_node_id`.

Lateral offsets follow REP 103: y is + to the left of the machine's reference point, and a
positive yaw rate turns the machine counter-clockwise (left), so a row at y travels at
v − ω_z·y. Pure Python, no ROS.
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import json
import re

from planter_ros import interfaces
from planter_ros.config import ConfigError, check, from_mapping, name_list, setting

IMPLICIT = ''                      # the name of the one row of a scene without `rows`
_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]*\Z')


@dataclass(frozen=True)
class RowLayout:
    """Which rows the machine has (fixed at start-up)."""

    rows: list[str] = name_list([], 'names of the planting units (rows); each has a block of '
                                'row settings <row>.lateral_offset, <row>.drive_node_id, '
                                '<row>.enabled, <row>.seedling_sensor; empty = one implicit '
                                'row', read_only=True)
    seedling_sensor: bool = setting(True, 'the rows carry a seedling sensor (an optical cup or '
                                    'drop-tube sensor counting the seedlings of each cycle, '
                                    'topic seedlings): a scene without rows, its one row; with '
                                    'rows, every row whose block does not set its own '
                                    '<row>.seedling_sensor. false: every planting instant '
                                    'is unknown (no seedling sensor), whatever is read',
                                    read_only=True)

    def __post_init__(self) -> None:
        check(self)
        seen: set[str] = set()
        for name in self.rows:
            if not _NAME.match(name):
                raise ConfigError(f'rows = {name!r} is not a row name: allowed letters, digits '
                                  'and _, starting with a letter')
            if name in seen:
                raise ConfigError(f'rows = {name!r} is named twice: allowed each name once')
            seen.add(name)


@dataclass(frozen=True)
class RowSettings:
    """One row: where it sits on the machine and which drive turns it (fixed at start-up)."""

    lateral_offset: float = setting(kind=float, description="the row's lateral offset from the "
                                    "machine's reference point, + = left (REP 103)", unit='m',
                                    range=(-20.0, 20.0), read_only=True)
    drive_node_id: int = setting(kind=int, description="CANopen node id of the row's servo "
                                 'drive', range=(1, 127), read_only=True)
    enabled: bool = setting(True, 'false: the row is never enabled on the bus and plants '
                            'nothing (a unit taken off the machine)', read_only=True)
    longitudinal_offset: float = setting(0.0, "the row's planting point ahead of the machine's "
                                         'reference point (behind: negative; a machine file '
                                         'sets it from the GNSS antenna)', unit='m',
                                         range=(-50.0, 50.0), read_only=True)
    seedling_sensor: bool = setting(True, 'the row carries a seedling sensor (topic seedlings, '
                                    'its joint\'s count each cycle); false: its planting '
                                    'instants are unknown (no seedling sensor). Default: the '
                                    "scene's seedling_sensor", read_only=True)

    def __post_init__(self) -> None:
        check(self)


@dataclass(frozen=True)
class Row:
    """One planting unit of the machine. `index` is its place in the scene's `rows` (the
    `row` field of every plant); `name` is '' for the implicit row."""

    index: int
    name: str
    lateral_offset: float
    drive_node_id: int | None
    enabled: bool = True
    longitudinal_offset: float = 0.0     # m, + ahead of the reference point
    # the row carries a seedling sensor; None: not declared (a bag recorded before the
    # setting: the sensor is inferred from its readings, prediction.seedlings)
    seedling_sensor: bool | None = True

    @property
    def label(self) -> str:
        """The row's name for people ('row' for the implicit row)."""
        return self.name or 'row'

    def joint(self, mechanism: str) -> str:
        """The row's mechanism joint in joint_states (`<row>/sun_bar`, or `sun_bar`)."""
        return interfaces.row_joint(self.name, mechanism)

    def as_dict(self) -> dict[str, object]:
        return {'index': self.index, 'name': self.name, 'lateral_offset': self.lateral_offset,
                'drive_node_id': self.drive_node_id, 'enabled': self.enabled,
                'longitudinal_offset': self.longitudinal_offset,
                'seedling_sensor': self.seedling_sensor}


def implicit_row(drive_node_id: int | None = None, seedling_sensor: bool | None = True) -> Row:
    return Row(0, IMPLICIT, 0.0, drive_node_id, True, seedling_sensor=seedling_sensor)


def rows_from_settings(names: Sequence[str], settings: Mapping[str, RowSettings],
                       default_node_id: int | None = None,
                       seedling_sensor: bool | None = True) -> list[Row]:
    """Rows from the row names and each name's RowSettings; one implicit row without names
    (`seedling_sensor`: its sensor, RowLayout.seedling_sensor). Raises ConfigError when two
    rows name the same drive."""
    if not names:
        return [implicit_row(default_node_id, seedling_sensor)]
    rows = [Row(i, name, settings[name].lateral_offset, settings[name].drive_node_id,
                settings[name].enabled, settings[name].longitudinal_offset,
                settings[name].seedling_sensor)
            for i, name in enumerate(names)]
    owner: dict[int | None, str] = {}
    for row in rows:
        if row.drive_node_id in owner:
            raise ConfigError(f'{row.name}.drive_node_id = {row.drive_node_id} is also row '
                              f'{owner[row.drive_node_id]}\'s: allowed a node id no other row '
                              'uses')
        owner[row.drive_node_id] = row.name
    return rows


def rows_from_scene(params: Mapping[str, object], default_node_id: int | None = None
                    ) -> list[Row]:
    """Rows of a flat scene parameter dict (`planter_ros.scene.load_scene`), as the nodes read
    them from their parameters. Raises ConfigError (one line)."""
    layout = from_mapping(RowLayout, {k: params[k] for k in ('rows', 'seedling_sensor')
                                      if k in params})
    settings: dict[str, RowSettings] = {}
    for name in layout.rows:
        prefix = f'{name}.'
        values = {k[len(prefix):]: v for k, v in params.items() if k.startswith(prefix)}
        values.setdefault('seedling_sensor', layout.seedling_sensor)
        settings[name] = from_mapping(RowSettings, values, prefix=prefix)
    return rows_from_settings(layout.rows, settings, default_node_id, layout.seedling_sensor)


def scene_row_parameters(params: Mapping[str, object]) -> dict[str, object]:
    """The row parameters of a flat scene dict (`rows` and every `<row>.<field>`)."""
    names = params.get('rows') or []
    if not isinstance(names, (list, tuple)):
        names = []
    return {k: v for k, v in params.items()
            if k in ('rows', 'seedling_sensor') or any(k.startswith(f'{n}.') for n in names)}


def rows_record(rows: Sequence[Row]) -> dict[str, str]:
    """The bag metadata record (`interfaces.ROWS_RECORD`) naming each row index."""
    return {'rows': json.dumps([row.as_dict() for row in rows])}


def rows_from_record(record: Mapping[str, str]) -> list[Row] | None:
    """Rows from a bag's rows record; None when the record is absent or unreadable."""
    try:
        items = json.loads(record['rows'])
        return [Row(int(r['index']), str(r['name']), float(r['lateral_offset']),
                    None if r.get('drive_node_id') is None else int(r['drive_node_id']),
                    bool(r.get('enabled', True)), float(r.get('longitudinal_offset', 0.0)),
                    None if r.get('seedling_sensor') is None else bool(r['seedling_sensor']))
                for r in items]
    except (KeyError, TypeError, ValueError):
        return None
