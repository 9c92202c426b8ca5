"""Simulated drives in a process of their own, on one end of a CAN socket pair
(`drive.socket_bus`): `python -m planter_ros.simdrive.process --fd N --nodes 1,2 [--options
JSON]` (the options: SimSpec fields, and `node_kwargs` per node id).

In the master's process the simulated drives share its GIL: a master stalled by its process
(a DDS publish holding the GIL, a collection) stalls them too, and they see no gap a real drive
would see. Here they run on their own clock, as devices on the cable do, and count what a real
drive would: watchdog trips, gaps between command frames and between SYNCs.

The parent talks to it over stdin/stdout (JSON lines): a line `["power_cycle", node id, off
s]` or `["emcy_storm", node id, rate, s]` injects that fault into that drive (`SimProcess.inject`;
doc/command.md, "Faults and their recovery"); end-of-file on stdin (the parent asked, or died,
even by SIGKILL) stops the drives and the process; the last stdout line is the report
(`{"watchdog_trips": [[node id, reason, EMCY code], ...], "rpdo_gaps": {...}, "sync": {...},
"drives": {...}}`: per drive the gaps between command frames, the SYNC timing on its own clock,
its state at the end). `SimProcess`
is the parent's handle.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import threading
from typing import Any

from planter_ros.drive.socket_bus import SocketPairBus

from .bus import SimulatedBus

__all__ = ['SimProcess', 'drives_report', 'end_states', 'main']


def end_states(drives: list) -> dict[str, dict[str, Any]]:
    """Each drive's CiA 402 state, mode of operation (display), motor speed (rad/s), NMT state
    and whether it is homed, when it was stopped."""
    return {str(d.node_id): {'state': d.state, 'mode': d.mode_display,
                             'motor_velocity': d.motor_velocity, 'nmt': d.nmt_state,
                             'homed': d.device.homing.homed} for d in drives}


def drives_report(sims: Any) -> dict[str, Any]:
    """What the simulated drives of `sims` (a SimulatedBus) counted on their own clock: watchdog
    trips, RPDO, SYNC and heartbeat gaps, the instants each mechanism truly passed its bottom,
    faults, and each drive's end state; the same whether they ran in their own process or in
    the caller's."""
    return {'watchdog_trips': [list(trip) for trip in sims.watchdog_trips],
            'rpdo_gaps': {str(d.node_id): d.rpdo_gaps.summary() for d in sims.drives},
            'sync': {str(d.node_id): d.sync_summary() for d in sims.drives},
            'heartbeat_gaps': {str(d.node_id): d.heartbeat_gaps.summary() for d in sims.drives},
            'bottom_times': {str(d.node_id): d.bottom_times for d in sims.drives
                             if d.spec.record_bottom},
            'faults': {str(d.node_id): {'power_cycles': d.power_cycles,
                                        'emcy_sent': d.emcy_sent} for d in sims.drives},
            'end': end_states(sims.drives)}


class SimProcess:
    """The parent's handle: start the drives' process on `fd` (one end of a CAN socket pair,
    inherited), stop it and read its report."""

    def __init__(self, fd: int, node_ids: list[int], priority: int = 0,
                 **options: Any) -> None:
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'planter_ros.simdrive.process', '--fd', str(fd),
             '--nodes', ','.join(str(n) for n in node_ids), '--options', json.dumps(options),
             '--priority', str(priority)],
            pass_fds=(fd,), stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        if self.process.stdin is None or self.process.stdout is None:     # PIPE makes both
            raise RuntimeError('the simulated drives\' process has no stdin/stdout pipe')
        self._stdin, self._stdout = self.process.stdin, self.process.stdout
        line = self._stdout.readline()
        if not line.startswith('ready'):
            self.process.kill()
            self.process.wait()
            raise RuntimeError(f'the simulated drives did not start: {line.strip()!r}')
        self.report: dict | None = None

    FAULTS = ('power_cycle', 'emcy_storm')

    def inject(self, fault: str, node_id: int, *args: float) -> None:
        """Inject `fault` ('power_cycle' off_s, 'emcy_storm' rate s) into drive `node_id`."""
        if fault not in self.FAULTS:
            raise ValueError(f'fault {fault!r}: allowed {", ".join(self.FAULTS)}')
        self._stdin.write(json.dumps([fault, int(node_id), *args]) + '\n')
        self._stdin.flush()

    def stop(self, timeout: float = 10.0) -> dict:
        """Stop the drives; their report ({} if none came)."""
        if self.report is not None:
            return self.report
        try:
            self._stdin.close()
            out = self._stdout.read()
            self.process.wait(timeout)
        except (OSError, subprocess.TimeoutExpired):
            self.process.kill()
            self.process.wait()
            out = ''
        lines = [line for line in out.splitlines() if line.startswith('{')]
        self.report = json.loads(lines[-1]) if lines else {}
        return self.report


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='planter_ros.simdrive.process')
    parser.add_argument('--fd', type=int, required=True)
    parser.add_argument('--nodes', required=True)
    parser.add_argument('--options', default='{}')
    parser.add_argument('--priority', type=int, default=0,
                        help='SCHED_FIFO priority (0: none): the drives stand for hardware, '
                             'whose servo loops and heartbeats no host load delays')
    args = parser.parse_args(argv)
    refused = ''
    if args.priority > 0:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(args.priority))
        except (OSError, ValueError, AttributeError) as exc:
            refused = f'SCHED_FIFO {args.priority} refused: {exc}'
    # the parent decides: the drives stand for hardware, which no stop signal to the process
    # group reaches (they end with their stdin, after the master shut them down)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, (signal.SIGINT, signal.SIGTERM))
    node_ids = [int(n) for n in args.nodes.split(',') if n]
    sims = SimulatedBus(SocketPairBus(args.fd), node_ids, **json.loads(args.options))
    sims.start()
    print('ready', os.getpid(), refused, flush=True)
    done = threading.Event()

    drives = {d.node_id: d for d in sims.drives}

    def watch_stdin() -> None:
        for line in sys.stdin:           # fault injections, until end-of-file: asked to stop,
            try:                         # or the parent died
                fault, node_id, *args = json.loads(line)
                if fault in SimProcess.FAULTS:
                    getattr(drives[int(node_id)], fault)(*args)
            except (ValueError, KeyError, TypeError) as exc:
                print(f'ignored {line.strip()!r}: {exc}', file=sys.stderr, flush=True)
        done.set()
    threading.Thread(target=watch_stdin, daemon=True).start()
    done.wait()
    sims.stop()
    print(json.dumps(drives_report(sims)), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
