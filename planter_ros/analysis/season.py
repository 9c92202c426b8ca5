"""A season's analysis under --out: the tables, the re-run rule and the incremental writes.

Layout of the output directory (each table in a folder of its own):

    bags/bags.parquet            one row per bag (analysis.tables), replaced atomically
    plants/part-<run>-<n>.parquet  the plants dataset: each write adds one part holding the
                                 plants of the bags completed since the previous write
    as_planted.zip, TASKDATA.zip the season for farm software (analysis.exports)
    report.html                  the season report (analysis.report)

Bags are keyed by their path relative to the analysed root (`bag_keys`: the directory given,
or the common directory of the paths given), so a season moved elsewhere still joins and is
not analysed again.

A run holds a lock on the directory itself (flock on its descriptor) while it writes, so a
second run on it is refused; the kernel drops it however the run ends, and no lock file is left
behind (the `.planter-analyze.lock` of earlier versions is removed).

The bags table is the truth: a bag's plants are the rows of its
`plants_file` whose `bag` is it. A bag is analysed again unless the table holds it with the
same key (BagKey: key, size, modification time, model version, options = the settings given and
the fallback scene's design) or `force`. Before the work starts, the rows of every bag to be
analysed again are removed from both tables, and so are rows no bag of the table claims (an
interrupted write), so the tables never hold a bag twice. Results are written as they complete,
every FLUSH_SECONDS at least (a larger table is rewritten less often), so an interrupted run
keeps what it finished.
"""

from dataclasses import dataclass, field
import fcntl
import hashlib
import json
import os
from pathlib import Path
import time

from planter_ros.design import to_json
from planter_ros.output_files import OutputError, atomic_output

from . import tables
from .bags import identity

BAGS_DIR = 'bags'
BAGS_FILE = f'{BAGS_DIR}/bags.parquet'
PLANTS_DIR = 'plants'
LOCK_FILE = '.planter-analyze.lock'            # earlier versions' lock: removed when seen
REPORT_FILE = 'report.html'
LEGACY_BAGS_FILE = 'bags.parquet'     # where an older planter analyze put the bags table
# the season's exports for farm software (written by analysis.exports)
SHAPEFILE = 'as_planted.zip'
ISOXML = 'TASKDATA.zip'
EXPORTS = (SHAPEFILE, ISOXML)
OWNED = (BAGS_DIR, PLANTS_DIR, LOCK_FILE, REPORT_FILE, LEGACY_BAGS_FILE) + EXPORTS
FLUSH_SECONDS = 5.0          # s between two writes of the tables, at least
FLUSH_BAGS = 2000            # bags completed that force a write
# status of a bag row: replayed (with or without warnings), refused by replay, a model error
ANALYSED = ('ok', 'warnings')
STATUSES = ('ok', 'warnings', 'failed', 'error')


@dataclass(frozen=True)
class BagKey:
    """What a bag's analysis depends on: a re-run skips a bag whose key is unchanged. `bag`:
    the path relative to the analysed root (the tables' key); `path`: where it is read."""

    bag: str
    file_size: int
    file_mtime_ns: int
    model_version: str
    options: str
    path: str = ''

    def matches(self, row):
        return (row.get('file_size') == self.file_size
                and row.get('file_mtime_ns') == self.file_mtime_ns
                and row.get('model_version') == self.model_version
                and row.get('options') == self.options)


def analysed_root(paths):
    """The directory the bags' keys are relative to: the directory given, a file's own
    directory, the common directory of several."""
    roots = []
    for given in paths:
        path = Path(given).resolve()
        roots.append(str(path if path.is_dir() else path.parent))
    return Path(os.path.commonpath(roots)) if roots else Path('.').resolve()


def bag_keys(bags, root):
    """{bag path: its key}: the path relative to `root`, '/'-separated."""
    root = Path(root)
    return {str(bag): Path(os.path.relpath(bag, root)).as_posix() for bag in bags}


def options_key(overrides, design):
    """The analysis options as canonical JSON: the settings given (not the defaults or what a
    bag recorded, which the bag's own identity covers) and the fallback design's hash."""
    given = {k: v for k, v in sorted((overrides or {}).items()) if v is not None}
    scene = None if design is None else hashlib.sha256(
        to_json(design).encode()).hexdigest()[:16]
    return json.dumps({'settings': given, 'scene_design': scene}, sort_keys=True)


