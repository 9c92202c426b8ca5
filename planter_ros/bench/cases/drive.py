"""CAN drive rows: enable time, SDO round trip, TPDO and RPDO latency, send_velocity() cost.

Master (`Cia402Drive`) and simulated drive share this process on a python-can virtual bus (a
channel of their own), so the latencies include both Python stacks and the hand-over between
their threads, no wire time. Each figure is measured event by event: median, p10–p90 and p99.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
import logging
import time
import uuid

from planter_ros.drive.cia402 import Cia402Drive, DriveConfig
from planter_ros.simdrive.drive import SimulatedDrive

from ..registry import BenchContext, Row, bench_case
from ..timing import from_samples

WHAT = 'CAN drive (virtual bus, master and simulated drive in one process)'
ERROR_OF = 'no error defined: timings only'


@contextmanager
def _quiet(*names: str) -> Iterator[None]:
    """Our final shutdown finds no drive on the bus (we stopped it first): expected, not news."""
    loggers = [logging.getLogger(n) for n in names]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


@contextmanager
def _drive_pair() -> Iterator[tuple[SimulatedDrive, Cia402Drive]]:
    """A simulated drive and our master on a fresh virtual channel; both stopped on exit."""
    channel = f'planter-bench-drive-{uuid.uuid4().hex}'
    sim = SimulatedDrive(channel)
    sim.start()
    drive = Cia402Drive(DriveConfig(can_interface='virtual', can_channel=channel,
                                    motor_gear_ratio=12.5))
    try:
        yield sim, drive
    finally:
        sim.stop()
        drive.shutdown()                 # no drive left: closes without waiting


def drive_session(samples: int, fresh: int) -> dict[str, list[float]]:
    """Per-event seconds of every drive figure: {'first_enable': [...], 'sdo': [...], ...}."""
    f: dict[str, list[float]] = {k: [] for k in ('first_enable', 'enable', 'sdo', 'tpdo',
                                                  'rpdo', 'send', 'send_alone')}
    for _ in range(fresh):
        with _drive_pair() as (_, drive):
            t0 = time.perf_counter()
            drive.connect_and_enable()
            f['first_enable'].append(time.perf_counter() - t0)
    with _drive_pair() as (sim, drive):
        for _ in range(max(2, samples // 20)):
            drive.connect_and_enable()
            drive.shutdown()
            t0 = time.perf_counter()
            drive.connect_and_enable()
            f['enable'].append(time.perf_counter() - t0)
            drive.shutdown()
        drive.connect_and_enable()
        node = drive.node
        if node is None:                 # connect_and_enable() made it or raised
            raise RuntimeError('the drive has no CANopen node after connect_and_enable()')
        for _ in range(samples):
            t0 = time.perf_counter()
            _ = node.sdo[0x6041].raw                   # expedited upload, one round trip
            f['sdo'].append(time.perf_counter() - t0)
        # TPDO latency: drive-side send stamp (virtual bus: time.time()) -> master callback
        node.tpdo[2].add_callback(lambda m: f['tpdo'].append(time.time() - m.timestamp))
        # command latency: send_velocity() call -> the simulated drive decoded the RPDO
        sent: dict[str, float | None] = {'t': None}

        def decoded(_pdo_map: object) -> None:
            if sent['t'] is not None:
                f['rpdo'].append(time.perf_counter() - sent['t'])
                sent['t'] = None
        sim.node.rpdo[1].add_callback(decoded)
        next_heartbeat = 0.0
        for i in range(samples):
            speed = 1.0 + 0.001 * (i % 100)
            sent['t'] = t0 = time.perf_counter()
            drive.send_velocity(speed)
            f['send'].append(time.perf_counter() - t0)
            if t0 >= next_heartbeat:
                drive.send_heartbeat()
                next_heartbeat = t0 + 0.1
            time.sleep(0.002)
        sent['t'] = None
        del f['tpdo'][samples:]
        # the call's own cost: the drive leaves the bus, nobody receives or competes for the GIL
        sim.stop()
        for _ in range(samples):
            t0 = time.perf_counter()
            drive.send_velocity(1.0)
            f['send_alone'].append(time.perf_counter() - t0)
    return f


ROWS = (
    ('first_enable', 'first enable, fresh drive', 'connect_and_enable() on a new bus and drive'),
    ('enable', 're-enable after shutdown',
     "waits for the drive's next heartbeat (period 0.1 s)"),
    ('sdo', 'SDO round trip (6041h upload)', 'expedited upload, one request and one response'),
    ('tpdo', 'TPDO latency, drive send → master callback',
     'frame stamped by python-can at send (time.time())'),
    ('rpdo', 'RPDO latency, send_velocity() → drive decoded it', ''),
    ('send', 'send_velocity() cost, drive on the bus',
     "pays for the virtual bus copy and the drive's receive thread taking the GIL"),
    ('send_alone', 'send_velocity() cost, nobody else on the bus', "the call's own cost"),
)


@bench_case('CAN drive')
def can_drive(ctx: BenchContext) -> Iterator[Row]:
    samples = ctx.n(1000, 50)
    fresh = ctx.n(10, 2)
    ctx.progress(f'  {samples} samples per figure, {fresh} fresh enables ...')
    with _quiet('planter_ros.drive', 'canopen', 'can'):
        f = drive_session(samples, fresh)
    for key, label, note in ROWS:
        values = f[key]
        if not values:
            raise RuntimeError(f'{label}: no event was measured')
        count = f'{len(values)} events'
        yield Row(WHAT, label, 1, 'event', from_samples(values, tail=True), error_of=ERROR_OF,
                  note=f'{count}; {note}' if note else count, extra={'events': len(values)})
