"""Sync loop rows: ground-speed message -> CAN frame latency of the real sync node, for a
machine of 1, 4 and 8 rows (one drive each on one bus); and the closed-loop simulation of a
4-row machine through 10 m curves, with and without turn compensation.

The sync node runs in its own executor thread (as in its own process on the machine) against
the simulated drives on a virtual bus of its own; the bench thread publishes TwistStamped
samples, each with a speed no other sample has, and notes time.time() just before publish().
A listener on the bus notes each velocity RPDO (python-can stamps virtual frames with
time.time() at send). The frame a sample caused, per row, is that row's first RPDO after the
publish whose payload differs from its previous RPDO's: the control timer only repeats the last
command (speed-only mode, no acceleration limit in the way), so a new payload can only come
from the new sample; a sample's latency is the time to the last row's frame. ROS runs in a
fresh Context on a private DDS domain, discovery on localhost only, so no other process's
topics mix in. The simulated drives sit on one bus of their own (`SimulatedBus`, as devices on
one cable) but share the process and its GIL (a thread each): with 8 of them the figures include
their load, which a machine's real drives do not put on the master; and a virtual-bus send
copies the frame in Python, where SocketCAN hands it to the kernel.
"""

from collections.abc import Iterator
import os
import threading
import time
import uuid

import can
from geometry_msgs.msg import TwistStamped
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import String

from planter_ros import interfaces
from planter_ros.design import to_json
from planter_ros.host.dds_domain import PRIVATE_GRAPH_ROS_ARGS, claim_private_domain
from planter_ros.host.stop_signals import SpinThread
from planter_ros.command.engine import CommandEngine
from planter_ros.nodes.sync_node import SyncNode
from planter_ros.sim.closed_loop import LoopTiming, RowCurveFigures, curve_comparison
from planter_ros.sim.runs import five_bar_design_message
from planter_ros.simdrive.bus import SimulatedBus

from ..registry import BenchContext, Row, Target, bench_case
from ..timing import from_samples

WHAT = 'sync loop: ground-speed message → CAN frame'
WHAT_ROWS = "sync loop, rows on one bus: ground-speed message → last row's CAN frame"
WHAT_CURVE = 'closed loop, 4 rows through 10 m turns: spacing error per row'
P99_TARGET = 2e-3          # quality target: sync loop ground-speed-message -> CAN frame p99
ROW_COUNTS = (1, 4, 8)
RATE = 50.0                # Hz, ground-speed samples
# --quick (the smoke run: does every row group come out, not its figures): 1 s of samples per
# run after 0.2 s of warm-up, the sizes that never failed a suite (one with 20 after 5 did:
# the drives tripped early on the loaded host and no frame matched)
QUICK_SAMPLES, QUICK_WARMUP = 50, 10
ERROR_OF = 'no error defined: timings only'


def row_parameters(rows: int) -> dict[str, object]:
    """Scene parameters of a machine of `rows` rows (node ids 1..rows, 0.5 m apart), as a
    parameter file gives them; none for one row (a scene without rows)."""
    if rows <= 1:
        return {}
    names = [f'row{i + 1}' for i in range(rows)]
    out: dict[str, object] = {'rows': names}
    for i, name in enumerate(names):
        out[f'{name}.lateral_offset'] = 0.5 * (0.5 * (rows - 1) - i)
        out[f'{name}.drive_node_id'] = i + 1
    return out


# a drive watchdog trip: (node id, reason, EMCY code)
Trip = tuple[int, str, int]


