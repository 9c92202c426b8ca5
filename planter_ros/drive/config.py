"""The drive's settings, declared once; the field names are the sync node's ROS parameters.

Two groups: `BusConfig`, the cable and the master on it (interface, channel, bit rate, our node
id and heartbeat period), and `DeviceConfig`, one drive on that cable (its node id, units,
watchdogs, timeouts). `DriveConfig` is both at once: the sync node declares its fields as
parameters (the names did not change when the groups were split), and `.bus` / `.device` hand
out each part.

All of them are fixed while the drive runs (read-only parameters): they configure the bus, the
PDO mapping and the drive's own watchdogs at enable time. Periods and timeouts go to the drive
as 16-bit milliseconds, hence the ranges.
"""

from dataclasses import dataclass, fields

from planter_ros.config import check, choice, setting

from .errors import DriveConfigError

__all__ = ['BusConfig', 'DeviceConfig', 'DriveConfig', 'interpolation_period']

INTERPOLATION_INDICES = (-3, -4, -5, -6, -2)   # ms first: the unit drives know best


def interpolation_period(period: float, index: int | None = None) -> tuple[int, int] | None:
    """(60C2h:1 value, 60C2h:2 index) with value × 10^index s exactly the SYNC period as 1006h
    states it (whole µs), value 1..255; `index`: the drive's fixed index. None: none exists."""
    micro = round(period * 1e6)
    if micro <= 0 or abs(period * 1e6 - micro) > 1e-6 * max(1.0, micro):
        return None
    for i in ((index,) if index is not None else INTERPOLATION_INDICES):
        if i + 6 >= 0:
            scale = 10 ** (i + 6)
            if micro % scale == 0 and 1 <= micro // scale <= 255:
                return micro // scale, i
        elif micro * 10 ** -(i + 6) <= 255:
            return micro * 10 ** -(i + 6), i
    return None


def _bad(name: str, value: object, allowed: str) -> DriveConfigError:
    return DriveConfigError(f'{name} = {value!r} is out of range: allowed {allowed}')


@dataclass(frozen=True)
class BusConfig:
    """The CAN bus and the master on it (SI units)."""

    can_interface: str = setting('socketcan', "python-can interface: 'socketcan' on a machine "
                                 "(as the launch file); the demo and the tests pass 'virtual'",
                                 read_only=True)
    can_channel: str = setting('can0', 'CAN channel (SocketCAN network interface, or the name '
                               'of a virtual bus)', read_only=True)
    can_bitrate: int = setting(500_000, 'CAN bit rate', unit='bit/s', range=(10_000, 1_000_000),
                               read_only=True)
    master_node_id: int = setting(127, 'our CANopen node id (heartbeat COB-ID 0x700 + id)',
                                  range=(1, 127), read_only=True)
    heartbeat_period: float = setting(0.05, 'our CANopen heartbeat period, sent from the '
                                      'control loop (0.05 s: the drive trips only after 6 '
                                      'in a row are lost)', unit='s', range=(0.01, 1.0),
                                      read_only=True)
    sync_period: float = setting(0.01, 'SYNC period the command process produces for drives '
                                 'in cyclic synchronous position (0x1006, 0x60C2): one '
                                 'position target per row per period', unit='s',
                                 range=(0.002, 0.1), read_only=True)

    def __post_init__(self) -> None:
        check(self, DriveConfigError)
        for name in ('can_interface', 'can_channel'):
            if not getattr(self, name):
                raise _bad(name, getattr(self, name), 'a non-empty name')
        if interpolation_period(self.sync_period) is None:
            raise _bad('sync_period', self.sync_period, 'a period that 1006h (whole µs) and '
                       '60C2h (1..255 × 10^index s) both state exactly, e.g. 0.0025, 0.01 or '
                       '0.0125 s')


