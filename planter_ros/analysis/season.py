"""A season's analysis under --out: the tables, the re-run rule and the incremental writes.

Layout of the output directory (each table in a folder of its own):

    bags/bags.parquet            one row per bag (analysis.tables), replaced atomically
    plants/part-<run>-<n>.parquet  the plants dataset: each write adds one part holding the
                                 plants of the bags completed since the previous write
    as_planted.zip, TASKDATA.zip the season for farm software (export.season)
    report.html                  the season report (analysis.report)
    .planter-analyze.json        what this command wrote here (OUTPUT_RECORD), so that a later
                                 run never replaces a file it did not write

**A bag is its content.** Both tables are keyed by `bag_id`, the bag's content fingerprint
(bags.fingerprint: SHA-256 of its bytes), so the same recording is one bag however it was
found: analysed from another root, in a moved or renamed folder, through a symbolic link, or a
copy of it found beside it (counted once, named in the report). A fingerprint is taken once:
a bag found again at the path, size and modification time its row records keeps its id
without being read. `bag` is the bag's name for people (the Shapefile's `bag`, the ISOXML
task, the report's fields): its path relative to the analysed root (the directory given, or
the common directory of the paths given), made unique among the table's bags by as many of its
parent folders as it takes; a later run that finds it again renames it to its path from that
run's root, unless that run looked only into a folder below (a shorter name, less context: the
name is kept). A rename rewrites the bag's rows of the plants parts.

A run holds a lock on the directory itself (flock on its descriptor) while it writes, so a
second run on it is refused; the kernel drops it however the run ends, and no lock file is left
behind (the `.planter-analyze.lock` of earlier versions is removed).

The bags table is the truth: a bag's plants are the rows of its `plants_file` whose `bag_id`
is it. A bag is analysed again unless the table holds it (its `bag_id`) with the same model
version and options (the settings given and the fallback scene's design), or `force`. Before
the work starts, the rows of every bag to be analysed again are removed from both tables, and
so are rows no bag of the table claims (an interrupted write), so the tables never hold a bag
twice. Tables of earlier versions, keyed by the path alone, are analysed again whole. Results
are written as they complete, every FLUSH_SECONDS at least (a larger table is rewritten less
often), so an interrupted run keeps what it finished.
"""

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
import fcntl
import hashlib
import itertools
import json
import os
from pathlib import Path
import time
from typing import Any

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from planter_ros.design import to_json
from planter_ros.output_files import OutputError, atomic_output, check_directory

from . import tables
from .bags import fingerprint, identity
from .engine import completed, worker_count
from .task import BagTask, analyze_bags

BAGS_DIR = 'bags'
BAGS_FILE = f'{BAGS_DIR}/bags.parquet'
PLANTS_DIR = 'plants'
LOCK_FILE = '.planter-analyze.lock'            # earlier versions' lock: removed when seen
REPORT_FILE = 'report.html'
LEGACY_BAGS_FILE = 'bags.parquet'     # where an older planter analyze put the bags table
# the season's exports for farm software (written by export.season)
SHAPEFILE = 'as_planted.zip'
ISOXML = 'TASKDATA.zip'
EXPORTS = (SHAPEFILE, ISOXML)
OUTPUT_RECORD = '.planter-analyze.json'   # the files this command wrote here (check_out)
OWNED = (BAGS_DIR, PLANTS_DIR, LOCK_FILE, REPORT_FILE, LEGACY_BAGS_FILE, OUTPUT_RECORD) + EXPORTS
FLUSH_SECONDS = 5.0          # s between two writes of the tables, at least
FLUSH_BAGS = 2000            # bags completed that force a write
_RUNS = itertools.count(1)   # Season objects of this process (their plants parts' names)
# status of a bag row: replayed (with or without warnings), refused by replay, a model error
ANALYSED = ('ok', 'warnings')
STATUSES = ('ok', 'warnings', 'failed', 'error')


