"""What one demo run is asked to do, checked before anything starts."""

from dataclasses import dataclass
from pathlib import Path

from planter_ros.config import ConfigError, check, setting
from planter_ros.output_files import check_directory, check_new_path

__all__ = ['DEFAULT_SCENE', 'DemoOptions', 'check_bag_path']

DEFAULT_SCENE = 'tomato_five_bar.yaml'      # in config/, the scene of a run without --scene


@dataclass(frozen=True)
class DemoOptions:
    """The demo's own settings (the command line's options). Fields without a `setting` are
    free-form: a path, a switch, or None for "the default"."""

    scene: str | None = None        # scene file; None: config/tomato_five_bar.yaml
    duration: float = setting(30.0, 'length of the field run', unit='s', range=(8.0, 3600.0))
    bag: str | None = None          # bag to record; None: bags/planter_<date-time>
    phase_lock: bool = True         # False: feed-forward speed only, for comparison
    turn_compensation: bool = True  # False: every row on the machine's speed, for comparison
    seed: int = setting(0, "sensor noise and tray seed", range=(0, 2 ** 32 - 1))
    empty_rate: float = setting(0.0, "share of the simulated tray's cells that are empty (each "
                                "row's cup sensor reads 0)", range=(0.0, 1.0))
    double_rate: float = setting(0.0, "share of the simulated tray's cells holding two "
                                 'seedlings (the cup sensor reads 2)', range=(0.0, 1.0))
    origin_latitude: float | None = None    # deg WGS 84; None: the simulated receiver's default
    origin_longitude: float | None = None   # deg WGS 84; None: the simulated receiver's default
    machine: str | None = None      # machine file (demo.commissioned); None: the scene rows

    def __post_init__(self) -> None:
        check(self)
        if self.empty_rate + self.double_rate > 1.0:
            raise ConfigError(f'empty_rate + double_rate = {self.empty_rate:g} + '
                              f'{self.double_rate:g}: allowed at most 1 together')


def check_bag_path(bag: str | None) -> None:
    """Refuse (OutputError) a --bag the recorder could not create, before anything starts:
    an existing path, an extension other than .mcap (a file) or none (a bag directory), a
    missing or read-only directory; without --bag, the default bags/ directory (or the current
    directory it would be made in) must be writable."""
    if bag is not None:
        check_new_path(bag, '--bag', ('.mcap', ''))
        return
    bags = Path('bags')
    default = bags / 'planter_<date-time>'
    check_directory(bags if bags.exists() else Path('.'), '--bag (default)', default)
