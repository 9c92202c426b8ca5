"""What a worker of `planter analyze` runs: one bag replayed into its rows of the two tables.

The replay code is imported with this module, once per worker process (the warm-up every worker
gets before the first bag). The bag is read from its path (shared storage): only the path and
the settings travel through the scheduler, and back only the bag's row and its plants table.
"""

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
import time

# what a replay imports only when it first reads a bag: loaded with this module, on every
# worker before its first bag (warm_up), so no bag pays for it
import mcap.records  # noqa: F401
import zstandard  # noqa: F401

from planter_ros.errors import PlanterError
from planter_ros.recording import indexed  # noqa: F401
from planter_ros.recording.errors import RecordingError
from planter_ros.recording.replay import replay

from .model_code import closure_version
from .tables import flatten, load_pyarrow, plants_arrays_table, with_heading


class WorkerMismatch(PlanterError, RuntimeError):
    """The worker runs another model version than the client asked for (one line)."""


@lru_cache(maxsize=1)
def model_version():
    """A short hash of the replay model: the code of every planter_ros module this task imports,
    directly or through others (replay, the tables; not their docstrings or comments), and the
    versions of the libraries they import (analysis.model_code)."""
    return closure_version([__name__], Path(__file__).resolve().parents[2])


def warm_up():
    """Run on every worker before the first bag: loads what a replay loads only when first
    needed (pyarrow and the pandas it loads with its first array: a second or more; the indexed
    reader and zstd come with this module), so no bag pays for it, and returns the model
    version the worker runs."""
    load_pyarrow()
    return model_version()


@dataclass(frozen=True)
class BagTask:
    """One bag for a worker: where it is read (`path`), the name it goes by (`key`: its path
    relative to the analysed root), its `identity` (size, modification time ns, content id:
    season.BagKey; without the id, the path stands for it) and the `options` key it is
    analysed with (season.options_key)."""

    path: str
    key: str
    identity: tuple[int, int] | tuple[int, int, str]
    options: str


def analyze_bag(bag, overrides, design, version):
    """Replay `bag` (a BagTask) as `planter replay` would with the setting `overrides` (and the
    fallback `design`, or None): (its `bags` row, its `plants` table or None), both naming it
    `bag.key` and keyed by its content id. A bag replay cannot read is a row with status
    'failed' and its one-line reason; any other exception of the model on this bag is status
    'error'. `bag.identity`, `bag.options` and `version` are the re-run key the client decided
    on."""
    path, key, identity, options = bag.path, bag.key, bag.identity, bag.options
    started, cpu = time.perf_counter(), time.process_time()
    if model_version() != version:
        raise WorkerMismatch(f'worker runs planter_ros model version {model_version()}, the '
                             f'analysis asked for {version}')
    bag_id = identity[2] if len(identity) > 2 else f'path:{path}'
    row = {'bag': key, 'bag_id': bag_id, 'status': None, 'reason': None,
           'file_size': identity[0], 'file_mtime_ns': identity[1], 'model_version': version,
           'options': options, 'analysed_at': time.time(), 'analysis_seconds': None,
           'analysis_cpu_seconds': None, 'plants_file': None, 'path': str(path)}
    table = None
    try:
        result = replay(str(path), overrides, fallback_design=design)
    except RecordingError as exc:
        row.update(status='failed', reason=_one_line(str(exc)))
    except Exception as exc:        # one bag's bug in the model must not stop the season
        row.update(status='error', reason=_one_line(f'{type(exc).__name__}: {exc}'))
    else:
        data = result.as_json(plants=False)
        data['path'] = data.pop('bag')          # where it was read; `bag` is the key
        row.update(flatten(data))
        row['status'] = 'warnings' if data['warnings'] else 'ok'
        if len(result.plants):
            table = with_heading(plants_arrays_table(key, result.plants,
                                                     [(r.index, r.label) for r in result.rows],
                                                     bag_id),
                                 result.placement.heading)
    row['analysis_seconds'] = time.perf_counter() - started
    # CPU time apart from wall time: on shared cores the difference is time spent waiting
    row['analysis_cpu_seconds'] = time.process_time() - cpu
    return row, table


def _one_line(text):
    lines = text.strip().splitlines()
    return lines[0] if lines else text


def analyze_bags(bags, overrides, design, version):
    """`analyze_bag` of each BagTask in `bags`, in order: one task of several bags (the
    scheduler's and client's cost per task shared among them)."""
    return [analyze_bag(bag, overrides, design, version) for bag in bags]