@dataclass(frozen=True)
class BagKey:
    """What a bag's analysis depends on: a re-run skips a bag whose key is unchanged. `bag_id`:
    its content (the tables' key); `bag`: its name for people; `path`: where it is read."""

    bag: str
    file_size: int
    file_mtime_ns: int
    model_version: str
    options: str
    path: str = ''
    bag_id: str = ''

    def matches(self, row):
        return (row.get('bag_id') == self.bag_id
                and row.get('model_version') == self.model_version
                and row.get('options') == self.options)


def analysed_root(paths):
    """The directory the bags' names are relative to: the directory given, a file's own
    directory, the common directory of several."""
    roots = []
    for given in paths:
        path = Path(given).resolve()
        roots.append(str(path if path.is_dir() else path.parent))
    return Path(os.path.commonpath(roots)) if roots else Path('.').resolve()


def bag_keys(bags, root):
    """{bag path: its name}: the path relative to `root`, '/'-separated."""
    root = Path(root)
    return {str(bag): Path(os.path.relpath(bag, root)).as_posix() for bag in bags}


def unique_name(name, path, taken):
    """`name`, or the shortest longer tail of the bag's `path` that no other bag has in
    `taken` ({name: bag_id}); the path itself with its id when even that is taken."""
    if name not in taken:
        return name
    parts = Path(path).parts
    for k in range(len(Path(name).parts) + 1, len(parts) + 1):
        longer = Path(*parts[-k:]).as_posix()
        if longer not in taken:
            return longer
    return f'{Path(path).as_posix()} #{len(taken)}'


FINGERPRINT_THREADS = 4          # bags read at once for their fingerprints (hashlib frees the GIL)


def fingerprints(paths, known):
    """{path: (bag_id, size, mtime ns)} of bags at `paths`: the id of `known` ({(path, size,
    mtime): bag_id}, what the table recorded) when the bag is unchanged there, else its
    fingerprint (read in threads). A bag that cannot be read gets an id of its own path (its
    analysis will say why)."""
    out, todo = {}, []
    for path in paths:
        size, mtime = identity(path)
        bag_id = known.get((str(path), size, mtime))
        out[path] = (bag_id, size, mtime)
        if bag_id is None:
            todo.append(path)

    def read(path):
        try:
            return fingerprint(path)
        except OSError as exc:
            return f'unreadable:{Path(path).as_posix()}:{exc.errno}'
    with ThreadPoolExecutor(max_workers=FINGERPRINT_THREADS) as pool:
        for path, bag_id in zip(todo, pool.map(read, todo)):
            out[path] = (bag_id, *out[path][1:])
    return out


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
    copies: list = field(default_factory=list)      # (path, path of the same bag found first)

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
                'copies': [{'path': p, 'same_as': q} for p, q in self.copies],
                'lost': [{'bag': b, 'reason': r} for b, r in self.not_done],
                'tables': {'bags': str(Path(self.out) / BAGS_DIR),
                           'plants': str(Path(self.out) / PLANTS_DIR)}}


def check_out(path, option='--out'):
    """Refuse (OutputError) an output directory the tables cannot go to: a path that is not a
    directory, a directory that is not writable, one that holds files this command did not
    write (a directory that is neither new nor empty must be the output of an earlier planter
    analyze: its OUTPUT_RECORD, or an earlier version's bags table; and a file there that the
    record does not know as written, such as a user's own report.html, is never replaced), a
    new one whose parent is missing or read-only. Returns a Path."""
    path = Path(path)
    if path.exists() or path.is_symlink():
        if not path.is_dir():
            raise OutputError(f'{option} = {path} exists and is not a directory: allowed a new '
                              'or an empty directory, or the output of an earlier planter analyze')
        names = {entry.name for entry in os.scandir(path)}
        if names:
            record = read_output_record(path, option)
            legacy = record is None and (path / BAGS_FILE).is_file()
            if record is None and not legacy:
                raise OutputError(f'{option} = {path} holds other files ({sorted(names)[0]}): '
                                  'allowed a new or an empty directory, or the output of an '
                                  'earlier planter analyze')
            if (path / BAGS_FILE).exists():
                read_bags(path / BAGS_FILE, option)
            # (an earlier version's output, which kept no record: its files are its own)
            foreign = [] if legacy else [
                name for name in (REPORT_FILE, LEGACY_BAGS_FILE) + EXPORTS
                if (path / name).exists() and not _ours(path, name, record)]
            if foreign:
                raise OutputError(f'{option} = {path} holds {foreign[0]}, which planter analyze '
                                  'did not write (or was changed since): allowed an output '
                                  'directory whose files are its own (move that file away)')
        check_directory(path, option)
    else:
        check_directory(path.parent if str(path.parent) else Path('.'), option, path)
    return path


