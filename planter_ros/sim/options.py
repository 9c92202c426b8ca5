"""`planter simulate`'s options: read by its command line (`--help` included) without the
simulator (sim.season), which loads the monitor's pipeline, the recorder and the ROS messages."""

from dataclasses import dataclass

from planter_ros.config import check, setting

__all__ = ['SeasonOptions']


@dataclass(frozen=True)
class SeasonOptions:
    """A simulated season (`planter simulate`'s options)."""

    bags: int = setting(1, 'runs (bags) to simulate', range=(1, 100_000))
    duration: float = setting(60.0, 'length of each run', unit='s', range=(10.0, 3600.0))
    rows: int = setting(4, 'planting rows of the machine (1: a machine without rows)',
                        range=(1, 16))
    seed: int = setting(0, 'seed of the season: the same seed gives the same bags',
                        range=(0, 2 ** 32 - 1))
    empty_rate: float = setting(0.02, "share of the tray's cells that are empty (the seedling "
                                'sensor reads 0)', range=(0.0, 1.0))
    double_rate: float = setting(0.01, "share of the tray's cells holding two seedlings (the "
                                 'sensor reads 2)', range=(0.0, 1.0))

    def __post_init__(self) -> None:
        check(self)
