"""The main of a node that only spins: discovery kept on the host, SIGTERM stopping like Ctrl-C,
each wait bounded (`stop_signals`), a bad parameter or setting (any of planter_ros's errors:
`errors.PlanterError`) answered in one line with exit code 2, the node destroyed and rclpy shut
down however the run ends. And the executor of the graphs the product starts for itself (the
demo's two processes): `graph_executor`."""
from collections.abc import Callable, Sequence
import sys

import rclpy
from rclpy.context import Context
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from planter_ros.errors import PlanterError
from planter_ros.host import stop_signals
from planter_ros.host.dds_domain import keep_discovery_on_host

_events_executor: Callable[..., Executor] | None
try:
    from rclpy.experimental import EventsExecutor as _events_executor
except ImportError:                       # rclpy before 7.1.4 (Jazzy): graph_executor
    _events_executor = None

__all__ = ['graph_executor', 'run_node']


def graph_executor(context: Context) -> Executor:
    """The executor of a graph the product starts for itself in `context` (the demo's design
    node, monitor, simulated sensors and observer; its sync process's sync node): rclpy's
    EventsExecutor where this rclpy has it (Jazzy's rclpy 7.1.4 and later), else a
    SingleThreadedExecutor. The SingleThreadedExecutor builds its wait set anew, in Python, at
    every wake-up (each joint_states, speed command and ground-speed sample): the demo's own
    process took 13.0 s of CPU in a 30 s 4-row demo with it, 7.0 s with the EventsExecutor (the
    bench's demo-runs case, two runs each, PASS every time). The machine's own nodes (run_node,
    the sync node's main) keep rclpy's standard executor: the EventsExecutor is still
    experimental in Jazzy. Callbacks run in it must be plain functions: before 7.1.11 it runs no
    coroutine callback of a subscription or a service."""
    if _events_executor is None:
        return SingleThreadedExecutor(context=context)
    return _events_executor(context=context)


def run_node(name: str, make_node: Callable[[list[str]], Node], args: list[str] | None = None,
             errors: Sequence[type[BaseException]] = ()) -> int:
    """Run the node `make_node(arguments)` makes (arguments: `args` or the command line) until
    a stop signal or the context ends; the exit code: 0, or 2 after one line `name: error: ...`
    on stderr for a PlanterError, a ParameterException or one of `errors`."""
    keep_discovery_on_host()
    stop = stop_signals.install(name)      # SIGTERM stops like Ctrl-C: the node's clean-up runs
    rclpy.init(args=args)
    caught: tuple[type[BaseException], ...] = (PlanterError, ParameterException, *errors)
    node = None
    try:
        node = make_node(sys.argv if args is None else args)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        stop_signals.spin(executor, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except caught as exc:
        print(f'{name}: error: {str(exc).splitlines()[0]}', file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