def read_output_record(out, option='--out'):
    """The OUTPUT_RECORD of an output directory ({'written': {name: sha256}}), None if it has
    none; OutputError if it is there but not one."""
    file = Path(out) / OUTPUT_RECORD
    if not file.exists():
        return None
    try:
        record = json.loads(file.read_text(encoding='utf-8'))
        if not isinstance(record.get('written'), dict):
            raise ValueError('no written files')
        return record
    except (OSError, ValueError, AttributeError) as exc:
        raise OutputError(f'{option}: {file} is not planter analyze\'s record of its files '
                          f'({type(exc).__name__}): allowed the output of planter analyze') \
            from None


def _file_digest(file):
    digest = hashlib.sha256()
    with open(file, 'rb') as f:
        while block := f.read(1 << 20):
            digest.update(block)
    return digest.hexdigest()


def _ours(out, name, record):
    """The file `name` under `out` is as this command wrote it (the record's digest)."""
    file = Path(out) / name
    return file.is_file() and record['written'].get(name) == _file_digest(file)


def written_after_the_tables(path, out):
    """The season output at `path` exists and was written after every table under `out`: a
    run stopped between its tables and its outputs leaves older ones, which are then written
    again; a re-run that changed no table keeps them."""
    try:
        made = Path(path).stat().st_mtime_ns
    except FileNotFoundError:
        return False
    out = Path(out)
    tables = [out / BAGS_FILE, *(out / PLANTS_DIR).glob('*.parquet')]
    return all(table.stat().st_mtime_ns <= made for table in tables if table.is_file())


def record_written(out, names):
    """Add the files `names` under `out` (written by this run, or an earlier version's that
    kept no record) to its OUTPUT_RECORD, with their digests."""
    out = Path(out)
    record = read_output_record(out) or {'what': 'files planter analyze wrote here (sha256); '
                                                 'a file not listed, or changed since, is '
                                                 'never replaced', 'written': {}}
    for name in names:
        if (out / name).is_file():
            record['written'][name] = _file_digest(out / name)
    with atomic_output(out / OUTPUT_RECORD) as tmp:
        tmp.write_text(json.dumps(record, indent=1, sort_keys=True) + '\n', encoding='utf-8')


