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
drives saw them, how many exceeded 50 ms, and the drives' watchdog trips; and the recording's
side: this process subscribes joint_states as a recorder does (the recording QoS) and reports
the largest hole between consecutive stamps and how many exceed twice the feedback period.
Targets (after): 0 command or SYNC gaps over 50 ms, heartbeat gaps ≤ 150 ms, 0 watchdog trips,
no joint_states hole over twice the feedback period (the SYNC period, 10 ms).
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

from geometry_msgs.msg import TwistStamped
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import String

from planter_ros import interfaces
from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.demo.sync_process import SyncProcess, SyncProcessSettings
from planter_ros.design import to_json
from planter_ros.drive.config import DriveConfig
from planter_ros.host.dds_domain import claim_private_domain
from planter_ros.sim.runs import five_bar_design_message

from ..registry import BenchContext, Row, Target, bench_case
from ..timing import from_samples

WHAT = 'command path while DDS participants join and leave the graph (drive-side gaps)'
JOINERS = 4
HOLD = 0.3                 # s a joining participant stays
RATE = 50.0                # Hz, ground speed
# s without a join done: a joiner is stuck in its DDS shutdown (an
# rmw_fastrtps destroy_participant spinning in DomainParticipant::set_listener at 100 % CPU,
# seen twice in 800 joins): the stuck one is killed and another does its remaining joins
JOIN_STUCK = 20.0

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
    joint_states: int
    joint_hole_max: float
    joint_holes_over: int


def _joint_holes(stamps: list[int], limit: float) -> tuple[float, int]:
    """The largest hole (s) between consecutive joint_states stamps (ns, in any order of
    arrival) and how many exceed `limit` s."""
    ordered = sorted(stamps)
    holes = [(b - a) * 1e-9 for a, b in zip(ordered, ordered[1:])]
    return max(holes, default=0.0), sum(hole > limit for hole in holes)


def _drive_figures(report: Mapping[str, Any], stamps: list[int], period: float
                   ) -> DriveFigures:
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
    hole_max, holes_over = _joint_holes(stamps, 2.0 * period)
    return {'joint_states': len(stamps), 'joint_hole_max': hole_max,
            'joint_holes_over': holes_over,
            'command_max': command[0], 'command_over_50ms': command[1],
            'sync_max': sync[0], 'sync_over_50ms': sync[1],
            'heartbeat_max': heartbeat[0], 'watchdog_trips': len(report.get('watchdog_trips', [])),
            'loop': report.get('loop', {})}


def _silent(text: str) -> None:
    pass


def stall_run(command_process: bool, joins: int, progress: Callable[[str], None] = _silent
              ) -> tuple[DriveFigures, int, float]:
    """One run of the layout; returns (figures, joins done, seconds)."""
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
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
    stamps: list[int] = []          # joint_states stamps (ns) while the joiners run
    recording = threading.Event()

    def on_joint(msg: Any) -> None:
        if recording.is_set():
            stamps.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
    interfaces.JOINT_STATES.subscribe(node, on_joint, qos=interfaces.JOINT_STATES.recording_qos())
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    # the feedback period: one sample per SYNC (CSP, after), per control step (before)
    period = DriveConfig().sync_period if command_process else SyncLoopConfig().control_period
    design_pub = interfaces.DESIGN.publisher(node)
    joiners: list[subprocess.Popen[str]] = []
    done = [0]
    stop = threading.Event()
    t0 = time.perf_counter()
    try:
        sync.wait_for('ready', 120.0)
        design_pub.publish(String(data=to_json(five_bar_design_message(spacing=0.2))))
        per = max(joins // JOINERS, 1)
        counters: list[threading.Thread] = []

        def start_joiner(count: int) -> subprocess.Popen[str]:
            proc = subprocess.Popen([sys.executable, '-c', JOINER, str(domain), str(count),
                                     str(HOLD), str(os.getpid())], stdout=subprocess.PIPE,
                                    text=True, stderr=subprocess.DEVNULL)
            joined[proc.pid] = 0

            def counting() -> None:
                for _ in proc.stdout or ():
                    done[0] += 1
                    joined[proc.pid] += 1
            counters.append(threading.Thread(target=counting, daemon=True))
            counters[-1].start()
            joiners.append(proc)
            return proc
        joined: dict[int, int] = {}
        owed = {start_joiner(per).pid: per for _ in range(JOINERS)}
        recording.set()
        msg = TwistStamped()
        msg.twist.linear.x = 0.2
        next_pub = time.monotonic()
        last_note = 0
        last_done, last_progress = 0, time.monotonic()
        while any(p.poll() is None for p in joiners) and not stop.is_set():
            if done[0] != last_done:
                last_done, last_progress = done[0], time.monotonic()
            elif time.monotonic() - last_progress > JOIN_STUCK:
                # a joiner stuck in its DDS shutdown: killed, another does its remaining joins
                for proc in [p for p in joiners if p.poll() is None]:
                    proc.kill()
                    proc.wait()
                    left = owed[proc.pid] - joined[proc.pid]
                    progress(f'    a joiner made no progress for {JOIN_STUCK:g} s (stuck in its '
                             f'DDS shutdown): killed, {left} of its joins handed on')
                    if left > 0:
                        owed[start_joiner(left).pid] = left
                last_progress = time.monotonic()
            if time.monotonic() >= next_pub:
                speed_pub.publish(msg)
                next_pub += 1.0 / RATE
            sync.poll(0.0)
            if done[0] - last_note >= 50:
                last_note = done[0]
                progress(f'    {"after" if command_process else "before"}: {done[0]} joins')
            executor.spin_once(timeout_sec=0.005)
        recording.clear()
        for thread in counters:
            thread.join(2.0)
    finally:
        for proc in joiners:
            if proc.poll() is None:
                proc.kill()
            proc.wait()
        final = sync.stop()
        report = final.flat() if final is not None else {}
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()
    return _drive_figures(report, stamps, period), done[0], time.perf_counter() - t0


@bench_case('graph-join stall')
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
            targets = [Target(f'≥ {joins} joins', done >= joins),
                       Target('0 command or SYNC gaps > 50 ms',
                              fig['command_over_50ms'] == 0 and fig['sync_over_50ms'] == 0),
                       Target('heartbeat gaps ≤ 150 ms', fig['heartbeat_max'] <= 0.15),
                       Target('0 watchdog trips', fig['watchdog_trips'] == 0),
                       Target('no joint_states hole > 2 feedback periods',
                              fig['joint_states'] > 0 and fig['joint_holes_over'] == 0)]
        method = ('before: sync node, masters and drives in one process' if name == 'before'
                  else 'after: shell + command process (CSP, SYNC 10 ms) + drives process')
        yield Row(WHAT, method, done, 'join', from_samples([seconds]),
                  error_of='no error defined: drive-side gaps in the note', targets=targets,
                  note=f'{done} joins; command gap max {ms["command_max"]:.1f} ms '
                       f'({fig["command_over_50ms"]} > 50 ms), SYNC gap max '
                       f'{ms["sync_max"]:.1f} ms ({fig["sync_over_50ms"]} > 50 ms), master '
                       f'heartbeat gap max {ms["heartbeat_max"]:.1f} ms, '
                       f'{fig["watchdog_trips"]} watchdog trip(s); joint_states as recorded: '
                       f'{fig["joint_states"]} samples, largest hole '
                       f'{1e3 * fig["joint_hole_max"]:.1f} ms ({fig["joint_holes_over"]} over '
                       'twice the feedback period)',
                  extra={'joins': done, **fig})
