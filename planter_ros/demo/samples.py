"""The committed sample bags that come from the real monitor node fed a simulated run:
`python -m planter_ros.demo.samples [--out bags]` regenerates bags/sample_<name>.mcap (the demo
records the other samples). Refuses to overwrite: delete a bag first to make it anew.
"""

import argparse
from collections.abc import Callable
from pathlib import Path

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from planter_ros.host.dds_domain import PRIVATE_GRAPH_ROS_ARGS, claim_private_domain
from planter_ros.nodes.monitor_node import MonitorNode
from planter_ros.recording.errors import BagWriteError
from planter_ros.sim.lockstep import LockStepFeeder
from planter_ros.sim.runs import Run, RunOptions, five_bar_design_message, simulate_run

__all__ = ['SAMPLES', 'main', 'record_sample']


def _pepper_stall() -> Run:
    """A pepper five-bar whose drive stalls at 7 s for 3.5 s (10 % of its speed)."""
    design = five_bar_design_message(depth=0.06, spacing=0.3, hole_ratio=0.05, ground_speed=0.3)
    return simulate_run(design, RunOptions(duration=20.0, cruise=0.3, step=1.6, drive_lag=0.25,
                                           phase_gain=1.0, stall_at=7.0, stall_for=3.5,
                                           stall_level=0.1, seed=2))


# name: the simulated run its bag records
SAMPLES: dict[str, Callable[[], Run]] = {'pepper_stall': _pepper_stall}


def record_sample(run, bag_path, monitor_parameters=None, timeout=60.0):
    """Run the real monitor node on `run` (sim.runs.Run) and let it record `bag_path`.

    The graph runs in a DDS domain of this process's own (planter_ros.host.dds_domain), on a
    simulated clock fed in lock-step (sim.lockstep). Returns the list of plant tables the
    monitor published (its live predictions), in order.
    """
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', *PRIVATE_GRAPH_ROS_ARGS], context=context,
               domain_id=claim_private_domain())
    params = [Parameter('use_sim_time', value=True), Parameter('bag_path', value=str(bag_path))]
    params += [Parameter(k, value=v) for k, v in (monitor_parameters or {}).items()]
    monitor = feeder = executor = None
    try:
        monitor = MonitorNode(context=context, parameter_overrides=params)
        if monitor.recorder is None:
            raise BagWriteError(monitor.record_error or 'the monitor is not recording')
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(monitor)
        feeder = LockStepFeeder(context, executor, taken=lambda: monitor.samples_taken,
                                has_design=lambda: monitor.has_design, timeout=timeout)
        feeder.feed(run, monitor.get_clock)
        return monitor.published_tables()
    finally:
        if feeder is not None:
            feeder.destroy()
        if executor is not None:
            executor.shutdown()
        if monitor is not None:
            monitor.destroy_node()
        rclpy.try_shutdown(context=context)


def main(argv=None):
    """Regenerate bags/sample_<name>.mcap (refuses to overwrite: delete them first)."""
    parser = argparse.ArgumentParser(description=main.__doc__, allow_abbrev=False)
    parser.add_argument('--out', default='bags', help='directory for the sample bags')
    args = parser.parse_args(argv)
    for name, simulated in SAMPLES.items():
        path = Path(args.out) / f'sample_{name}.mcap'
        run = simulated()
        tables = record_sample(run, path)
        print(f'{path}: {sum(len(t) for t in tables)} plants, {path.stat().st_size} bytes')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