def read_bags(file, option='--out'):
    """The rows of a bags table, or OutputError (a file this command cannot read)."""
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
        self._lock: int | None = os.open(self.out, os.O_RDONLY | os.O_DIRECTORY)
        try:
            fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self._lock)
            raise OutputError(f'--out = {out} is being written by another planter analyze: '
                              'allowed an output directory no other run is writing') from None
        (self.out / LOCK_FILE).unlink(missing_ok=True)
        if not (self.out / OUTPUT_RECORD).exists():      # the directory is this command's:
            # new, or an earlier version's output (check_out let it through): its files too
            record_written(self.out, EXPORTS + (REPORT_FILE,))
        self.plants_dir = self.out / PLANTS_DIR
        self.plants_dir.mkdir(exist_ok=True)
        (self.out / BAGS_DIR).mkdir(exist_ok=True)
        legacy = self.out / LEGACY_BAGS_FILE      # absolute keys: every bag is analysed again
        if legacy.is_file():
            legacy.unlink()
            for part in self.plants_dir.glob('part-*.parquet'):
                part.unlink()
        file = self.out / BAGS_FILE
        rows = read_bags(file) if file.exists() else []
        if any(not row.get('bag_id') for row in rows):   # keyed by the path alone: redone
            rows = []
            file.unlink()
            for part in self.plants_dir.glob('part-*.parquet'):
                part.unlink()
        self.rows = {row['bag_id']: row for row in rows}
        self.copies = []                     # (path, path of the same bag found first)
        self.renamed = {}                    # bag_id -> its new name (plan)
        self.moved = False                   # a bag skipped was found elsewhere (plan)
        self.superseded = []                 # names of bags whose file was rewritten (plan)
        # (the process's count of runs too: two runs of one process within a second, the
        # command called in-process, must not name a part alike and replace the other's)
        self._run = time.strftime('%Y%m%dT%H%M%S') + f'-{os.getpid()}-{next(_RUNS)}'
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
                (self.out / OUTPUT_RECORD).unlink(missing_ok=True)
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
        """(keys of the bags to analyse, number skipped). `bags`: {path: its name from the
        analysed root} (bag_keys). Each bag is its content: paths with the same content are
        one bag (the first; the others in `self.copies`); a bag the table holds with the same
        model version and options, its plants part there, is skipped; the names of the bags
        found are brought up to date (module doc; `self.renamed`, `apply_renames`)."""
        known = {(row.get('path'), row.get('file_size'), row.get('file_mtime_ns')): bag_id
                 for bag_id, row in self.rows.items()}
        ids = fingerprints(sorted(bags), known)
        found: dict[str, list[Path]] = {}
        for path in sorted(bags):
            found.setdefault(ids[path][0], []).append(path)
        first = {}
        for bag_id, paths in found.items():
            # the path the table knows the bag at, else the one its name names (a moved
            # folder), else the first: the others are copies
            row = self.rows.get(bag_id) or {}
            name = row.get('bag', '')
            path = next((p for p in paths if str(p) == row.get('path')), None) or next(
                (p for p in paths if name and (bags[p] == name or name.endswith('/' + bags[p])
                                               or bags[p].endswith('/' + name))), paths[0])
            first[bag_id] = path
            self.copies += [(str(p), str(path)) for p in paths if p != path]
        # a bag of the table whose file now holds another recording (rewritten in place, a
        # repaired copy) and that is not found elsewhere: the new content takes its place
        at = {str(path): bag_id for path in bags for bag_id in (ids[path][0],)}
        for bag_id, row in list(self.rows.items()):
            if bag_id not in found and at.get(row.get('path'), bag_id) != bag_id:
                del self.rows[bag_id]
                self.superseded.append(row['bag'])
        taken = {row['bag']: bag_id for bag_id, row in self.rows.items() if bag_id not in first}
        todo, skipped = [], 0
        for bag_id, path in first.items():
            _, size, mtime = ids[path]
            row = self.rows.get(bag_id)
            name = bags[path]
            if row is not None and row['bag'] != name and \
                    row['bag'].endswith('/' + name):   # seen from a folder below: keep
                name = row['bag']
            name = unique_name(name, path, taken)
            taken[name] = bag_id
            key = BagKey(name, size, mtime, version, options, str(path), bag_id)
            part = row and row.get('plants_file')
            if (not force and row is not None and key.matches(row)
                    and (not part or (self.plants_dir / part).is_file())):
                skipped += 1
                if row['bag'] != name:
                    self.renamed[bag_id] = name
                now = dict(bag=name, file_size=size, file_mtime_ns=mtime, path=str(path))
                if any(row.get(k) != v for k, v in now.items()):
                    row.update(now)
                    self.moved = True
            else:
                todo.append(key)
        return todo, skipped

    def apply_renames(self):
        """Write what `plan` found changed: the bags table (names, where each bag is), and the
        plants parts holding a renamed bag's rows (each part replaced whole), the rows of bags
        whose file now holds another recording. True if a bag was renamed or removed (the
        exports are written again)."""
        if self.superseded:
            self.clear([])                   # their plants go with them
            self.write_bags()
        if not self.renamed:
            if self.moved:
                self.write_bags()
            return bool(self.superseded)
        parts = {self.rows[bag_id].get('plants_file') for bag_id in self.renamed} - {None}
        ids = pa.array(sorted(self.renamed), type=pa.string())
        names = pa.array([self.renamed[i] for i in sorted(self.renamed)], type=pa.string())
        for part in sorted(parts):
            file = self.plants_dir / part
            if not file.is_file():
                continue
            table = pq.read_table(file)
            where = pc.index_in(table['bag_id'], value_set=ids)
            renamed = pc.if_else(pc.is_null(where), table['bag'], pc.take(names, where))
            table = table.set_column(table.schema.get_field_index('bag'), 'bag', renamed)
            with atomic_output(file) as tmp:
                pq.write_table(tables.with_units(table, tables.PLANTS), tmp)
        self.write_bags()
        return True

    def clear(self, keys):
        """Remove the rows of the bags `keys` name from both tables, and plants rows no bag
        claims; write what changed."""
        dropped = [k.bag_id for k in keys if self.rows.pop(k.bag_id, None) is not None]
        claimed: dict[str, set[str]] = {}
        for bag_id, row in self.rows.items():
            if row.get('plants_file'):
                claimed.setdefault(row['plants_file'], set()).add(bag_id)
        for part in sorted(self.plants_dir.glob('part-*.parquet')):
            held = set(pq.read_table(part, columns=['bag_id']).column('bag_id').unique()
                       .to_pylist())
            keep = held & claimed.get(part.name, set())
            if keep == held:
                continue
            if not keep:
                part.unlink()
                continue
            table = pq.read_table(part)
            table = table.filter(pc.is_in(table['bag_id'],
                                          value_set=tables.column(sorted(keep))))
            with atomic_output(part) as tmp:
                pq.write_table(table, tmp)
        if dropped:
            self.write_bags()

    def add(self, finished):
        """Write the results `finished` ([(bags row, plants table or None)]): one new plants
        part, then the bags table (so a row never names a part that is not there)."""
        parts = [table for _, table in finished if table is not None]
        name = None
        if parts:
            self._parts += 1
            name = f'part-{self._run}-{self._parts:05d}.parquet'
            with atomic_output(self.plants_dir / name) as tmp:
                pq.write_table(tables.concat(parts, tables.PLANTS), tmp)
        for row, table in finished:
            row['plants_file'] = name if table is not None else None
            self.rows[row['bag_id']] = row
        self.write_bags()

    def write_bags(self):
        table = tables.table_of(sorted(self.rows.values(), key=lambda row: row['bag']),
                                tables.BAGS, self.root)
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
    tables.load_pyarrow()                    # once per process, before the clock starts
    report = Report(out=str(season.out))
    if design is not None:                   # one copy per worker, not one per task
        design = client.scatter(design, broadcast=True)
    arguments = [BagTask(k.path or k.bag, k.bag, (k.file_size, k.file_mtime_ns, k.bag_id),
                         k.options) for k in keys]
    options = {'overrides': overrides, 'design': design,
               'version': keys[0].model_version if keys else None}
    # (a bag's row, its plants table or None) analysed and not yet written
    pending: list[tuple[dict[str, Any], pa.Table | None]] = []
    last_write, write_cost = time.monotonic(), 0.0
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
        retry: list[int] = []
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


def notices(report: Report, exports, failed) -> list[str]:
    """The run's lines for stderr: bags left out of the ISOXML, bags the engine lost, outputs
    not written ([(path, its one-line reason)])."""
    return ([f'planter: warning: {item["bag"]} not in the ISOXML task data ({item["reason"]})'
             for item in (exports or {}).get('skipped', [])]
            + [f'planter: warning: {bag} not analysed ({reason}): a re-run tries it again'
               for bag, reason in report.not_done]
            + [f'planter: error: {path} not written ({reason}); the tables and the '
               'other outputs are' for path, reason in failed])


def format_report(report: Report) -> str:
    """The run's report for people."""
    data = report.as_json()
    lines = [f'{report.found} bags found: {report.analysed} analysed ({report.warnings} with '
             f'warnings), {report.failed} failed, {report.skipped} skipped (analysed before), '
             f'{len(report.not_done)} lost; {report.plants} plants']
    if report.copies:
        path, same = report.copies[0]
        more = f' and {len(report.copies) - 1} more' if len(report.copies) > 1 else ''
        lines.append(f'{len(report.copies)} file(s) are copies of bags found (counted once): '
                     f'{path} = {same}{more}')
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
