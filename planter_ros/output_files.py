"""Files the commands write: checked before any work, written atomically.

`check_output` refuses a path the command could not write in the end (missing or read-only
directory, a directory where a file is asked for, an unsupported extension), so a long run never
fails at its last step; `atomic_output` writes through a temporary file in the same directory and
a rename, so a reader never sees a half-written file and a failed or invalid write leaves the
user's old file as it was (`atomic_outputs`: a set of files written whole before any is renamed;
`atomic_directory`: a directory of files). Pure Python, no ROS.
"""

from collections.abc import Collection, Iterable, Iterator, Mapping
from contextlib import contextmanager
import math
import os
from pathlib import Path
import shutil
import stat
import tempfile
from typing import TypeVar

from planter_ros.errors import PlanterError

_T = TypeVar('_T')
PathLike = str | os.PathLike[str]


class OutputError(PlanterError, ValueError):
    """An output path that cannot be written as asked (one line: the option, the path, why)."""


def check_output(path: PathLike | None, option: str, suffixes: Collection[str]) -> Path:
    """Refuse (OutputError) an output file `path` given as `option` that cannot be written:
    its extension not one of `suffixes` (e.g. ('.png',)), a directory, an existing file that is
    not a writable regular file, a missing, non-directory or read-only parent. Returns a Path."""
    if path is None or str(path) == '':
        raise OutputError(f'{option} is empty: allowed a file name ending in {_words(suffixes)}')
    path = Path(path)
    if path.is_dir():
        raise OutputError(f'{option} = {path} is a directory: allowed a file name ending in '
                          f'{_words(suffixes)}')
    if path.suffix.lower() not in suffixes:
        raise OutputError(f'{option} = {path} has an unsupported extension: allowed a file name '
                          f'ending in {_words(suffixes)}')
    if path.exists() or path.is_symlink():
        if not path.is_file():
            raise OutputError(f'{option} = {path} exists and is not a regular file: allowed a '
                              'new file or a regular file to replace')
        if not os.access(path, os.W_OK):
            raise OutputError(f'{option} = {path} is a read-only file: allowed a writable or '
                              'new file')
    check_directory(path.parent, option, path)
    return path


