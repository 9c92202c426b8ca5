"""CAN bus load of a machine's configuration, the physical limit of several drives on one bus.

Worst case, per second: every frame the configuration makes, times its length in bits with
the worst-case bit stuffing, over the bit rate. A CAN 2.0A data frame with n data bytes has
47 + 8n bits (SOF, 11-bit id, RTR, IDE, r0, DLC, data, CRC 15 + delimiter, ACK 2, EOF 7,
intermission 3); the 34 + 8n bits from SOF to the CRC are stuffed, at worst one stuff bit
after every four bits after the first: floor((34 + 8n − 1) / 4) more (R. I. Davis, A. Burns,
R. J. Bril, J. J. Lukkien: "Controller Area Network (CAN) schedulability analysis: refuted,
revisited and revised", Real-Time Systems 35(3):239–272, 2007).

The frames of `planter_ros.drive.cia402` per enabled row (sizes from drive.objects), in
profile velocity: the RPDO (controlword + target velocity, 6 bytes) once per control period and
once per ground-speed sample; TPDO1 (statusword + error code, 4 bytes) and TPDO2 (position +
velocity, 8 bytes) every feedback period. In cyclic synchronous position (`csp`): per SYNC
period one SYNC (0 bytes) for the bus, and per row the RPDO (controlword + target position,
6 bytes) and both TPDOs. Either way the drive's heartbeat (1 byte) and the master's one.
`BusTiming` holds what sets those rates: the periods of the drive settings and the loop's.
Pure, no ROS, no bus.
"""
from __future__ import annotations

from dataclasses import dataclass

from . import objects as od
from .config import DriveConfig
from .errors import DriveConfigError

__all__ = ['LIMIT', 'RPDO_BYTES', 'TPDO_BYTES', 'HEARTBEAT_BYTES', 'SYNC_BYTES', 'frame_bits',
           'BusLoad', 'BusTiming', 'bus_load', 'check_bus_load']

LIMIT = 0.70                 # refused above this share of the bit rate

RPDO_BYTES = od.RPDO_VELOCITY.size                      # controlword + target velocity
TPDO_BYTES = tuple(layout.size for layout in od.TPDOS)  # status; motion
HEARTBEAT_BYTES = 1
SYNC_BYTES = 0


def frame_bits(data_bytes: int) -> int:
    """Worst-case length (bits) of a CAN 2.0A data frame with `data_bytes` bytes (0..8)."""
    if not 0 <= data_bytes <= 8:
        raise ValueError(f'data_bytes = {data_bytes} is out of range: allowed 0..8')
    n = 8 * data_bytes
    return 47 + n + (34 + n - 1) // 4


@dataclass(frozen=True)
class BusTiming:
    """What sets the frame rates of a configuration (s; `ground_speed_rate` in Hz): the loop's
    control period and ground-speed samples, the drive's feedback and heartbeat periods, the
    master's heartbeat period and, for drives in CSP, the SYNC period."""

    control_period: float
    ground_speed_rate: float
    feedback_period: float
    drive_heartbeat_period: float
    heartbeat_period: float
    sync_period: float = 0.0

    @classmethod
    def of(cls, drive: DriveConfig, control_period: float,
           ground_speed_rate: float) -> BusTiming:
        """The timing of drives set by `drive` under a loop of `control_period` and
        `ground_speed_rate`."""
        return cls(control_period, ground_speed_rate, drive.feedback_period,
                   drive.drive_heartbeat_period, drive.heartbeat_period, drive.sync_period)


@dataclass(frozen=True)
class BusLoad:
    """The worst-case load of one configuration."""

    rows: int                 # drives on the bus (enabled rows)
    bitrate: int              # bit/s
    frames_per_second: float
    bits_per_second: float
    items: tuple[tuple[str, float, float], ...]   # (what, frames/s, bits/s) per kind of frame
    sync_period: float = 0.0  # s, the SYNC period of drives in CSP (0: profile velocity)

    @property
    def csp(self) -> bool:
        return self.sync_period > 0

    @property
    def wire_per_period(self) -> float:
        """CSP: bus time (s) of one SYNC period's frames, worst case."""
        return self.bits_per_second * self.sync_period / self.bitrate if self.csp else 0.0

    @property
    def load(self) -> float:
        """Share of the bit rate, 0..1 (can exceed 1: the bus cannot carry it)."""
        return self.bits_per_second / self.bitrate

    def values(self) -> list[tuple[str, str | int]]:
        """Key/value pairs for diagnostics and people."""
        out: list[tuple[str, str | int]] = [('bus load', f'{100 * self.load:.1f} %'),
               ('bus load limit', f'{100 * LIMIT:.0f} %'),
               ('drives on the bus', self.rows), ('bit rate', f'{self.bitrate} bit/s'),
               ('frames per second', f'{self.frames_per_second:.0f}')]
        out += [(f'{what}', f'{frames:.0f} frames/s, {bits:.0f} bit/s')
                for what, frames, bits in self.items]
        return out


