"""The local cluster's workers die with `planter analyze` (or `planter simulate`), also when it is
killed with SIGKILL: a Dask worker plugin ties each worker process to the command's process
(planter_ros.host.processes). Dask's own link (a pipe whose end-of-file ends the worker) needs the
worker's Python to run; the kernel's signal does not. Only for the local cluster: the workers
of an existing cluster (--scheduler) are not ours."""

import os

from distributed import WorkerPlugin

from planter_ros.host.processes import die_with_parent


class DieWithParent(WorkerPlugin):
    """Sets the parent-death signal in each worker process as it starts."""

    name = 'planter-die-with-parent'

    def __init__(self, parent_pid=None):
        self.parent_pid = os.getpid() if parent_pid is None else parent_pid

    def setup(self, worker):
        die_with_parent(self.parent_pid)
