"""The sync node's `machine_file` parameter, declared once (scene.schema lists it among the
sync node's, scene.machine_file reads the file)."""

from dataclasses import dataclass

from planter_ros.config import setting

__all__ = ['MachineFileSetting']


@dataclass(frozen=True)
class MachineFileSetting:
    """The sync node's machine file (a parameter)."""

    machine_file: str = setting('', 'the machine file (doc/machine_file.md): its bus, rows, node '
                                'ids, lever arms, gear ratios and encoder counts are the '
                                'defaults of those parameters (one given explicitly wins, with '
                                'a warning when it differs); each drive is checked against it '
                                'and its polarity, homing and phase offset applied at every '
                                'start; empty: none', read_only=True)
