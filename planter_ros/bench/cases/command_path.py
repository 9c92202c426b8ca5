"""Graph-join stall: does a DDS participant joining the graph stall the command frames?

The demo's command path (`demo.sync_process`: the sync node and its drives) runs on a private
DDS domain, fed with ground speed at 50 Hz by this process, while separate processes join and
leave that domain (each process creates a participant, a node and a publisher, keeps them
0.3 s, destroys them and starts again; up to 4 processes at a time). Two layouts in one run:

* before: the sync node, its CAN masters and the simulated drives in one process (virtual
  bus); a DDS publish that blocks on the transport's mutex holds the GIL, and every thread
  of the process stops, the drives' too (so they under-report what a real drive would see);
* after: the sync node is a shell; the command process (no DDS, no rclpy) sends the frames
  and the SYNC; the simulated drives run in a process of their own and count on the bus's
  clock.

Per layout: the largest gap between command frames, SYNC frames and master heartbeats as the
drives saw them, how many exceeded 50 ms, and the drives' watchdog trips. Targets (after): 0
command or SYNC gaps over 50 ms, heartbeat gaps ≤ 150 ms, 0 watchdog trips.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
import os
import subprocess
import sys
import threading
import time
from typing import Any, TypedDict
import uuid

from ..registry import BenchContext, Row, Target, bench_case
from ..timing import from_samples

WHAT = 'command path while DDS participants join and leave the graph (drive-side gaps)'
JOINERS = 4
HOLD = 0.3                 # s a joining participant stays
RATE = 50.0                # Hz, ground speed

JOINER = '''
import os, sys, time
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import String
domain, count, hold = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
parent = int(sys.argv[4])
for k in range(count):
    if os.getppid() != parent:        # the bench is gone: so are we
        break
    context = Context()
    rclpy.init(context=context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    node = Node(f'joiner_{k}', context=context)
    node.create_publisher(String, 'joiner', 10)
    time.sleep(hold)
    node.destroy_node()
    context.try_shutdown()
    print('joined', flush=True)
'''


class DriveFigures(TypedDict):
    """The drives' own figures of a run (s, counts)."""

    command_max: float
    command_over_50ms: int
    sync_max: float
    sync_over_50ms: int
    heartbeat_max: float
    watchdog_trips: int
    loop: dict[str, float]


def _drive_figures(report: Mapping[str, Any]) -> DriveFigures:
    """The drives' own figures: the largest gap (s) and the count over 50 ms of command frames,
    SYNC frames and master heartbeats, and the watchdog trips."""
    def worst(table: Mapping[str, Any] | None) -> tuple[float, int]:
        gaps = list((table or {}).values())
        return (max((g['max'] for g in gaps), default=0.0),
                sum(g['over'].get('50 ms', 0) for g in gaps))
    command = worst(report.get('drive_gaps'))
    sync = worst({k: v['gaps'] for k, v in (report.get('drive_sync') or {}).items()
                  if v.get('syncs')})
    heartbeat = worst(report.get('drive_heartbeat_gaps'))
    return {'command_max': command[0], 'command_over_50ms': command[1],
            'sync_max': sync[0], 'sync_over_50ms': sync[1],
            'heartbeat_max': heartbeat[0], 'watchdog_trips': len(report.get('watchdog_trips', [])),
            'loop': report.get('loop', {})}


def _silent(text: str) -> None:
    pass


