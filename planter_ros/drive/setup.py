"""What a machine file says of one drive, checked and applied every time the master configures
it: the drive's identity (0x1018), the modes the row needs (0x6502), its EDS (the start-up plan,
drive.plan, is made from it), the polarity (0x607E), homing (mode 6) and where the mechanism's
tip is lowest (the phase offset).

`DriveSetup` is plain data (the command process gets it as JSON); the checks here are pure (the
master reads the drive, these compare); `Cia402Drive` runs them in its configure path. The
homing speeds are the commissioning's and the start's: one place. Pure: no bus.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace
import math
from typing import Any
from collections.abc import Callable

from . import objects as od

__all__ = ['DriveSetup', 'HOMING_ALLOWED', 'HOMING_BIT', 'HOMING_METHODS', 'HOMING_SEARCH_SPEED',
           'HOMING_ZERO_SPEED', 'MODE_BITS', 'homing_method_ok', 'homing_timeout',
           'identity_mismatch', 'missing_modes', 'mode_bits', 'pdo_mismatch']

MODE_BITS = {'csp': 0x80, 'pv': 0x04}             # 0x6502 bit 7 CSP, bit 2 profile velocity
HOMING_BIT = 0x20                                 # 0x6502 bit 5: homing mode
HOMING_SEARCH_SPEED = 1.0    # rad/s at the mechanism: homing's search for the switch
HOMING_ZERO_SPEED = 0.05     # rad/s: homing's search for zero (the edge, the index pulse)
IDENTITY = (('vendor_id', od.VENDOR_ID), ('product_code', od.PRODUCT_CODE),
            ('revision', od.REVISION_NUMBER))
NOT_CHECKED = -1             # an identity value the machine file does not state
# CiA 402 homing methods (6098h): 1..14, 17..30, 33..35, 37 (15, 16, 31, 32, 36 and 38 up are
# reserved); 0: no homing; negative: the drive maker's own
HOMING_METHODS = frozenset([*range(1, 15), *range(17, 31), 33, 34, 35, 37])
HOMING_ALLOWED = ('0 (none), 1..14, 17..30, 33, 34, 35, 37 (CiA 402) or negative (the drive '
                  "maker's)")


def homing_method_ok(method: int) -> bool:
    """`method` is no homing, a CiA 402 method or a maker's (negative)."""
    return method <= 0 or method in HOMING_METHODS


def homing_timeout() -> float:
    """s: one and a half mechanism turns at the search speed, and the slow part."""
    return 1.5 * 2.0 * math.pi / HOMING_SEARCH_SPEED + 30.0


@dataclass(frozen=True)
class DriveSetup:
    """One row's drive as its machine file states it (SI; -1: an identity value not checked;
    None: the drive config's own gear ratio / encoder counts; phase_offset None: no machine
    file, the angle is the drive's count as it is)."""

    modes: tuple[str, ...] = ()          # 'csp', 'pv': the modes it must offer (0x6502)
    polarity: str = 'normal'             # 'reversed': 0x607E bits 7 and 6 set
    homing_method: int = 0               # 0x6098; 0: no homing at start
    phase_offset: float | None = None    # rad: the angle after homing with the tip lowest
    vendor_id: int = NOT_CHECKED         # 0x1018:1
    product_code: int = NOT_CHECKED      # 0x1018:2
    revision: int = NOT_CHECKED          # 0x1018:3
    eds: str = ''                        # the drive's EDS/DCF ('' : planter_drive.eds)
    gear_ratio: float | None = None      # motor turns per mechanism turn
    encoder_counts: int | None = None    # counts per motor turn

    def device(self, config: Any) -> Any:
        """`config` (a DriveConfig) with this drive's gear ratio, encoder counts and EDS."""
        changes: dict[str, Any] = {}
        if self.gear_ratio is not None:
            changes['motor_gear_ratio'] = float(self.gear_ratio)
        if self.encoder_counts is not None:
            changes['counts_per_motor_rev'] = int(self.encoder_counts)
        if self.eds:
            changes['eds_path'] = self.eds
        return replace(config, **changes) if changes else config

    def data(self) -> dict[str, Any]:
        return {**asdict(self), 'modes': list(self.modes)}

    @classmethod
    def from_data(cls, data: dict[str, Any]) -> 'DriveSetup':
        return cls(**{**data, 'modes': tuple(data.get('modes', ()))})


def mode_bits(setup: DriveSetup) -> int:
    """The 0x6502 bits of the modes (and homing) `setup` lists."""
    bits = sum(MODE_BITS[m] for m in set(setup.modes))
    return bits | (HOMING_BIT if setup.homing_method else 0)


def missing_modes(supported: int | None, setup: DriveSetup) -> list[str]:
    """The modes (and homing) `setup` needs that 0x6502 = `supported` lacks (None: not said:
    everything is missing)."""
    modes = supported or 0
    missing = [m for m in setup.modes if not modes & MODE_BITS[m]]
    if setup.homing_method and not modes & HOMING_BIT:
        missing.append('homing')
    return missing


def identity_mismatch(setup: DriveSetup, identity: dict[str, int | None]) -> str:
    """'' when the drive's 0x1018 (`identity`, as Cia402Drive.read_identity) is what `setup`
    states, else which object differs: expected and found."""
    for name, obj in IDENTITY:
        want = getattr(setup, name)
        if want == NOT_CHECKED:
            continue
        found = identity.get(name)
        if found != want:
            shown = 'nothing (no such object)' if found is None else f'0x{found:08X}'
            return (f'0x{obj.index:04X}:{obj.subindex} {obj.name}: expected 0x{want:08X}, found '
                    f'{shown}')
    return ''


def pdo_mismatch(layout: od.PdoLayout, node_id: int, read: Callable[[int, int], int]) -> str:
    """'' when the drive's PDO `layout` reads back as written, else the first entry that
    differs. `read(index, subindex)` reads one object by SDO."""
    base = 0x1400 if layout.kind == 'RPDO' else 0x1800
    comm, mapping = base + layout.number - 1, base + 0x200 + layout.number - 1
    cob_id = read(comm, 1)
    want_cob = layout.cob_id(node_id)
    if cob_id & 0x7FF != want_cob or cob_id & 0x8000_0000:
        return (f'{comm:04X}h:1 {layout.kind}{layout.number} COB-ID: expected 0x{want_cob:X} '
                f'(valid), found 0x{cob_id:08X}')
    count = read(mapping, 0)
    if count != len(layout.entries):
        return (f'{mapping:04X}h:0 {layout.kind}{layout.number} mapped objects: expected '
                f'{len(layout.entries)}, found {count}')
    for sub, obj in enumerate(layout.entries, start=1):
        want = (obj.index << 16) | (obj.subindex << 8) | obj.bits
        found = read(mapping, sub)
        if found != want:
            return (f'{mapping:04X}h:{sub} {layout.kind}{layout.number} mapping: expected '
                    f'0x{want:08X} ({obj.address} {obj.name}), found 0x{found:08X}')
    return ''
