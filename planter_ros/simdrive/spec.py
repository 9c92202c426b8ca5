"""What a simulated drive is built as: its motor, its mechanism, its device (modes, identity,
dictionary) and its injected slowness, one frozen dataclass checked once (the parts of the
drive each take their share). JSON-ready (`data()` / `SimSpec(**data)`): the drives' own process
gets it over its command line."""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

from planter_ros.drive.states import PROFILE_VELOCITY

from .switch import HomeSwitch

__all__ = ['SimSpec']


@dataclass(frozen=True)
class SimSpec:
    """A simulated drive (SI; counts on the bus)."""

    # motor and its speed loop
    time_constant: float = 0.05          # s, first-order lag of the speed loop
    max_acceleration: float = 2000.0     # motor rad/s²
    counts_per_motor_rev: int = 4096     # encoder increments per motor turn (608Fh)
    coast_time_constant: float = 0.5     # s, speed decay with the power stage off
    # device
    supported_modes: tuple[int, ...] | None = (PROFILE_VELOCITY,)   # None: the EDS's 6502h
    # 1018h:1..4 (None: the EDS's own)
    identity: tuple[int, int, int, int] | None = (0x0000_0000, 0x0000_0402, 1, 0)
    eds_path: str | None = None          # the object dictionary (None: planter_drive.eds)
    # mechanism behind the gear
    gear_ratio: float = 1.0              # motor turns per mechanism turn
    motor_reversed: bool = False         # a positive motor turn turns the mechanism back
    mechanical_offset: float = 0.0       # rad, the mechanism's bottom from the encoder's zero
    home_switch_width: float = 0.2       # rad of mechanism turn the bottom switch is active
    # a real switch (simdrive.switch; 0: ideal): on hysteresis/2 inside its nominal edge, off
    # hysteresis/2 outside it; the input shows a change delay + uniform [0, jitter) s later
    home_switch_hysteresis: float = 0.0  # rad, 0 <= hysteresis < home_switch_width
    home_switch_delay: float = 0.0       # s
    home_switch_jitter: float = 0.0      # s, drawn per change from `seed`
    record_bottom: bool = False          # keep the instants the mechanism passes its bottom
    # a slow drive: SDO answers late (one at a time, in order), from a seeded random stream
    sdo_delay: tuple[float, float] | None = None
    sdo_slow_share: float = 1.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ('time_constant', 'max_acceleration', 'counts_per_motor_rev',
                     'coast_time_constant', 'gear_ratio'):
            if not getattr(self, name) > 0:
                raise ValueError(f'{name} = {getattr(self, name)!r} is out of range: allowed '
                                 '> 0')
        HomeSwitch(self.home_switch_width, self.home_switch_hysteresis,
                   self.home_switch_delay, self.home_switch_jitter)       # checks its values
        if self.sdo_delay is not None and not 0.0 <= self.sdo_delay[0] <= self.sdo_delay[1]:
            raise ValueError(f'sdo_delay = {self.sdo_delay!r}: allowed (shortest, longest) '
                             '>= 0 s')
        # lists from JSON to tuples (frozen, hashable)
        for name in ('supported_modes', 'identity', 'sdo_delay'):
            value = getattr(self, name)
            if value is not None and not isinstance(value, tuple):
                object.__setattr__(self, name, tuple(value))
        if self.eds_path is not None:
            object.__setattr__(self, 'eds_path', str(Path(self.eds_path)))

    def with_options(self, **options: Any) -> 'SimSpec':
        """This spec with `options` (field names) changed; ValueError naming an unknown one."""
        known = {f.name for f in fields(self)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise ValueError(f'simulated drive option {unknown[0]!r} is unknown: allowed '
                             + ', '.join(sorted(known)))
        return replace(self, **options) if options else self

    def data(self) -> dict[str, Any]:
        return asdict(self)