@dataclass
class Report:
    """What a run did (SI)."""

    out: str
    found: int = 0
    skipped: int = 0
    analysed: int = 0                # bags replayed (status ok or warnings)
    warnings: int = 0                # of those, with warnings
    failed: int = 0                  # status failed (unreadable) or error
    plants: int = 0
    data_seconds: float = 0.0        # bag time covered by the bags analysed
    seconds: float = 0.0             # wall time from the first task to the last result
    workers: int = 0
    not_done: list = field(default_factory=list)    # (bag, reason): the engine lost them
    failures: list = field(default_factory=list)    # (bag, status, reason)

    def as_json(self):
        done = self.analysed + self.failed
        return {'out': self.out, 'bags_found': self.found, 'skipped': self.skipped,
                'analysed': self.analysed, 'with_warnings': self.warnings,
                'failed': self.failed, 'not_analysed': len(self.not_done),
                'plants': self.plants, 'bag_seconds': self.data_seconds,
                'seconds': self.seconds, 'workers': self.workers,
                'bags_per_second': done / self.seconds if self.seconds > 0 else None,
                'times_real_time': self.data_seconds / self.seconds if self.seconds > 0
                else None,
                'failures': [{'bag': b, 'status': s, 'reason': r} for b, s, r in self.failures],
                'lost': [{'bag': b, 'reason': r} for b, r in self.not_done],
                'tables': {'bags': str(Path(self.out) / BAGS_DIR),
                           'plants': str(Path(self.out) / PLANTS_DIR)}}


def check_out(path, option='--out'):
    """Refuse (OutputError) an output directory the tables cannot go to: a path that is not a
    directory, a directory that is not writable or that holds other files and no tables of an
    earlier run, a new one whose parent is missing or read-only. Returns a Path."""
    from planter_ros.output_files import check_directory
    path = Path(path)
    if path.exists() or path.is_symlink():
        if not path.is_dir():
            raise OutputError(f'{option} = {path} exists and is not a directory: allowed a new '
                              'or an empty directory, or the output of an earlier planter analyze')
        names = {entry.name for entry in os.scandir(path)}
        if names and not names & set(OWNED):
            raise OutputError(f'{option} = {path} holds other files: allowed a new or an empty '
                              'directory, or the output of an earlier planter analyze')
        check_directory(path, option)
        if (path / BAGS_FILE).exists():
            read_bags(path / BAGS_FILE, option)
    else:
        check_directory(path.parent if str(path.parent) else Path('.'), option, path)
    return path


def read_bags(file, option='--out'):
    """The rows of a bags table, or OutputError (a file this command cannot read)."""
    import pyarrow.parquet as pq
    try:
        rows = pq.read_table(file).to_pylist()
    except Exception as exc:         # pyarrow's ArrowInvalid, OSError, ...
        raise OutputError(f'{option}: {file} is not a readable bags table '
                          f'({type(exc).__name__}): allowed the output of planter analyze') \
            from None
    if rows and not {'bag', 'status', 'model_version'} <= set(rows[0]):
        raise OutputError(f'{option}: {file} is not a bags table of planter analyze: allowed '
                          'the output of planter analyze')
    return rows