def sync_latencies(samples: int, rate: float = RATE, warmup: int = 50, timeout: float = 10.0,
                   rows: int = 1) -> tuple[list[float], int, list[Trip]]:
    """Seconds from publish() to the last row's CAN frame it caused, one entry per sample
    matched on every row; returns (latencies, samples sent). The node spins in rclpy's
    single-threaded executor, as sync_node's main does."""
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    channel = f'planter-bench-sync-{uuid.uuid4().hex}'
    context = Context()
    rclpy.init(args=['--ros-args', *PRIVATE_GRAPH_ROS_ARGS], context=context,
               domain_id=claim_private_domain(),
               signal_handler_options=SignalHandlerOptions.NO)
    sims: SimulatedBus | None = None
    sync: SyncNode | None = None
    source: Node | None = None
    spinner: SpinThread | None = None
    listener: can.BusABC | None = None
    frames: list[tuple[float, int, bytes]] = []
    stop = threading.Event()
    try:
        sims = SimulatedBus(channel, range(1, max(rows, 1) + 1))
        sims.start()
        sync = SyncNode(context=context, parameter_overrides=[
            Parameter('can_interface', value='virtual'), Parameter('can_channel', value=channel),
            Parameter('phase_lock', value=False),
            Parameter('max_acceleration', value=1000.0), Parameter('max_speed', value=100.0),
            Parameter('max_ground_acceleration', value=50.0),
            Parameter('ground_speed_tolerance', value=1.0)]
            + [Parameter(k, value=v) for k, v in row_parameters(rows).items()])
        source = Node('latency_source', context=context)
        speed_pub = interfaces.GROUND_SPEED.publisher(source)
        design_pub = interfaces.DESIGN.publisher(source)
        design_pub.publish(String(data=to_json(five_bar_design_message(spacing=0.2))))
        listener = can.Bus(interface='virtual', channel=channel)
        rpdo_ids = range(0x200 + 1, 0x200 + max(rows, 1) + 1)

        def listen(bus: can.BusABC) -> None:
            while not stop.is_set():
                msg = bus.recv(timeout=0.1)
                if msg is not None and msg.arbitration_id in rpdo_ids:
                    frames.append((msg.timestamp, msg.arbitration_id, bytes(msg.data)))

        ex = SingleThreadedExecutor(context=context)
        spinner = SpinThread(ex, 'bench-sync-executor')
        ex.add_node(sync)
        sync.enable_drive()
        engine = sync.engine
        if not isinstance(engine, CommandEngine):      # a virtual bus: in the node's process
            raise TypeError('the sync latency bench runs the command path in process')
        threading.Thread(target=listen, args=(listener,), daemon=True).start()
        spinner.start()
        deadline = time.monotonic() + timeout
        # discovery done and the latched design taken
        while speed_pub.get_subscription_count() == 0 or engine.law.spacing is None:
            if time.monotonic() > deadline:
                raise TimeoutError(f'the sync node did not see the source within {timeout} s')
            time.sleep(0.01)
        sent: list[float] = []
        msg = TwistStamped()
        for i in range(samples + warmup):
            msg.twist.linear.x = 0.2 + 0.001 * (i % 200)    # a new command every sample
            t = time.time()
            speed_pub.publish(msg)
            if i >= warmup:
                sent.append(t)
            time.sleep(1.0 / rate)
        time.sleep(0.2)
        trips = sims.watchdog_trips
    finally:
        stop.set()
        if spinner is not None:
            spinner.stop()                  # spinning ended, then the executor shut down
        for node in (sync, source):
            if node is not None:
                node.destroy_node()
        context.try_shutdown()
        if listener is not None:
            listener.shutdown()
        if sims is not None:
            sims.stop()
    return match_frames(sent, frames), len(sent), trips


def tripped(trips: list[Trip]) -> str:
    """Why no command changed, when a drive's watchdog stopped it (the host starved the
    process past the drive's deadlines): '' otherwise."""
    if not trips:
        return ''
    node, reason, code = trips[0]
    return (f': the drives quick-stopped ({len(trips)} watchdog trip(s), first node {node}: '
            f'{reason}, EMCY {code:04X}h)')


def match_frames(sent: list[float], frames: list[tuple[float, int, bytes]]) -> list[float]:
    """Latency of each sample: per row (COB-ID), the first RPDO after it, before the next
    sample, with a new payload; the sample's latency is the last row's. A sample some row has
    no such frame for is left out."""
    changes: dict[int, list[float]] = {}
    last: dict[int, bytes] = {}
    for stamp, cob, data in frames:
        if last.get(cob) is not None and data != last[cob]:
            changes.setdefault(cob, []).append(stamp)
        last[cob] = data
    lat = []
    cursor = {cob: 0 for cob in changes}
    for k, t in enumerate(sent):
        nxt = sent[k + 1] if k + 1 < len(sent) else float('inf')
        worst = None
        for cob, stamps in changes.items():
            j = cursor[cob]
            while j < len(stamps) and stamps[j] < t:
                j += 1
            cursor[cob] = j
            if j < len(stamps) and stamps[j] < nxt:
                worst = stamps[j] if worst is None else max(worst, stamps[j])
            else:
                worst = None
                break
        if worst is not None and changes:
            lat.append(worst - t)
    return lat


