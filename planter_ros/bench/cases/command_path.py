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
from dataclasses import dataclass
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


class Joiners:
    """The processes joining the graph: `at_once` of them, each doing its share of `joins`
    (each prints one line per join done). When no join is done for `stuck` s, the running ones
    are stuck (in their DDS shutdown: JOIN_STUCK): each is killed, counted in `killed`, and a
    new one does the joins it still owed."""

    def __init__(self, argv: Callable[[int], list[str]], joins: int, at_once: int,
                 stuck: float = JOIN_STUCK, progress: Callable[[str], None] = _silent) -> None:
        self.argv, self.stuck, self.progress = argv, stuck, progress
        self.done = 0           # joins done, by every joiner
        self.killed = 0         # stuck joiners killed
        self.procs: list[subprocess.Popen[str]] = []
        self._owed: dict[int, int] = {}
        self._joined: dict[int, int] = {}
        self._counters: list[threading.Thread] = []
        per = max(joins // at_once, 1)
        for _ in range(at_once):
            self._start(per)
        self._last_done, self._last_progress = 0, time.monotonic()

    def _start(self, count: int) -> None:
        proc = subprocess.Popen(self.argv(count), stdout=subprocess.PIPE, text=True,
                                stderr=subprocess.DEVNULL)
        self._owed[proc.pid], self._joined[proc.pid] = count, 0

        def counting() -> None:
            for _ in proc.stdout or ():
                self.done += 1
                self._joined[proc.pid] += 1
        self._counters.append(threading.Thread(target=counting, daemon=True))
        self._counters[-1].start()
        self.procs.append(proc)

    def running(self) -> bool:
        return any(p.poll() is None for p in self.procs)

    def check(self) -> None:
        """Kill the running joiners when none did a join for `stuck` s; hand their joins on."""
        now = time.monotonic()
        if self.done != self._last_done:
            self._last_done, self._last_progress = self.done, now
            return
        if now - self._last_progress <= self.stuck:
            return
        for proc in [p for p in self.procs if p.poll() is None]:
            proc.kill()
            proc.wait()
            self.killed += 1
            left = self._owed[proc.pid] - self._joined[proc.pid]
            self.progress(f'    a joiner made no progress for {self.stuck:g} s (stuck in its '
                          f'DDS shutdown): killed, {left} of its joins handed on')
            if left > 0:
                self._start(left)
        self._last_progress = time.monotonic()

    def finish(self, timeout: float = 2.0) -> None:
        """Wait for the counting of every line printed (after the joiners ended)."""
        for thread in self._counters:
            thread.join(timeout)

    def kill(self) -> None:
        for proc in self.procs:
            if proc.poll() is None:
                proc.kill()
            proc.wait()


@dataclass(frozen=True)
class StallRun:
    """One run of a layout: the drives' figures, the joins done, its seconds, and how many
    stuck joiners were killed (their joins handed on)."""

    figures: DriveFigures
    joins: int
    seconds: float
    stuck_killed: int


def stall_run(command_process: bool, joins: int, progress: Callable[[str], None] = _silent
              ) -> StallRun:
    """One run of the layout."""
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
    joiners: Joiners | None = None
    t0 = time.perf_counter()
    try:
        sync.wait_for('ready', 120.0)
        design_pub.publish(String(data=to_json(five_bar_design_message(spacing=0.2))))
        joiners = Joiners(lambda count: [sys.executable, '-c', JOINER, str(domain), str(count),
                                         str(HOLD), str(os.getpid())], joins, JOINERS,
                          progress=progress)
        recording.set()
        msg = TwistStamped()
        msg.twist.linear.x = 0.2
        next_pub = time.monotonic()
        last_note = 0
        while joiners.running():
            joiners.check()
            if time.monotonic() >= next_pub:
                speed_pub.publish(msg)
                next_pub += 1.0 / RATE
            sync.poll(0.0)
            if joiners.done - last_note >= 50:
                last_note = joiners.done
                progress(f'    {"after" if command_process else "before"}: {joiners.done} joins')
            executor.spin_once(timeout_sec=0.005)
        recording.clear()
        joiners.finish()
    finally:
        if joiners is not None:
            joiners.kill()
        final = sync.stop()
        report = final.flat() if final is not None else {}
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()
    assert joiners is not None          # made in the try, which returned normally
    return StallRun(_drive_figures(report, stamps, period), joiners.done,
                    time.perf_counter() - t0, joiners.killed)


@bench_case('graph-join stall')
def graph_join_stall(ctx: BenchContext) -> Iterator[Row]:
    joins = ctx.n(400, 2 * JOINERS)          # --quick: the smoke run, two rounds of joiners
    results: dict[str, StallRun] = {}
    for command_process in (False, True):
        name = 'after' if command_process else 'before'
        ctx.progress(f'  {name}: {joins} joins, {JOINERS} joiners at a time ...')
        results[name] = stall_run(command_process, joins, ctx.progress)
    for name, run in results.items():
        fig, done, seconds = run.figures, run.joins, run.seconds
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
                       f'twice the feedback period); {run.stuck_killed} stuck joiner(s) killed '
                       f'(no join for {JOIN_STUCK:g} s: a DDS participant shutdown that hangs), '
                       'their joins handed on',
                  extra={'joins': done, 'stuck_joiners_killed': run.stuck_killed, **fig})
