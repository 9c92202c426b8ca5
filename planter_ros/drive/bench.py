"""Figures for the CAN drive on a virtual bus: enable time, SDO round trip, TPDO latency,
command (RPDO) latency and send_velocity cost.

    .venv/bin/python -m planter_ros.drive.bench [--repeats N]

Master and simulated drive share this process (two python-can virtual buses on one channel),
so the latencies include both Python stacks and the thread hand-over, no wire time.
"""
from __future__ import annotations

import argparse
import logging
import statistics
import time
import uuid

from planter_ros.drive.cia402 import Cia402Drive, DriveConfig
from planter_ros.drive.simulated_drive import SimulatedDrive


def _summary(values_s: list[float], unit: float = 1e3, name: str = 'ms') -> str:
    values = sorted(v * unit for v in values_s)
    p99 = values[min(len(values) - 1, int(0.99 * len(values)))]
    return (f'median {statistics.median(values):.3f} {name}, p99 {p99:.3f} {name}, '
            f'max {values[-1]:.3f} {name} (n={len(values)})')


def _session(repeats: int) -> dict[str, list[float]]:
    channel = f'planter-bench-{uuid.uuid4().hex}'
    sim = SimulatedDrive(channel)
    sim.start()
    drive = Cia402Drive(DriveConfig(channel=channel, motor_gear_ratio=12.5))
    figures: dict[str, list[float]] = {'enable': [], 'sdo': [], 'tpdo': [], 'rpdo': [], 'send': []}
    try:
        for _ in range(max(2, repeats // 20)):
            t0 = time.perf_counter()
            drive.connect_and_enable()
            figures['enable'].append(time.perf_counter() - t0)
            drive.shutdown()
        drive.connect_and_enable()
        node = drive.node
        for _ in range(repeats):
            t0 = time.perf_counter()
            node.sdo[0x6041].raw                       # expedited upload, one round trip
            figures['sdo'].append(time.perf_counter() - t0)
        # TPDO latency: drive-side send timestamp (virtual bus: time.time()) -> master callback
        node.tpdo[2].add_callback(lambda m: figures['tpdo'].append(time.time() - m.timestamp))
        # command latency: send_velocity() call -> the simulated drive decoded the RPDO
        sent: dict[str, float | None] = {'t': None}

        def decoded(_pdo_map) -> None:
            if sent['t'] is not None:
                figures['rpdo'].append(time.perf_counter() - sent['t'])
                sent['t'] = None
        sim.node.rpdo[1].add_callback(decoded)
        next_heartbeat = 0.0
        for i in range(repeats):
            speed = 1.0 + 0.001 * (i % 100)
            sent['t'] = t0 = time.perf_counter()
            drive.send_velocity(speed)
            figures['send'].append(time.perf_counter() - t0)
            if t0 >= next_heartbeat:
                drive.send_heartbeat()
                next_heartbeat = t0 + 0.1
            time.sleep(0.002)
        sent['t'] = None
        del figures['tpdo'][repeats:]
        # the call's own cost: the drive leaves the bus, nobody receives or competes for the GIL
        sim.stop()
        figures['send_alone'] = []
        for i in range(repeats):
            t0 = time.perf_counter()
            drive.send_velocity(1.0)
            figures['send_alone'].append(time.perf_counter() - t0)
    finally:
        sim.stop()
        drive.shutdown()                                # no drive left: closes without waiting
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--repeats', type=int, default=1000, help='samples per figure (>= 20)')
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.ERROR)    # the final shutdown finds no drive: expected
    if args.repeats < 20:
        parser.error(f'--repeats {args.repeats} is out of range (allowed: >= 20)')
    f = _session(args.repeats)
    print('CAN drive on a virtual bus (master + simulated drive in one process)')
    print(f'  first enable (fresh drive)  : {f["enable"][0] * 1e3:.3f} ms')
    print(f'  re-enable after shutdown    : {_summary(f["enable"][1:])}'
          ' (includes the wait for the drive\'s next heartbeat, period 0.1 s)')
    print(f'  SDO round trip (0x6041)     : {_summary(f["sdo"])}')
    print(f'  TPDO latency (drive->master): {_summary(f["tpdo"])}')
    print(f'  RPDO latency (send->decoded): {_summary(f["rpdo"])}')
    print(f'  send_velocity cost          : {_summary(f["send"], 1e6, "us")}')
    print(f'  send_velocity, nobody on bus: {_summary(f["send_alone"], 1e6, "us")}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
