"""`planter simulate`'s engine: a season of simulated bags written on Dask (a local cluster or
an existing one), with progress; and the check of where they go."""

import time
from pathlib import Path

from planter_ros.output_files import OutputError, check_directory

from .engine import check_workers, cluster, completed
from .progress import Progress
from .task import model_version, warm_up

__all__ = ['check_path', 'simulate_season']


def check_path(path, names):
    """Refuse (OutputError) a PATH the bags cannot be written to: not a directory, not
    writable, a parent missing, or one of the bags already there (never overwritten)."""
    path = Path(path)
    if path.exists() or path.is_symlink():
        if not path.is_dir():
            raise OutputError(f'PATH = {path} exists and is not a directory: allowed a '
                              'directory for the bags')
        check_directory(path, 'PATH')
        taken = [name for name in names if (path / name).exists()]
        if taken:
            raise OutputError(f'PATH = {path} already holds {taken[0]}'
                              f'{f" and {len(taken) - 1} more" if len(taken) > 1 else ""}: '
                              'allowed another PATH or --seed (a recording is never '
                              'overwritten)')
    else:
        check_directory(path.parent if str(path.parent) else Path('.'), 'PATH', path)
    return path



def simulate_season(path: Path, names: list[str], seed: int, duration: float, rows: int,
                    workers_wanted: int | None, scheduler: str | None, scene: str | None = None):
    """Write the bags `names` under `path`: (report, the runs written, [(name, error)]), each
    of a `rows`-row machine or of the machine of the scene file `scene` (checked by the
    caller). EngineError when the cluster cannot be had."""
    from planter_ros.sim.season import bag_name, simulate_bag
    version = model_version()
    where = scheduler or 'the local cluster'
    written, errors = [], []
    with cluster(workers_wanted, scheduler) as client:
        workers = check_workers(client, warm_up, version, where)
        path.mkdir(exist_ok=True)
        progress = Progress(len(names), what='bags', label='planter simulate')
        started = time.monotonic()
        try:
            arguments = [(str(path.resolve() / name), seed, k, duration, rows, scene)
                         for k, name in enumerate(names)]
            for i, result, error in completed(client, simulate_bag, arguments):
                if error is None:
                    written.append(result)
                else:
                    errors.append((names[i], error))
                progress.update(len(written) + len(errors),
                                sum(r['duration'] for r in written), len(errors))
        finally:
            progress.close()
        seconds = time.monotonic() - started
    written.sort(key=lambda r: r['run'])
    run_seconds = sum(r['duration'] for r in written)
    size = sum((path / bag_name(seed, r['run'])).stat().st_size for r in written)
    report = {'path': str(path), 'bags': len(written), 'failed': len(errors),
              'seed': seed, 'duration': duration, 'rows': rows, 'scene': scene,
              'workers': workers, 'seconds': seconds, 'bag_seconds': run_seconds,
              'times_real_time': run_seconds / seconds if seconds > 0 else None,
              'bytes': size, 'messages': sum(r['messages'] for r in written),
              'plants': sum(r['plants'] for r in written)}
    return report, written, errors
