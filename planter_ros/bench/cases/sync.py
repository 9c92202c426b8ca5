"""Sync loop rows: ground-speed message -> CAN frame latency of the real sync node.

The sync node runs in its own executor thread (as in its own process on the machine) against
the simulated drive on a virtual bus of its own; the bench thread publishes TwistStamped
samples, each with a speed no other sample has, and notes time.time() just before publish().
A listener on the bus notes each velocity RPDO (python-can stamps virtual frames with
time.time() at send). The frame a sample caused is the first RPDO after the publish whose
payload differs from the previous RPDO's: the control timer only repeats the last command
(speed-only mode, no acceleration limit in the way), so a new payload can only come from the
new sample. ROS runs in a fresh Context on a private DDS domain, discovery on localhost only,
so no other process's topics mix in.
"""

import os
import threading
import time
import uuid

from ..registry import Row, Target, bench_case
from ..timing import from_samples

WHAT = 'sync loop: ground-speed message → CAN frame'
P99_TARGET = 2e-3          # quality target: sync loop ground-speed-message -> CAN frame p99
RATE = 50.0                # Hz, ground-speed samples
ERROR_OF = 'no error defined: timings only'


def sync_latencies(samples, rate=RATE, warmup=50, timeout=10.0):
    """Seconds from publish() to the CAN frame it caused, one entry per matched sample;
    returns (latencies, samples sent). The node spins in rclpy's single-threaded executor,
    as sync_node's main does."""
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    import can
    import json
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.signals import SignalHandlerOptions
    from geometry_msgs.msg import TwistStamped
    from std_msgs.msg import String

    from planter_ros import interfaces
    from planter_ros.drive.simulated_drive import SimulatedDrive
    from planter_ros.nodes.sync_node import SyncNode
    from planter_ros.dds_domain import claim_private_domain

    channel = f'planter-bench-sync-{uuid.uuid4().hex}'
    context = Context()
    rclpy.init(context=context, domain_id=claim_private_domain(),
               signal_handler_options=SignalHandlerOptions.NO)
    sim = sync = source = ex = listener = None
    frames = []
    stop = threading.Event()
    try:
        sim = SimulatedDrive(channel, node_id=1)
        sim.start()
        sync = SyncNode(context=context, parameter_overrides=[
            Parameter('can_interface', value='virtual'), Parameter('can_channel', value=channel),
            Parameter('phase_lock', value=False),
            Parameter('max_acceleration', value=1000.0), Parameter('max_speed', value=100.0),
            Parameter('max_ground_acceleration', value=50.0),
            Parameter('ground_speed_tolerance', value=1.0)])
        source = Node('latency_source', context=context)
        speed_pub = interfaces.GROUND_SPEED.publisher(source)
        design_pub = interfaces.DESIGN.publisher(source)
        design_pub.publish(String(data=json.dumps(
            {'mechanism': 'five_bar', 'plants_per_revolution': 1, 'plant_spacing': 0.2})))
        listener = can.Bus(interface='virtual', channel=channel)
        rpdo_ids = range(0x200 + 1, 0x580)

        def listen():
            while not stop.is_set():
                msg = listener.recv(timeout=0.1)
                if msg is not None and msg.arbitration_id in rpdo_ids:
                    frames.append((msg.timestamp, msg.arbitration_id, bytes(msg.data)))

        ex = SingleThreadedExecutor(context=context)
        ex.add_node(sync)
        sync.enable_drive()
        threading.Thread(target=listen, daemon=True).start()
        threading.Thread(target=ex.spin, daemon=True).start()
        deadline = time.monotonic() + timeout
        # discovery done and the latched design taken
        while speed_pub.get_subscription_count() == 0 or sync.law.spacing is None:
            if time.monotonic() > deadline:
                raise TimeoutError(f'the sync node did not see the source within {timeout} s')
            time.sleep(0.01)
        sent = []
        msg = TwistStamped()
        for i in range(samples + warmup):
            msg.twist.linear.x = 0.2 + 0.001 * (i % 200)    # a new command every sample
            t = time.time()
            speed_pub.publish(msg)
            if i >= warmup:
                sent.append(t)
            time.sleep(1.0 / rate)
        time.sleep(0.2)
    finally:
        stop.set()
        if ex is not None:
            ex.shutdown(timeout_sec=2.0)
        for node in (sync, source):
            if node is not None:
                node.destroy_node()
        context.try_shutdown()
        if listener is not None:
            listener.shutdown()
        if sim is not None:
            sim.stop()
    return match_frames(sent, frames), len(sent)


def match_frames(sent, frames):
    """Latency of each sample: first RPDO after it, before the next sample, with a new payload."""
    changes = []
    last = {}
    for stamp, cob, data in frames:
        if last.get(cob) is not None and data != last[cob]:
            changes.append(stamp)
        last[cob] = data
    lat = []
    j = 0
    for k, t in enumerate(sent):
        nxt = sent[k + 1] if k + 1 < len(sent) else float('inf')
        while j < len(changes) and changes[j] < t:
            j += 1
        if j < len(changes) and changes[j] < nxt:
            lat.append(changes[j] - t)
    return lat


@bench_case('sync loop latency', requires=('rclpy', 'can', 'planter_ros.nodes.sync_node'))
def sync_latency(ctx):
    samples = ctx.n(1000, 50)
    ctx.progress(f'  {samples} samples at {RATE:g} Hz ...')
    lat, sent = sync_latencies(samples, RATE, warmup=ctx.n(50, 10))
    if not lat:
        raise RuntimeError(f'no CAN frame matched any of {sent} ground-speed samples')
    t = from_samples(lat, tail=True)
    yield Row(WHAT, 'sync_node (single-threaded executor, own thread)', 1, 'message', t,
              error_of=ERROR_OF, targets=[Target('p99 ≤ 2 ms', t.p99 <= P99_TARGET)],
              note=f'{len(lat)}/{sent} samples matched at {RATE:g} Hz, max '
                   f'{max(lat) * 1e3:.2f} ms; frame stamped by python-can at send',
              extra={'samples': sent, 'matched': len(lat), 'max_s': max(lat)})
