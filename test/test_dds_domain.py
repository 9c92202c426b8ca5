"""Private DDS domains: a graph started for our own purposes is out of reach of other graphs."""
import os
import socket
import subprocess
import sys

from planter_ros.host import dds_domain


def test_the_session_runs_in_a_private_domain_not_the_default():
    domain = int(os.environ['ROS_DOMAIN_ID'])
    assert domain != 0
    assert domain == dds_domain.claim_private_domain()      # one per process


def test_a_second_process_gets_another_domain():
    out = subprocess.run(
        [sys.executable, '-c',
         'from planter_ros.host.dds_domain import claim_private_domain; '
         'print(claim_private_domain())'],
        capture_output=True, text=True, check=True, timeout=30)
    assert int(out.stdout) != dds_domain.claim_private_domain()


def test_a_domain_whose_ports_are_bound_counts_as_used():
    domain = next(d for d in dds_domain.CANDIDATES if dds_domain.ports_free(d))
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind(('0.0.0.0', dds_domain.unicast_ports(domain)[0]))
        assert not dds_domain.ports_free(domain)
    finally:
        sock.close()
    assert dds_domain.ports_free(domain)