class Season:
    """The tables under one output directory, held (locked) while a run writes them."""

    def __init__(self, out, root=None):
        self.out = Path(out)
        self.root = root
        self.created = not self.out.exists()
        self.out.mkdir(exist_ok=True)
        self._lock = os.open(self.out, os.O_RDONLY | os.O_DIRECTORY)
        try:
            fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self._lock)
            raise OutputError(f'--out = {out} is being written by another planter analyze: '
                              'allowed an output directory no other run is writing') from None
        (self.out / LOCK_FILE).unlink(missing_ok=True)
        self.plants_dir = self.out / PLANTS_DIR
        self.plants_dir.mkdir(exist_ok=True)
        (self.out / BAGS_DIR).mkdir(exist_ok=True)
        legacy = self.out / LEGACY_BAGS_FILE      # absolute keys: every bag is analysed again
        if legacy.is_file():
            legacy.unlink()
            for part in self.plants_dir.glob('part-*.parquet'):
                part.unlink()
        file = self.out / BAGS_FILE
        self.rows = {row['bag']: row for row in read_bags(file)} if file.exists() else {}
        self._run = time.strftime('%Y%m%dT%H%M%S') + f'-{os.getpid()}'
        self._parts = 0
        for stale in self.plants_dir.glob('.*.tmp.parquet'):   # a killed run's temporary file
            stale.unlink()

    def close(self):
        """Release the directory; one this run made and left empty (refused before any work)
        is removed again."""
        if self._lock is None:
            return
        os.close(self._lock)
        self._lock = None
        if self.created and not self.rows:
            try:
                self.plants_dir.rmdir()
                (self.out / BAGS_DIR).rmdir()
                self.out.rmdir()
            except OSError:          # something was put there meanwhile: leave it
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def plan(self, bags, version, options, force=False):
        """(keys of the bags to analyse, number skipped): a bag is skipped when its row has
        the same key and its plants part is there. `bags`: {path: key} (bag_keys)."""
        todo, skipped = [], 0
        for bag, name in bags.items():
            size, mtime = identity(bag)
            key = BagKey(name, size, mtime, version, options, str(bag))
            row = self.rows.get(key.bag)
            part = row and row.get('plants_file')
            if (not force and row is not None and key.matches(row)
                    and (not part or (self.plants_dir / part).is_file())):
                skipped += 1
            else:
                todo.append(key)
        return todo, skipped

    def clear(self, keys):
        """Remove the rows of the bags `keys` name from both tables, and plants rows no bag
        claims; write what changed."""
        import pyarrow.compute as pc
        import pyarrow.parquet as pq
        dropped = [k.bag for k in keys if self.rows.pop(k.bag, None) is not None]
        claimed = {}
        for bag, row in self.rows.items():
            if row.get('plants_file'):
                claimed.setdefault(row['plants_file'], set()).add(bag)
        for part in sorted(self.plants_dir.glob('part-*.parquet')):
            held = set(pq.read_table(part, columns=['bag']).column('bag').unique().to_pylist())
            keep = held & claimed.get(part.name, set())
            if keep == held:
                continue
            if not keep:
                part.unlink()
                continue
            table = pq.read_table(part)
            table = table.filter(pc.is_in(table['bag'], value_set=tables.column(sorted(keep))))
            with atomic_output(part) as tmp:
                pq.write_table(table, tmp)
        if dropped:
            self.write_bags()

    def add(self, finished):
        """Write the results `finished` ([(bags row, plants table or None)]): one new plants
        part, then the bags table (so a row never names a part that is not there)."""
        import pyarrow.parquet as pq
        parts = [table for _, table in finished if table is not None]
        name = None
        if parts:
            self._parts += 1
            name = f'part-{self._run}-{self._parts:05d}.parquet'
            with atomic_output(self.plants_dir / name) as tmp:
                pq.write_table(tables.concat(parts, tables.PLANTS), tmp)
        for row, table in finished:
            row['plants_file'] = name if table is not None else None
            self.rows[row['bag']] = row
        self.write_bags()

    def write_bags(self):
        import pyarrow.parquet as pq
        table = tables.table_of([self.rows[bag] for bag in sorted(self.rows)], tables.BAGS,
                                self.root)
        with atomic_output(self.out / BAGS_FILE) as tmp:
            pq.write_table(table, tmp)


BATCH_MAX = 16       # bags per task at most (a task costs the scheduler and client 2-5 ms)
BATCH_SHARE = 4      # a task takes at most 1/(BATCH_SHARE × workers) of the bags left