def stall_run(command_process: bool, joins: int, progress: Callable[[str], None] = _silent
              ) -> tuple[DriveFigures, int, float]:
    """One run of the layout; returns (figures, joins done, seconds)."""
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    import rclpy
    from geometry_msgs.msg import TwistStamped
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import String

    from planter_ros import interfaces
    from planter_ros.dds_domain import claim_private_domain
    from planter_ros.demo.sync_process import SyncProcess, SyncProcessSettings
    from planter_ros.design import to_json
    from planter_ros.sim.runs import five_bar_design_message

    domain = claim_private_domain()
    names = ['r1', 'r2', 'r3', 'r4']
    rows: dict[str, object] = {'rows': names}
    for i, name in enumerate(names):
        rows[f'{name}.lateral_offset'] = 0.75 - 0.5 * i
        rows[f'{name}.drive_node_id'] = i + 1
    channel = f'planter-bench-stall-{uuid.uuid4().hex[:8]}'
    sync = SyncProcess(SyncProcessSettings(
        domain, channel, (1, 2, 3, 4), interfaces.NAMESPACE,
        tuple(rows.items()) + (('can_interface', 'virtual'), ('can_channel', channel)),
        'error', {'supported_modes': [3, 8]} if command_process else {},
        command_process=command_process))
    context = Context()
    rclpy.init(context=context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    node = Node('stall_source', context=context, namespace=interfaces.NAMESPACE)
    speed_pub = interfaces.GROUND_SPEED.publisher(node)
    design_pub = interfaces.DESIGN.publisher(node)
    joiners: list[subprocess.Popen[str]] = []
    done = [0]
    stop = threading.Event()
    t0 = time.perf_counter()
    try:
        sync.wait_for('ready', 120.0)
        design_pub.publish(String(data=to_json(five_bar_design_message(spacing=0.2))))
        per = max(joins // JOINERS, 1)
        joiners = [subprocess.Popen([sys.executable, '-c', JOINER, str(domain), str(per),
                                     str(HOLD), str(os.getpid())], stdout=subprocess.PIPE,
                                    text=True,
                                    stderr=subprocess.DEVNULL)
                   for _ in range(JOINERS)]

        def count(proc: subprocess.Popen[str]) -> None:
            for _ in proc.stdout or ():
                done[0] += 1
        counters = [threading.Thread(target=count, args=(p,), daemon=True) for p in joiners]
        for thread in counters:
            thread.start()
        msg = TwistStamped()
        msg.twist.linear.x = 0.2
        next_pub = time.monotonic()
        last_note = 0
        while any(p.poll() is None for p in joiners) and not stop.is_set():
            if time.monotonic() >= next_pub:
                speed_pub.publish(msg)
                next_pub += 1.0 / RATE
            sync.poll(0.0)
            if done[0] - last_note >= 50:
                last_note = done[0]
                progress(f'    {"after" if command_process else "before"}: {done[0]} joins')
            time.sleep(0.005)
        for thread in counters:
            thread.join(2.0)
    finally:
        for proc in joiners:
            if proc.poll() is None:
                proc.kill()
            proc.wait()
        final = sync.stop()
        report = final.flat() if final is not None else {}
        node.destroy_node()
        context.try_shutdown()
    return _drive_figures(report), done[0], time.perf_counter() - t0


@bench_case('graph-join stall', requires=('rclpy', 'can', 'planter_ros.command.process',
                                          'planter_ros.demo.sync_process'))
def graph_join_stall(ctx: BenchContext) -> Iterator[Row]:
    joins = ctx.n(400, 2 * JOINERS)          # --quick: the smoke run, two rounds of joiners
    results: dict[str, tuple[DriveFigures, int, float]] = {}
    for command_process in (False, True):
        name = 'after' if command_process else 'before'
        ctx.progress(f'  {name}: {joins} joins, {JOINERS} joiners at a time ...')
        results[name] = stall_run(command_process, joins, ctx.progress)
    for name, (fig, done, seconds) in results.items():
        ms = {'command_max': 1e3 * fig['command_max'], 'sync_max': 1e3 * fig['sync_max'],
              'heartbeat_max': 1e3 * fig['heartbeat_max']}
        targets = []
        if name == 'after':
            targets = [Target('0 command or SYNC gaps > 50 ms',
                              fig['command_over_50ms'] == 0 and fig['sync_over_50ms'] == 0),
                       Target('heartbeat gaps ≤ 150 ms', fig['heartbeat_max'] <= 0.15),
                       Target('0 watchdog trips', fig['watchdog_trips'] == 0)]
        method = ('before: sync node, masters and drives in one process' if name == 'before'
                  else 'after: shell + command process (CSP, SYNC 10 ms) + drives process')
        yield Row(WHAT, method, done, 'join', from_samples([seconds]),
                  error_of='no error defined: drive-side gaps in the note', targets=targets,
                  note=f'{done} joins; command gap max {ms["command_max"]:.1f} ms '
                       f'({fig["command_over_50ms"]} > 50 ms), SYNC gap max '
                       f'{ms["sync_max"]:.1f} ms ({fig["sync_over_50ms"]} > 50 ms), master '
                       f'heartbeat gap max {ms["heartbeat_max"]:.1f} ms, '
                       f'{fig["watchdog_trips"]} watchdog trip(s)',
                  extra={'joins': done, **fig})