@dataclass(frozen=True)
class DeviceConfig:
    """One CiA 402 drive on the bus (SI units)."""

    drive_node_id: int = setting(1, 'CANopen node id of the servo drive', range=(1, 127),
                                 read_only=True)
    motor_gear_ratio: float = setting(1.0, 'motor revolutions per mechanism revolution',
                                      range=(0.01, 1000.0), read_only=True)
    counts_per_motor_rev: int = setting(4096, 'encoder counts per motor revolution (0x6064 '
                                        'units)', range=(1, 1 << 24), read_only=True)
    drive_heartbeat_timeout: float = setting(0.35, 'drive heartbeat older than this = drive '
                                             'lost: command 0, report ERROR, wait for '
                                             'reset_fault', unit='s', range=(0.05, 5.0),
                                             read_only=True)
    master_heartbeat_timeout: float = setting(0.3, "the drive's timeout for our heartbeat "
                                              '(0x1016): it stops the motor if this process '
                                              'dies or hangs', unit='s', range=(0.02, 5.0),
                                              read_only=True)
    command_timeout: float = setting(0.2, 'drive-side command watchdog (RPDO deadline): the '
                                     'drive quick-stops if our frames stop', unit='s',
                                     range=(0.02, 5.0), read_only=True)
    step_timeout: float = setting(0.5, 'timeout of each enable/disable state-machine step',
                                  unit='s', range=(0.05, 10.0), read_only=True)
    sdo_timeout: float = setting(1.0, 'time an SDO answer may take (a drive busy with its '
                                 'configuration answers in up to ~0.8 s); asked twice, then '
                                 'the start fails naming the node and the object', unit='s',
                                 range=(0.05, 10.0), read_only=True)
    drive_heartbeat_period: float = setting(0.05, "the drive's heartbeat producer period "
                                            '(0x1017; 0.05 s: lost after 7 in a row)', unit='s',
                                            range=(0.01, 1.0), read_only=True)
    feedback_period: float = setting(0.01, 'TPDO event timer of the drive feedback (statusword '
                                     'and motion)', unit='s', range=(0.001, 1.0), read_only=True)
    reset_timeout: float = setting(1.0, 'a fault reset not finished by then is abandoned',
                                   unit='s', range=(0.1, 10.0), read_only=True)
    eds_path: str = setting('', "the drive's EDS file; empty = config/planter_drive.eds",
                            read_only=True)
    operation_mode: str = choice('auto', "'csp': cyclic synchronous position (mode 8, "
                                 "position targets on SYNC); 'velocity': profile velocity "
                                 "(mode 3); 'auto': csp when the drive's 0x6502 offers it, "
                                 'else velocity', ('auto', 'csp', 'velocity'), read_only=True)
    following_error_window: float = setting(0.2, 'CSP: following error the drive tolerates '
                                            '(0x6065), mechanism angle', unit='rad',
                                            range=(0.001, 10.0), read_only=True)
    following_error_timeout: float = setting(0.05, 'CSP: a following error beyond the window '
                                             'for this long faults the drive (0x6066)',
                                             unit='s', range=(0.0, 1.0), read_only=True)

    def __post_init__(self) -> None:
        check(self, DriveConfigError)
        if self.drive_heartbeat_timeout <= self.drive_heartbeat_period:
            raise _bad('drive_heartbeat_timeout', self.drive_heartbeat_timeout,
                       f'> drive_heartbeat_period={self.drive_heartbeat_period} s')


@dataclass(frozen=True)
class DriveConfig(BusConfig, DeviceConfig):
    """A drive on a bus: every field of `BusConfig` and `DeviceConfig` (the sync node's
    parameters), plus the checks that need both."""

    def __post_init__(self) -> None:
        BusConfig.__post_init__(self)
        DeviceConfig.__post_init__(self)
        if self.drive_node_id == self.master_node_id:
            raise _bad('master_node_id', self.master_node_id,
                       f'1..127 except drive_node_id={self.drive_node_id}')
        if self.master_heartbeat_timeout <= self.heartbeat_period:
            raise _bad('master_heartbeat_timeout', self.master_heartbeat_timeout,
                       f'> heartbeat_period={self.heartbeat_period} s')

    @property
    def bus(self) -> BusConfig:
        return BusConfig(**{f.name: getattr(self, f.name) for f in fields(BusConfig)})

    @property
    def device(self) -> DeviceConfig:
        return DeviceConfig(**{f.name: getattr(self, f.name) for f in fields(DeviceConfig)})

    @classmethod
    def of(cls, bus: BusConfig, device: DeviceConfig) -> 'DriveConfig':
        """The drive `device` on `bus`."""
        values = {f.name: getattr(device, f.name) for f in fields(DeviceConfig)}
        values.update({f.name: getattr(bus, f.name) for f in fields(BusConfig)})
        return cls(**values)
