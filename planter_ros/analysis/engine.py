"""The Dask distributed engine of `planter analyze` and `planter simulate`.

`cluster()` gives a Client: of a local cluster of worker processes sized to the machine (one
single-threaded worker process per usable core, or `workers`), scheduler and workers bound to
127.0.0.1, no dashboard, each worker dying with this process and silent once it closes
(worker_plugin: no shutdown race of distributed's on the user's terminal), its allocator
keeping a bag's buffers (WORKER_MALLOC); of one worker in this process (`in_process`: the
commands' `--workers 1`, no process to start: a small season's run takes ~1.8 s of CPU less);
or of an existing cluster (`scheduler` = its scheduler's address, `tcp://host:8786`).
`check_workers` runs a warm-up on every worker (imports the code once, says
which model version it runs) and refuses a cluster that cannot run ours. `completed` maps a
function over argument tuples and yields the results as they complete, gathered in batches.
"""

import asyncio
from contextlib import contextmanager
from dataclasses import dataclass
import logging
import os
import shutil
import tempfile

from planter_ros.config import check, setting
from planter_ros.errors import PlanterError

CONNECT_TIMEOUT = 10.0      # s to reach an existing scheduler
WORKER_WAIT = 30.0          # s an existing scheduler may take to have a worker
HANDSHAKE_GRACE = 2.0       # s beyond CONNECT_TIMEOUT for a connected scheduler's handshake
# glibc's allocator in the local workers: Dask starts them with MALLOC_TRIM_THRESHOLD_ = 64 KiB
# (memory handed back to the system at once), which also fixes the mmap threshold at 128 KiB,
# so every array or buffer a bag needs above that (the decompressed chunks, the joints' bytes,
# the arcs) is mapped fresh and faulted in page by page: 1.5-3 ms of a 60-s bag's 15-18 ms.
# These keep a bag's buffers in the heap from one bag to the next; a worker keeps at most
# 32 MiB more than it uses.
WORKER_MALLOC = {'MALLOC_MMAP_THRESHOLD_': str(16 << 20), 'MALLOC_TRIM_THRESHOLD_': str(32 << 20)}


class EngineError(PlanterError, ValueError):
    """A cluster the command cannot use (one line: the option or address and why)."""


@dataclass(frozen=True)
class EngineSettings:
    """The local cluster's size (the command-line option)."""

    workers: int = setting(1, 'worker processes of the local cluster (one thread each)',
                           range=(1, 512))

    def __post_init__(self):
        check(self)


def scheduler_address(text):
    """`text` if it is a scheduler address Dask can connect to (`tcp://host:port`, ...), else
    EngineError."""
    from distributed.comm.addressing import (  # lazy: distributed 350 ms (as above)
        parse_address, parse_host_port)
    try:
        scheme, location = parse_address(text, strict=True)
        parse_host_port(location)
    except (ValueError, TypeError):
        raise EngineError(f'--scheduler = {text} is not a scheduler address: allowed '
                          'tcp://host:port (or tls://, ws://, wss://)') from None
    if scheme not in ('tcp', 'tls', 'ws', 'wss'):
        raise EngineError(f'--scheduler = {text} uses protocol {scheme}: allowed tcp://, '
                          'tls://, ws:// or wss://host:port')
    return text


def usable_cores():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


@contextmanager
def cluster(workers=None, scheduler=None, in_process=False):
    """A distributed.Client (see the module doc); everything is closed on exit. `in_process`
    (with `workers` 1): the scheduler and the one single-threaded worker in this process
    (in-memory comms: nothing listens but the scheduler's HTTP routes on 127.0.0.1)."""
    if in_process and (scheduler or workers != 1):
        raise ValueError('in_process is a local cluster of one worker (workers=1)')
    from distributed import Client, LocalCluster  # lazy: 350 ms, only when bags are analysed
    # the workers inherit the environment: any ROS they touched would stay on loopback
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    local = scratch = None
    if scheduler:
        probe_scheduler(scheduler)
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise EngineError(f'--scheduler = {scheduler}: cannot connect '
                              f'({_first_line(exc)}): allowed the address of a running Dask '
                              'scheduler, e.g. tcp://host:8786') from None
        try:
            client.wait_for_workers(1, timeout=WORKER_WAIT)
        except (OSError, TimeoutError) as exc:
            client.close()
            raise EngineError(f'--scheduler = {scheduler} has no worker after '
                              f'{WORKER_WAIT:.0f} s ({_first_line(exc)}): allowed a scheduler '
                              'with at least one worker') from None
    else:
        import dask  # lazy: 100 ms, only for a local cluster

        # lazy: a distributed WorkerPlugin: loading it loads distributed (as above)
        from .worker_plugin import DieWithParent, QuietClose
        scratch = scratch_directory()
        try:
            with dask.config.set({'temporary-directory': scratch, **{
                    f'distributed.nanny.pre-spawn-environ.{k}': v
                    for k, v in WORKER_MALLOC.items()}}):
                # (the scheduler serves its HTTP routes, health and metrics, whatever the
                # dashboard: on a free loopback port, not on 8787, which another cluster may
                # hold: Dask then warns "Port 8787 is already in use" on stderr)
                # (the in-process cluster's comms are in memory (inproc://), no host or port)
                where = ({'processes': False} if in_process else
                         {'processes': True, 'host': '127.0.0.1', 'scheduler_port': 0,
                          'plugins': {DieWithParent(), QuietClose()}})
                local = LocalCluster(n_workers=workers or usable_cores(), threads_per_worker=1,
                                     dashboard_address=None, worker_dashboard_address=None,
                                     scheduler_kwargs={'dashboard_address': '127.0.0.1:0'},
                                     silence_logs=logging.ERROR, local_directory=scratch,
                                     **where)
        except Exception as exc:             # no free port, no processes, ...
            shutil.rmtree(scratch, ignore_errors=True)
            raise EngineError(f'the local cluster did not start ({_first_line(exc)}): allowed '
                              'a machine where Dask can start worker processes on 127.0.0.1') \
                from None
        client = Client(local, set_as_default=False)
    try:
        yield client
    finally:
        client.close()
        if local is not None:
            local.close()
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)


