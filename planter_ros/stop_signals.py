"""SIGTERM is Ctrl-C: what systemd, `docker stop` and `timeout` send must stop a run cleanly.

`install()` handles SIGINT and SIGTERM alike. The first one asks for a clean stop: it is noted
(`received`), and whoever runs the process acts on it at a safe point — in a node's main,
rclpy's own handler (installed by rclpy.init() after ours, and calling ours afterwards) has
already shut its context down, so spin() returns and the node's clean-up runs (drives shut
down, bag finalised); the demo's loop polls `received`. Nothing is raised into whatever the
main thread is doing, so a stop never lands in the middle of writing a bag. The second signal
ends the process at once (`os._exit`, exit code 128 + the signal), for a stop that hangs.
`spin` runs a node's executor until the first signal (each wait bounded, so none is missed).
Pure Python: no ROS import.
"""

import os
import signal

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopSignals:
    """The handler of both stop signals; `received` is the first one (None until then)."""

    def __init__(self, name):
        self.name = name
        self.received = None

    def __call__(self, signum, _frame):
        if self.received is None:
            self.received = signum
            return
        os.write(2, f'{self.name}: second {signal.Signals(signum).name}: forced exit, without '
                 'a clean stop\n'.encode())
        os._exit(128 + signum)

    @property
    def name_received(self):
        """'SIGTERM', 'SIGINT' or '' (no stop asked for)."""
        return signal.Signals(self.received).name if self.received is not None else ''


def install(name):
    """Handle SIGINT and SIGTERM in this process as described above (call from the main
    thread, before rclpy.init()); returns the handler."""
    handler = StopSignals(name)
    for signum in STOP_SIGNALS:
        signal.signal(signum, handler)
    return handler


def spin(executor, handler, period=0.2):
    """Spin `executor` (an rclpy executor with the node added) until a stop signal arrives or
    its context ends. rclpy's own handler wakes a waiting executor, but a signal that lands
    while the wait is being set up can be missed (seen: about one SIGTERM in ten left a
    design node waiting forever on a loaded host), so each wait is bounded by `period` s and
    this handler's flag is checked after it. A signal landing between that check and the next
    wait shuts the context down under it: rclpy then refuses the wait (its RCLError "context is
    not valid"), which is this stop, not an error (seen on CI: a design node's SIGTERM ended in
    that traceback and exit code 1)."""
    while handler.received is None and executor.context.ok():
        try:
            executor.spin_once(timeout_sec=period)
        except Exception:                       # noqa: BLE001  (rclpy's RCLError: no ROS here)
            if handler.received is None and executor.context.ok():
                raise
            return


def ignore():
    """A helper process its parent stops (over a pipe): the terminal's Ctrl-C, which reaches
    the whole process group, must not stop it on its own."""
    for signum in STOP_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)