def check_new_path(path: PathLike, option: str, suffixes: Collection[str]) -> Path:
    """Refuse (OutputError) a path that must not exist yet (a recording) or whose parent is
    missing or read-only; `suffixes` may contain '' (a directory name). Returns a Path."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise OutputError(f'{option} = {path} has an unsupported extension: allowed '
                          f'{_words(suffixes)}')
    if path.exists() or path.is_symlink():
        raise OutputError(f'{option} = {path} exists: allowed a new path (a recording is never '
                          'overwritten)')
    check_directory(path.parent, option, path)
    return path


def check_directory(directory: Path, option: str, path: Path | None = None) -> None:
    """Refuse (OutputError) a directory that is missing, not a directory or not writable (tried
    by creating and removing a temporary file: permissions, read-only mounts, full quota)."""
    shown = f'{option} = {path}: directory {directory}' if path is not None else \
        f'{option} = {directory}: directory'
    if not directory.exists():
        raise OutputError(f'{shown} does not exist: allowed a path in an existing directory')
    if not directory.is_dir():
        raise OutputError(f'{shown} is not a directory: allowed a path in an existing directory')
    try:
        fd, probe = tempfile.mkstemp(dir=directory, prefix='.planter-probe-')
    except OSError as exc:
        raise OutputError(f'{shown} is not writable ({exc.strerror or exc}): allowed a path in '
                          'a writable directory') from None
    os.close(fd)
    os.unlink(probe)


@contextmanager
def atomic_output(path: PathLike) -> Iterator[Path]:
    """Yield a temporary path next to `path` (same extension, so writers that go by it work);
    on success it replaces `path` (keeping an existing file's mode), on an exception it is
    removed and `path` is untouched."""
    path = Path(path)
    mode = _mode_for(path)           # a replaced file keeps its mode, a new one gets open()'s
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f'.{path.name}.',
                               suffix=f'.tmp{path.suffix}')
    os.close(fd)
    try:
        yield Path(tmp)
        with open(tmp, 'rb+') as f:
            os.fsync(f.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


@contextmanager
def atomic_outputs(paths: Iterable[PathLike]) -> Iterator[list[Path]]:
    """atomic_output for a set of files that belong together (a Shapefile's .shp, .shx, .dbf,
    ...): yields one temporary path per path (same directory and extension); only when all
    are written are they renamed onto the paths, in the order given (put the file readers
    open first last); on an exception every temporary is removed and no path is touched."""
    targets = [Path(p) for p in paths]
    temporaries: list[Path] = []
    try:
        for path in targets:
            fd, name = tempfile.mkstemp(dir=path.parent, prefix=f'.{path.name}.',
                                        suffix=f'.tmp{path.suffix}')
            os.close(fd)
            temporaries.append(Path(name))
        yield list(temporaries)
        for path, temporary in zip(targets, temporaries):
            with open(temporary, 'rb+') as f:
                os.fsync(f.fileno())
            os.chmod(temporary, _mode_for(path))
        for path, temporary in zip(targets, temporaries):
            os.replace(temporary, path)
    except BaseException:
        for temporary in temporaries:
            try:
                os.unlink(temporary)
            except OSError:
                pass
        raise


@contextmanager
def atomic_directory(path: PathLike) -> Iterator[Path]:
    """Yield a new temporary directory next to `path`; on success it takes the place of `path`
    (an existing directory there is moved aside, then removed: a reader sees the old or the
    new one, never a half-written one); on an exception it is removed and `path` untouched."""
    path = Path(path)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=f'.{path.name}.', suffix='.tmp'))
    try:
        yield tmp
        for file in (f for f in tmp.rglob('*') if f.is_file()):
            with open(file, 'rb+') as f:
                os.fsync(f.fileno())
        os.chmod(tmp, _mode_for(path, directory=True))
        old = None
        if path.exists():
            old = Path(tempfile.mkdtemp(dir=path.parent, prefix=f'.{path.name}.',
                                        suffix='.old'))
            os.replace(path, old)        # onto the empty directory just made
        os.replace(tmp, path)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _mode_for(path: Path, directory: bool = False) -> int:
    """The mode a replaced file or directory keeps, or what a new one would get."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return (0o777 if directory else 0o666) & ~umask


def write_text_atomically(path: PathLike, text: str) -> None:
    """Write `text` (UTF-8) to `path` through atomic_output."""
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding='utf-8')


def _words(suffixes: Collection[str]) -> str:
    words = [s if s else 'a directory name without extension' for s in suffixes]
    return words[0] if len(words) == 1 else ', '.join(words[:-1]) + ' or ' + words[-1]


def require_finite(result: _T, what: str) -> _T:
    """Raise OutputError naming the first NaN or infinite number in a JSON-like result (a
    design no one can build must never be printed as one); return the result."""
    def walk(value: object, key: object) -> None:
        if isinstance(value, dict):
            for k, v in value.items():
                walk(v, k)
        elif isinstance(value, (list, tuple)):
            for v in value:
                walk(v, key)
        elif isinstance(value, float) and not math.isfinite(value):
            raise OutputError(f'{what}: {key} = {value} is not finite: allowed inputs whose '
                              'result is a finite design')
    walk(result, what)
    return result


def check_distinct(outputs: Mapping[str, PathLike | None]) -> None:
    """OutputError when two output options ({option: path or None}) name the same file (the
    later would replace the earlier)."""
    seen: dict[Path, str] = {}
    for option, path in outputs.items():
        if not path:
            continue
        key = Path(path).resolve()
        if key in seen:
            raise OutputError(f'{option} = {path} is also {seen[key]}: allowed a path no other '
                              'output option names')
        seen[key] = option