def batches(count, workers):
    """The bags 0..count-1 in tasks, in order: guided self-scheduling, each task a share of
    what is left (at most BATCH_MAX bags, at least one), so the first tasks carry many bags
    (the scheduler's cost spread over them) and the last ones few (no worker waits long for
    another's last task)."""
    out, start = [], 0
    while start < count:
        size = max(1, min(BATCH_MAX, (count - start) // (BATCH_SHARE * max(1, workers))))
        out.append(range(start, start + size))
        start += size
    return out


def run(season, client, keys, overrides, design, progress=None):
    """Analyse the bags `keys` on `client`'s cluster into `season`: a Report (without the
    counts of bags found and skipped, which the caller knows). The bags go in tasks of several
    (`batches`); a task the engine lost is tried again bag by bag, so only a bag no worker
    can run is lost."""
    from .engine import completed, worker_count
    from .task import analyze_bags
    tables.load_pyarrow()                    # once per process, before the clock starts
    report = Report(out=str(season.out))
    if design is not None:                   # one copy per worker, not one per task
        design = client.scatter(design, broadcast=True)
    arguments = [(k.path or k.bag, k.bag, (k.file_size, k.file_mtime_ns), k.options)
                 for k in keys]
    options = {'overrides': overrides, 'design': design,
               'version': keys[0].model_version if keys else None}
    pending, last_write, write_cost = [], time.monotonic(), 0.0
    started = time.monotonic()
    done = 0

    def write():
        nonlocal pending, last_write, write_cost
        t0 = time.monotonic()
        season.add(pending)
        pending = []
        last_write = time.monotonic()
        write_cost = last_write - t0

    def tasks(groups, retry):
        """Run the tasks `groups` (bag positions); a lost task of several bags goes to
        `retry`, a lost bag to the report."""
        nonlocal done
        work = [([arguments[i] for i in group],) for group in groups]
        for g, results, error in completed(client, analyze_bags, work, **options):
            if error is not None:
                if len(groups[g]) > 1 and retry is not None:
                    retry.extend(groups[g])
                    continue
                results = [None] * len(groups[g])
            for i, result in zip(groups[g], results):
                done += 1
                if result is None:
                    report.not_done.append((keys[i].bag, _first_line(error)))
                    continue
                row, table = result
                pending.append((row, table))
                if row['status'] in ANALYSED:
                    report.analysed += 1
                    report.warnings += row['status'] == 'warnings'
                    report.data_seconds += row.get('duration') or 0.0
                    report.plants += 0 if table is None else table.num_rows
                else:
                    report.failed += 1
                    report.failures.append((row['bag'], row['status'], row['reason']))
            if progress is not None:
                progress.update(done, report.data_seconds,
                                report.failed + len(report.not_done))
            if pending and (len(pending) >= FLUSH_BAGS or time.monotonic() - last_write >=
                            max(FLUSH_SECONDS, 20.0 * write_cost)):
                write()

    try:
        retry = []
        tasks(batches(len(keys), worker_count(client) if keys else 1), retry)
        if retry:
            tasks([[i] for i in sorted(retry)], None)
        report.seconds = time.monotonic() - started
    finally:
        if pending:
            write()                          # an interrupted run keeps what it finished
        if progress is not None:
            progress.close()
    return report


def _first_line(exc):
    text = str(exc).strip().splitlines()
    return f'{type(exc).__name__}: {text[0]}' if text else type(exc).__name__


SHOWN_FAILURES = 10      # failed bags listed for people (all are in the bags table)


def format_report(report: Report) -> str:
    """The run's report for people."""
    data = report.as_json()
    lines = [f'{report.found} bags found: {report.analysed} analysed ({report.warnings} with '
             f'warnings), {report.failed} failed, {report.skipped} skipped (analysed before), '
             f'{len(report.not_done)} lost; {report.plants} plants']
    if report.seconds > 0:
        lines.append(f'{report.seconds:.1f} s on {report.workers} worker(s): '
                     f'{data["bags_per_second"]:.3g} bags/s, '
                     f'{data["times_real_time"]:.0f}× real time')
    lines.append(f'tables: {data["tables"]["bags"]}, {data["tables"]["plants"]}/')
    for bag, status, reason in report.failures[:SHOWN_FAILURES]:
        lines.append(f'{status}: {bag}: {reason}')
    if len(report.failures) > SHOWN_FAILURES:
        lines.append(f'... and {len(report.failures) - SHOWN_FAILURES} more (column `status` '
                     'of the bags table)')
    return '\n'.join(lines)
