"""Measure ground-speed message -> CAN frame latency of the sync node (a benchmark, not a test).

    python -m planter_ros.nodes.sync_latency [--samples N] [--rate HZ] [--executor single|multi]

The sync node runs in its own executor thread (as in its own process on the machine) against
the simulated drive on a virtual bus; the main thread publishes TwistStamped samples, each with
a speed no other sample has, and notes time.time() just before publish(). A listener on the bus
notes each velocity RPDO (python-can stamps virtual frames with time.time() at send). The frame
a sample caused is the first RPDO after the publish whose payload differs from the previous
RPDO's: the control timer only repeats the last command (speed-only mode, no acceleration limit
in the way), so a new payload can only come from the new sample.
"""

import argparse
import os
import statistics
import threading
import time


def measure(samples=1000, rate=50.0, executor='single', warmup=50):
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    import can
    import json
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.signals import SignalHandlerOptions
    from geometry_msgs.msg import TwistStamped
    from std_msgs.msg import String

    from planter_ros import interfaces
    from planter_ros.drive.simulated_drive import SimulatedDrive
    from planter_ros.nodes.qos import DESIGN_QOS, GROUND_SPEED_QOS
    from planter_ros.nodes.sync_node import SyncNode

    channel = f'planter_latency_{os.getpid()}'
    sim = SimulatedDrive(channel, node_id=1)
    sim.start()
    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    sync = SyncNode(context=context, parameter_overrides=[
        Parameter('can_channel', value=channel), Parameter('phase_lock', value=False),
        Parameter('max_acceleration', value=1000.0), Parameter('max_speed', value=100.0),
        Parameter('max_ground_acceleration', value=50.0),
        Parameter('ground_speed_tolerance', value=1.0)])
    source = Node('latency_source', context=context)
    speed_pub = source.create_publisher(TwistStamped, interfaces.GROUND_SPEED, GROUND_SPEED_QOS)
    design_pub = source.create_publisher(String, interfaces.DESIGN, DESIGN_QOS)
    design_pub.publish(String(data=json.dumps(
        {'mechanism': 'five_bar', 'plants_per_revolution': 1, 'plant_spacing': 0.2})))
    frames = []
    listener = can.Bus(interface='virtual', channel=channel)
    rpdo_ids = range(0x200 + 1, 0x580)

    def listen():
        while not stop.is_set():
            msg = listener.recv(timeout=0.1)
            if msg is not None and msg.arbitration_id in rpdo_ids:
                frames.append((msg.timestamp, msg.arbitration_id, bytes(msg.data)))

    stop = threading.Event()
    ex = (SingleThreadedExecutor if executor == 'single' else MultiThreadedExecutor)(
        context=context)
    ex.add_node(sync)
    try:
        sync.enable_drive()
        listen_thread = threading.Thread(target=listen, daemon=True)
        listen_thread.start()
        spin_thread = threading.Thread(target=ex.spin, daemon=True)
        spin_thread.start()
        time.sleep(0.5)                          # discovery and the latched design
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
        ex.shutdown(timeout_sec=2.0)
        sync.destroy_node()
        source.destroy_node()
        context.try_shutdown()
        listener.shutdown()
        sim.stop()
    return _latencies(sent, frames)


def _latencies(sent, frames):
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
    lat.sort()
    if not lat:
        return {'samples': len(sent), 'matched': 0}
    return {'samples': len(sent), 'matched': len(lat),
            'p50_ms': 1e3 * statistics.median(lat),
            'p99_ms': 1e3 * lat[min(len(lat) - 1, int(0.99 * len(lat)))],
            'max_ms': 1e3 * lat[-1]}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--samples', type=int, default=1000)
    parser.add_argument('--rate', type=float, default=50.0, help='samples per second')
    parser.add_argument('--executor', choices=('single', 'multi'), default='single')
    args = parser.parse_args(argv)
    r = measure(args.samples, args.rate, args.executor)
    if not r.get('matched'):
        print(f"no frame matched any of {r['samples']} samples")
        return 1
    print(f"ground_speed -> CAN frame latency ({args.executor}-threaded executor, "
          f"{r['matched']}/{r['samples']} samples matched at {args.rate:g} Hz): "
          f"p50 {r['p50_ms']:.3f} ms, p99 {r['p99_ms']:.3f} ms, max {r['max_ms']:.3f} ms")
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
