"""Finding the bags of a season: `.mcap` files and rosbag2 bag directories, recursively.

A directory is a bag directory (one bag, not searched further) when it holds rosbag2's
`metadata.yaml` or a split file named after it (`<dir>/<dir>_<n>.mcap`, which is how this
package's recorder and rosbag2 name them, a killed recording without metadata.yaml included).
Any other directory is searched: each `.mcap` file in it is a bag, each subdirectory is searched
in turn. Names starting with '.' are skipped (temporary files), and so is the output directory.
An entry named `.mcap` that is not a regular file (a FIFO, a socket, a device: reading it could
wait forever) or a symbolic link to nothing is not a bag: it is skipped and named (`ignored`).

A bag's identity is its content (`fingerprint`: SHA-256 of its bytes), so the same recording is
one bag however it was found: from another root, in a moved folder, through a symbolic link or
as a copy. Its size and modification time (`identity`) only tell whether a fingerprint taken
before still holds. Pure Python, no ROS.
"""

import hashlib
import os
from pathlib import Path
import re
import stat

from planter_ros.errors import PlanterError


class BagSearchError(PlanterError, ValueError):
    """A path given to search that is not there or not a bag (one line)."""


def is_bag_directory(directory):
    directory = Path(directory)
    if (directory / 'metadata.yaml').is_file():
        return True
    split = re.compile(re.escape(directory.name) + r'_\d+\.mcap')
    try:
        return any(split.fullmatch(entry.name) and entry.is_file()
                   for entry in os.scandir(directory))
    except OSError:
        return False


def path_kind(path):
    """'file', 'dir', or why `path` is neither (a symbolic link to nothing, a FIFO, ...)."""
    try:
        mode = os.stat(path).st_mode          # follows links
    except FileNotFoundError:
        return 'a symbolic link to nothing' if os.path.islink(path) else 'missing'
    except OSError as exc:
        return f'not readable ({exc.strerror or exc})'
    if stat.S_ISREG(mode):
        return 'file'
    if stat.S_ISDIR(mode):
        return 'dir'
    what = {stat.S_IFIFO: 'a FIFO', stat.S_IFSOCK: 'a socket', stat.S_IFCHR: 'a device',
            stat.S_IFBLK: 'a device'}.get(stat.S_IFMT(mode), 'not a regular file')
    return what


def check_bag(bag):
    """BagSearchError for a single BAG (planter replay's) that is empty or neither a file nor
    a directory (a FIFO named .mcap would be read forever): one line, before any reading. A
    missing one is left to the reader, which names it."""
    if str(bag).strip() == '':
        raise BagSearchError('BAG is empty: allowed a .mcap file or a rosbag2 bag directory')
    kind = path_kind(Path(bag))
    if kind not in ('file', 'dir', 'missing', 'a symbolic link to nothing'):
        raise BagSearchError(f'BAG = {bag} is {kind}, not a bag: allowed a .mcap file or a '
                             'rosbag2 bag directory')


def find_bags(paths, skip=(), ignored=None):
    """Every bag under `paths` (files and directories), as absolute paths, sorted, each once;
    directories in `skip` (absolute) are not searched; an entry named .mcap that is not a
    regular file (module doc) is appended to `ignored` as (path, why). BagSearchError for a
    path given that does not exist, is not .mcap, or is neither a file nor a directory."""
    skip = {Path(s).resolve() for s in skip}
    ignored = [] if ignored is None else ignored
    found = set()
    for given in paths:
        if str(given).strip() == '':
            raise BagSearchError("PATH is empty: allowed .mcap files and directories holding "
                                 "bags ('.' for the working directory)")
        path = Path(given)
        kind = path_kind(path)
        if kind == 'missing' or kind == 'a symbolic link to nothing':
            raise BagSearchError(f'PATH = {given} does not exist'
                                 f'{" (a symbolic link to nothing)" if kind != "missing" else ""}'
                                 ': allowed .mcap files and directories holding bags')
        if kind not in ('file', 'dir'):
            raise BagSearchError(f'PATH = {given} is {kind}, not a bag: allowed .mcap files '
                                 'and directories holding bags')
        path = path.resolve()
        if kind == 'file':
            if path.suffix.lower() != '.mcap':
                raise BagSearchError(f'PATH = {given} is not a .mcap file: allowed .mcap files '
                                     'and directories holding bags')
            found.add(path)
            continue
        if is_bag_directory(path):
            found.add(path)
            continue
        seen = set()
        for root, dirs, files in os.walk(path, followlinks=True):
            here = Path(root)
            real = here.resolve()
            if real in seen or real in skip:           # a symlink loop, the output
                dirs[:] = []
                continue
            seen.add(real)
            keep = []
            for name in sorted(dirs):
                sub = here / name
                if name.startswith('.') or sub.resolve() in skip:
                    continue
                if is_bag_directory(sub):
                    found.add(sub.resolve())
                else:
                    keep.append(name)
            dirs[:] = keep
            for name in sorted(files):
                if not name.lower().endswith('.mcap') or name.startswith('.'):
                    continue
                kind = path_kind(here / name)
                if kind == 'file':
                    found.add((here / name).resolve())
                elif kind == 'dir':
                    continue                           # os.walk lists it as a directory too
                else:
                    ignored.append((str(here / name), kind))
    return sorted(found)


def identity(path):
    """(bytes, modification time ns) of a bag: a file's own, or for a bag directory the sum of
    its files' sizes and the latest modification time of the directory and its files (a file
    added, removed or rewritten changes it)."""
    path = Path(path)
    info = path.stat()
    if not path.is_dir():
        return info.st_size, info.st_mtime_ns
    size, mtime = 0, info.st_mtime_ns
    for entry in os.scandir(path):
        if entry.is_file():
            stat = entry.stat()
            size += stat.st_size
            mtime = max(mtime, stat.st_mtime_ns)
    return size, mtime


FINGERPRINT_BLOCK = 1 << 20          # bytes read at a time


def fingerprint(path):
    """A bag's content identity: 'sha256:' and the SHA-256 of its bytes (a bag directory: of
    its .mcap files' bytes, in name order; its metadata.yaml, which rosbag2 rewrites, is not
    content). OSError if it cannot be read."""
    path = Path(path)
    files = sorted(f for f in path.iterdir() if f.suffix.lower() == '.mcap'
                   and f.is_file()) if path.is_dir() else [path]
    digest = hashlib.sha256()
    for file in files:
        with open(file, 'rb') as f:
            while block := f.read(FINGERPRINT_BLOCK):
                digest.update(block)
    return f'sha256:{digest.hexdigest()}'