def probe_scheduler(address, timeout=None):
    """Refuse (EngineError) an address where no Dask scheduler answers Dask's handshake within
    `timeout` (default CONNECT_TIMEOUT): nothing listening, a port that accepts and never
    answers (distributed waits for the handshake without a limit), another protocol (an HTTP
    server). One bounded connection, closed again."""
    from distributed.comm import connect  # lazy: distributed 350 ms, only when bags are analysed
    timeout = CONNECT_TIMEOUT if timeout is None else timeout

    async def handshake():
        comm = await connect(address, timeout=timeout)
        await comm.close()
    try:                             # (connect's own limit first: nothing listening)
        asyncio.run(asyncio.wait_for(handshake(), timeout + HANDSHAKE_GRACE))
    except (asyncio.TimeoutError, TimeoutError):
        raise EngineError(f'--scheduler = {address}: no Dask scheduler answered within '
                          f'{timeout + HANDSHAKE_GRACE:.0f} s (something there accepts the '
                          'connection and says nothing): allowed the address of a running '
                          'Dask scheduler, e.g. tcp://host:8786') from None
    except OSError as exc:           # refused, reset, closed (CommClosedError), timed out
        raise EngineError(f'--scheduler = {address}: cannot connect ({_first_line(exc)}): '
                          'allowed the address of a running Dask scheduler, e.g. '
                          'tcp://host:8786') from None
    except Exception as exc:         # its answer is not Dask's protocol (an HTTP server)
        raise EngineError(f'--scheduler = {address}: what answers there is not a Dask '
                          f'scheduler (its reply does not decode: {type(exc).__name__}): '
                          'allowed the address of a running Dask scheduler, e.g. '
                          'tcp://host:8786') from None


SCRATCH_PREFIX = 'planter-dask-'


def scratch_directory():
    """A new directory for the local cluster's scratch space (Dask's lock files and spill):
    removed when the cluster goes, not left in the temporary directory. One a killed run left
    (its process is gone) is removed here."""
    base = tempfile.gettempdir()
    for entry in os.scandir(base):
        owner = entry.name[len(SCRATCH_PREFIX):].partition('-')[0]
        if entry.name.startswith(SCRATCH_PREFIX) and owner.isdigit() and entry.is_dir() \
                and not _alive(int(owner)):
            shutil.rmtree(entry.path, ignore_errors=True)
    return tempfile.mkdtemp(prefix=f'{SCRATCH_PREFIX}{os.getpid()}-', dir=base)


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:                  # someone else's process
        return True
    return True


def worker_count(client):
    return len(client.scheduler_info(n_workers=-1)['workers'])


def check_workers(client, warm_up, expected, where):
    """Run `warm_up()` on every worker and refuse (EngineError) a worker whose answer is not
    `expected` (the model version) or that cannot run it at all."""
    try:
        answers = client.run(warm_up)
    except Exception as exc:              # ModuleNotFoundError on the worker, lost worker, ...
        raise EngineError(f'{where}: a worker cannot run planter_ros ({_first_line(exc)}): '
                          'allowed workers with the same planter_ros installed') from None
    wrong = {worker: got for worker, got in answers.items() if got != expected}
    if wrong:
        worker, got = sorted(wrong.items())[0]
        raise EngineError(f'{where}: worker {worker} runs planter_ros model version {got}, '
                          f'this command {expected}: allowed workers with the same planter_ros')
    return len(answers)


def completed(client, fn, arguments, **kwargs):
    """Run fn(*args, **kwargs) for every tuple in `arguments` on the cluster; yield (position
    in `arguments`, result, None) or (position, None, exception) as tasks complete. Results
    are gathered in batches (one round trip for all that completed meanwhile) and released."""
    from distributed import as_completed  # lazy: 350 ms, only when bags are analysed
    if not arguments:
        return
    futures = client.map(fn, *zip(*arguments), pure=False, **kwargs)
    position = {future.key: i for i, future in enumerate(futures)}
    pending = as_completed(futures, loop=client.loop)
    try:
        for batch in pending.batches():
            done = [f for f in batch if f.status == 'finished']
            results = client.gather(done) if done else []
            for future, result in zip(done, results):
                yield position[future.key], result, None
            for future in batch:
                if future.status != 'finished':
                    try:
                        error = future.exception()
                    except BaseException as exc:      # a cancelled future raises its reason
                        error = exc
                    yield position[future.key], None, error
                future.release()          # the worker may drop the result now
                futures[position[future.key]] = None
    finally:
        client.cancel([f for f in futures if f is not None and not f.done()])


def _first_line(exc):
    text = str(exc).strip().splitlines()
    return f'{type(exc).__name__}: {text[0]}' if text else type(exc).__name__
