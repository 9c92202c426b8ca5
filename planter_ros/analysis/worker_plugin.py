"""The local cluster's worker processes, tied to `planter analyze` (or `planter simulate`) by two
Dask worker plugins (only for the local cluster: the workers of an existing cluster,
--scheduler, are not ours):

* `DieWithParent`: each worker dies with the command's process, also when it is killed with
  SIGKILL (planter_ros.host.processes). Dask's own link (a pipe whose end-of-file ends the
  worker) needs the worker's Python to run; the kernel's signal does not.
* `QuietClose`: a closing worker says nothing more on the command's stderr (which it shares).
  A worker's close cuts its comms to the scheduler while a heartbeat may be on its way; that
  heartbeat then fails with "Stream is closed" and distributed logs it as an ERROR with its
  traceback (a race in distributed's Worker.close, dask/distributed issues 7105 and 7891).
  Plugins are torn down early in Worker.close, before the comms are cut.
"""

import logging
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


class QuietClose(WorkerPlugin):
    """When its worker starts to close: only CRITICAL records of distributed's loggers in that
    worker process from then on (the work is done or given up; what a user needs to know
    reaches the command through its tasks' results)."""

    name = 'planter-quiet-close'

    def teardown(self, worker):
        logging.getLogger('distributed').setLevel(logging.CRITICAL)