@bench_case('sync loop latency')
def sync_latency(ctx: BenchContext) -> Iterator[Row]:
    samples = ctx.n(1000, QUICK_SAMPLES)
    ctx.progress(f'  {samples} samples at {RATE:g} Hz ...')
    lat, sent, trips = sync_latencies(samples, RATE, warmup=ctx.n(50, QUICK_WARMUP))
    if not lat:
        raise RuntimeError(f'no CAN frame matched any of {sent} ground-speed samples'
                           + tripped(trips))
    t = from_samples(lat, tail=True)
    yield Row(WHAT, 'sync_node (single-threaded executor, own thread)', 1, 'message', t,
              error_of=ERROR_OF, targets=[Target('p99 ≤ 2 ms', t.tail <= P99_TARGET)],
              note=f'{len(lat)}/{sent} samples matched at {RATE:g} Hz, max '
                   f'{max(lat) * 1e3:.2f} ms; frame stamped by python-can at send',
              extra={'samples': sent, 'matched': len(lat), 'max_s': max(lat)})


@bench_case('sync loop latency per row count')
def sync_latency_rows(ctx: BenchContext) -> Iterator[Row]:
    samples = ctx.n(1000, QUICK_SAMPLES)
    for rows in ROW_COUNTS:
        ctx.progress(f'  {rows} row(s): {samples} samples at {RATE:g} Hz ...')
        lat, sent, trips = sync_latencies(samples, RATE, warmup=ctx.n(50, QUICK_WARMUP), rows=rows)
        if not lat:
            raise RuntimeError(f'{rows} rows: no sample matched a CAN frame on every row'
                               + tripped(trips))
        t = from_samples(lat, tail=True)
        targets = [Target('8 rows: p99 ≤ 2 ms', t.tail <= P99_TARGET)] if rows == 8 else []
        yield Row(WHAT_ROWS, f'{rows} row(s), simulated drives in the process', rows,
                  'row', t, error_of=ERROR_OF, targets=targets,
                  note=f'{len(lat)}/{sent} samples matched on every row at {RATE:g} Hz, p50 '
                       f'{t.median * 1e3:.2f} ms, p99 {t.tail * 1e3:.2f} ms, max '
                       f'{max(lat) * 1e3:.2f} ms',
                  extra={'rows': rows, 'samples': sent, 'matched': len(lat),
                         'max_s': max(lat)})


@bench_case('closed loop through curves')
def closed_loop_curves(ctx: BenchContext) -> Iterator[Row]:
    result: dict[str, list[RowCurveFigures]] = {}
    timing = LoopTiming(dt=ctx.n(0.001, 0.002))
    t = ctx.measure(lambda: result.update(curve_comparison(timing=timing)),
                    repeats=1, min_time=0.0)
    d = 0.2

    def known(value: float | None) -> float:
        if value is None:
            raise RuntimeError('a curve of the run has no plants: it has no figures')
        return value
    for mode in ('compensated', 'uncompensated'):
        for row in result[mode]:
            worst = max(known(c['rms_spacing_error']) for c in row['curves'])
            ratios = [known(c['median_speed_ratio']) for c in row['curves']]
            detail = '; '.join(
                f"R {c['radius']:+g} m: RMS {known(c['rms_spacing_error']) * 1e3:.2f} mm, mean "
                f"{known(c['mean_spacing_error']) * 1e3:+.2f} mm (−y·d/R "
                f"{c['uncompensated_bias'] * 1e3:+.1f} mm), speed ratio "
                f"{known(c['median_speed_ratio']):.3f}" for c in row['curves'])
            targets = []
            if mode == 'compensated':
                targets = [Target('RMS ≤ 2 % of d', worst <= 0.02 * d),
                           Target('speed ratio within 3 %',
                                  all(abs(r - 1.0) <= 0.03 for r in ratios))]
            yield Row(WHAT_CURVE, f"{mode}, row y = {row['lateral_offset']:+.2f} m", 1, 'run',
                      t, error=worst / d,
                      error_of='worst RMS spacing error in a curve over d (tomato, d = 200 mm, '
                               '0.2 and 0.3 m/s, 5 mm/s and 5 mrad/s sensor noise)',
                      targets=targets, note=detail,
                      extra={'curves': row['curves'], 'mode': mode})
