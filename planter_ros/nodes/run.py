"""The main of a node that only spins: discovery kept on the host, SIGTERM stopping like Ctrl-C,
each wait bounded (`stop_signals`), a bad parameter or setting (any of planter_ros's errors:
`errors.PlanterError`) answered in one line with exit code 2, the node destroyed and rclpy shut
down however the run ends."""
from collections.abc import Callable, Sequence
import sys

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from planter_ros.errors import PlanterError
from planter_ros.host import stop_signals
from planter_ros.host.dds_domain import keep_discovery_on_host

__all__ = ['run_node']


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
