"""Node health on /diagnostics, in one place: the levels, the status names and the KeyValue keys
the package writes and reads, the one way a status is built and the one way it is read back.

A node's health policy decides a `Report` (task, level, message, key/value pairs: the sync
node's in control.sync_status, the monitor's in nodes.monitor_node); `array` turns a node's
reports into the diagnostic_msgs/DiagnosticArray it publishes: each status named
`<node>: <task>` (diagnostic_aggregator groups by that prefix), its level the same byte as
DiagnosticStatus has, every value as text. `values` reads a status's key/value pairs back (tests,
tools); `decode` reads a DiagnosticArray out of a bag; `section_states` reads the section states
the sync node's statuses carried before they had the `sections` topic of their own
(interfaces.SECTIONS), for bags recorded then.

Pure: no rclpy. diagnostic_msgs is imported only where a message is built; a recorded message is
decoded by rosbags' CDR deserialiser.
"""

from collections.abc import Iterable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

__all__ = ['OK', 'WARN', 'ERROR', 'STALE', 'LEVEL_NAMES', 'Report', 'worst',
           'DRIVE', 'GROUND_SPEED', 'PHASE_LOCK', 'BUS', 'CONTROL_LOOP', 'DESIGN',
           'PREDICTION', 'RECORDING', 'SPACING_QUALITY', 'SECTION', 'SECTION_ON',
           'SECTION_OFF', 'status_name', 'task_of', 'status', 'array', 'decode', 'level_of',
           'values', 'section_states']

# levels, the bytes of diagnostic_msgs/DiagnosticStatus
OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVEL_NAMES = {OK: 'OK', WARN: 'WARN', ERROR: 'ERROR', STALE: 'STALE'}
# how bad a level is, for merging (diagnostic_msgs numbers STALE above ERROR)
_SEVERITY = {OK: 0, WARN: 1, STALE: 2, ERROR: 3}

# status (task) names. The sync node: its drive, its ground-speed input, the phase lock (a
# scene without rows; with rows one status per row, named after the row), the CAN bus and the
# control loop's deadline. Both nodes: who set the design (scene.design_sources). The monitor:
# its predictions, its recording and the spacing quality so far.
DRIVE = 'drive'
GROUND_SPEED = 'ground speed'
PHASE_LOCK = 'phase lock'
BUS = 'bus'
CONTROL_LOOP = 'control loop'
DESIGN = 'design'
PREDICTION = 'prediction'
RECORDING = 'recording'
SPACING_QUALITY = 'spacing quality'

# the key of a row's (or the phase lock's) status saying whether its section is on or off;
# read back only from bags recorded before the `sections` topic (`section_states`). Every other
# key is a label for people, written once, where its figure is computed.
SECTION = 'section'
SECTION_ON, SECTION_OFF = 'on', 'off'


@dataclass(frozen=True)
class Report:
    """One status: task name, level (OK..STALE), message, (key, value) pairs."""

    task: str
    level: int
    message: str
    values: tuple = ()


def worst(levels: Iterable[int]) -> int:
    """The worst of some levels (STALE is worse than WARN, ERROR worst)."""
    return max(levels, key=_SEVERITY.__getitem__)


def status_name(node_name: str, task: str) -> str:
    """A status's name: `<node>: <task>`."""
    return f'{node_name}: {task}'


def task_of(name: str) -> str:
    """The task of a status name (`<node>: <task>` -> task)."""
    return name.rsplit(': ', 1)[-1]


def status(report: Report, node_name: str, hardware_id: str) -> Any:
    """The diagnostic_msgs/DiagnosticStatus of a report."""
    # lazy: diagnostic_msgs costs 15 ms (rosidl_parser) and only a node builds a message;
    # replay and analyze decode recorded ones with rosbags (`decode`)
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
    return DiagnosticStatus(level=bytes((report.level,)), name=status_name(node_name,
                                                                           report.task),
                            message=report.message, hardware_id=hardware_id,
                            values=[KeyValue(key=str(k), value=str(v))
                                    for k, v in report.values])


def array(reports: Iterable[tuple[Report, str]], node_name: str, stamp: Any = None) -> Any:
    """The diagnostic_msgs/DiagnosticArray of a node's reports, each with its hardware id;
    `stamp` (builtin_interfaces/Time) in its header."""
    from diagnostic_msgs.msg import DiagnosticArray  # lazy: 15 ms, as in `status`
    msg = DiagnosticArray(status=[status(r, node_name, hardware_id)
                                  for r, hardware_id in reports])
    if stamp is not None:
        msg.header.stamp = stamp
    return msg


def decode(raw: bytes | bytearray | memoryview) -> Any:
    """The diagnostic_msgs/DiagnosticArray of CDR bytes (as a bag holds them), without rclpy:
    an object with `header` and `status` (each with `level` as an int, `name`, `message`,
    `hardware_id`, `values` of `key`/`value`). Raises ValueError for bytes that are not one."""
    try:
        return _typestore().deserialize_cdr(bytes(raw), 'diagnostic_msgs/msg/DiagnosticArray')
    except Exception as exc:         # rosbags' SerdeError, or what the bytes made it trip on
        raise ValueError(f'not a DiagnosticArray: {str(exc).splitlines()[0]}') from None


@lru_cache(maxsize=1)
def _typestore() -> Any:
    # lazy: rosbags costs 16 ms and only a recorded message is decoded; the nodes and the
    # command process, which build theirs, load this module and never decode
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def level_of(diagnostic: Any) -> int:
    """A status's level as a number (rclpy gives the byte as bytes, other readers an int)."""
    level = diagnostic.level
    return level[0] if isinstance(level, (bytes, bytearray)) else int(level)


def values(diagnostic: Any) -> dict[str, str]:
    """A status's key/value pairs as a dict."""
    return {item.key: item.value for item in diagnostic.values}


def section_states(statuses: Iterable[Any]) -> dict[str, bool]:
    """{row name: section on} from diagnostic statuses (objects with `name` and `values` of
    `key`/`value`, as diagnostic_msgs has them) as the sync node published them before the
    `sections` topic: each row's status (`<node>: <row>`), or in a scene without rows its
    phase-lock status (row name ''). Statuses without the section key are not the sync
    node's: left out."""
    states = {}
    for diagnostic in statuses:
        for item in diagnostic.values:
            if item.key == SECTION and item.value in (SECTION_ON, SECTION_OFF):
                task = task_of(diagnostic.name)
                states['' if task == PHASE_LOCK else task] = item.value == SECTION_ON
                break
    return states
