"""A DDS domain of this process's own: graphs started for the product's own purposes (demo,
bench, sample and season generators, tests) must be unreachable from any other graph on the host.
And the machine's own nodes discover only on this host unless the user widens it on purpose.

ROS 2 graphs in different DDS domains never see each other. A domain counts as free when no
process of ours holds its claim and no participant on the host has bound its first unicast
ports (Fast DDS and the other DDS vendors bind 7410 + 250·domain + 2·participant and the port
after it for each participant, on every interface). The claim is held until the process exits,
so two runs started at the same instant never pick the same domain. On Linux the claim is a
socket bound in the abstract namespace (no file: nothing is left behind, however the process
ends, and it is seen by exactly the processes that share the network, as the DDS ports are);
elsewhere a lock file in the temporary directory. Domain 0 (everybody's default) is never
chosen. A private graph writes no log files (`PRIVATE_GRAPH_ROS_ARGS`): its console output is
its log. Pure Python: no ROS import.
"""

from collections.abc import MutableMapping
import fcntl
import os
import socket
import sys
import tempfile
from typing import TextIO

from planter_ros.errors import PlanterError

# 1..101: the domain ids whose ports stay below Linux's ephemeral range (32768 and up)
CANDIDATES = range(1, 102)
PARTICIPANTS_PROBED = 5
# rclpy.init arguments of a private graph: no log file in ~/.ros/log for each run
PRIVATE_GRAPH_ROS_ARGS = ('--disable-external-lib-logs',)
# domain -> bound socket or open lock file, kept for the life of the process
_held: dict[int, socket.socket | TextIO] = {}


class NoFreeDomainError(PlanterError, RuntimeError):
    """Every candidate domain is in use on this host (one line)."""


def unicast_ports(domain: int, participants: int = PARTICIPANTS_PROBED) -> list[int]:
    """The metatraffic and user unicast ports of the first `participants` participants."""
    base = 7400 + 250 * domain
    return [base + 10 + 2 * i + k for i in range(participants) for k in (0, 1)]


def ports_free(domain: int) -> bool:
    """True when no participant of `domain` has bound its unicast ports on this host."""
    for port in unicast_ports(domain):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            try:
                sock.bind(('127.0.0.1', port))
            except OSError:
                return False
    return True


def _lock_path(domain: int) -> str:
    return os.path.join(tempfile.gettempdir(), f'planter_ros-dds-domain-{domain}.lock')


def _claim(domain: int) -> socket.socket | TextIO | None:
    """This process's claim on `domain` (held while the returned object is open), or None when
    another process holds it."""
    if sys.platform.startswith('linux'):
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        try:
            sock.bind(f'\0planter_ros-dds-domain-{domain}')
        except OSError:
            sock.close()
            return None
        return sock
    try:
        handle = open(_lock_path(domain), 'a')
    except OSError:
        return None
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.close()
        return None
    return handle


def claim_private_domain() -> int:
    """Claim a free DDS domain for this process and return its id (cached: one per process)."""
    if _held:
        return next(iter(_held))
    start = os.getpid() % len(CANDIDATES)
    order = list(CANDIDATES[start:]) + list(CANDIDATES[:start])
    for domain in order:
        handle = _claim(domain)
        if handle is None:
            continue
        if ports_free(domain):
            _held[domain] = handle
            return domain
        handle.close()
    raise NoFreeDomainError(f'no free DDS domain among {CANDIDATES.start}..{CANDIDATES.stop - 1} '
                            'on this host')


def keep_discovery_on_host(environ: MutableMapping[str, str] = os.environ) -> str:
    """ROS_AUTOMATIC_DISCOVERY_RANGE unset (or empty) -> LOCALHOST, before rclpy.init(): the
    nodes of one machine run on one host, and a graph reachable from the whole subnet is a
    choice the user makes (SUBNET, or SYSTEM_DEFAULT with ROS_STATIC_PEERS). Returns the range
    in force."""
    if not environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE'):
        environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return environ['ROS_AUTOMATIC_DISCOVERY_RANGE']


def isolate_environment(environ: MutableMapping[str, str] = os.environ) -> int:
    """Point ROS_DOMAIN_ID at a private domain (and keep discovery on the host unless the
    environment already chose a range); returns the domain id."""
    domain = claim_private_domain()
    environ['ROS_DOMAIN_ID'] = str(domain)
    keep_discovery_on_host(environ)
    return domain