def bus_load(rows: int, bitrate: int, timing: BusTiming, csp: bool = False) -> BusLoad:
    """Worst-case load of `rows` drives (bit rate in bit/s); `csp`: the drives run cyclic
    synchronous position on a SYNC every `timing.sync_period`."""
    sync_period = timing.sync_period
    if csp and not sync_period > 0:
        raise ValueError('bus_load: csp needs sync_period > 0 s')
    items: list[tuple[str, float, float]] = []

    def add(what: str, frames: float, data_bytes: int) -> None:

        items.append((what, frames, frames * frame_bits(data_bytes)))

    if csp:
        add('SYNC', 1.0 / sync_period, SYNC_BYTES)
        add('RPDO (position target)', rows / sync_period, od.RPDO_POSITION.size)
        for number, size in enumerate(TPDO_BYTES, 1):
            add(f'TPDO{number} (feedback)', rows / sync_period, size)
    else:
        add('RPDO (command)', rows * (1.0 / timing.control_period + timing.ground_speed_rate),
            RPDO_BYTES)
        for number, size in enumerate(TPDO_BYTES, 1):
            add(f'TPDO{number} (feedback)', rows / timing.feedback_period, size)
    add('drive heartbeats', rows / timing.drive_heartbeat_period, HEARTBEAT_BYTES)
    add('master heartbeat', 1.0 / timing.heartbeat_period, HEARTBEAT_BYTES)
    return BusLoad(rows, int(bitrate), sum(i[1] for i in items), sum(i[2] for i in items),
                   tuple(items), sync_period if csp else 0.0)


def check_bus_load(load: BusLoad, row_names: list[str], timing: BusTiming) -> None:
    """Raise DriveConfigError (one line naming rows, periods, bit rate and the knobs that fix
    it: the bit rate, the period, the rows per bus) above LIMIT."""
    t = timing
    if load.load <= LIMIT:
        return
    per_row = load.bits_per_second / max(load.rows, 1)
    fits = int(LIMIT * load.bitrate // per_row) if per_row else 0
    names = ', '.join(row_names) if row_names else f'{load.rows} row(s)'
    if load.csp:
        raise DriveConfigError(
            f'CAN bus load {100 * load.load:.1f} % is out of range: allowed <= '
            f'{100 * LIMIT:.0f} % ({names} at {load.bitrate} bit/s in cyclic synchronous '
            f'position: a SYNC and per row an RPDO and 2 TPDOs every sync_period = '
            f'{load.sync_period * 1e3:g} ms, {load.wire_per_period * 1e3:.2f} ms of wire per '
            f'period; a heartbeat per drive every {t.drive_heartbeat_period * 1e3:g} ms: at most '
            f'{fits} rows fit on this bus; lengthen sync_period, raise can_bitrate, or put the '
            'other rows on a second bus)')
    raise DriveConfigError(
        f'CAN bus load {100 * load.load:.1f} % is out of range: allowed <= {100 * LIMIT:.0f} % '
        f'({names} at {load.bitrate} bit/s; per row an RPDO every control_period = '
        f'{t.control_period * 1e3:g} ms and per ground-speed sample at '
        f'{t.ground_speed_rate:g} Hz, 2 TPDOs every feedback_period = '
        f'{t.feedback_period * 1e3:g} ms, a heartbeat every {t.drive_heartbeat_period * 1e3:g} '
        f'ms; master heartbeat {t.heartbeat_period * 1e3:g} ms: '
        f'at most {fits} rows fit, or lengthen the periods, or raise can_bitrate)')
