"""Finding the bags of a season: `.mcap` files and rosbag2 bag directories, recursively.

A directory is a bag directory (one bag, not searched further) when it holds rosbag2's
`metadata.yaml` or a split file named after it (`<dir>/<dir>_<n>.mcap`, which is how this
package's recorder and rosbag2 name them, a killed recording without metadata.yaml included).
Any other directory is searched: each `.mcap` file in it is a bag, each subdirectory is searched
in turn. Names starting with '.' are skipped (temporary files), and so is the output directory.
Each bag's identity for the re-run rule is its size and modification time (`identity`).
Pure Python, no ROS.
"""

import os
from pathlib import Path
import re


class BagSearchError(ValueError):
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


def find_bags(paths, skip=()):
    """Every bag under `paths` (files and directories), as absolute paths, sorted, each once;
    directories in `skip` (absolute) are not searched. BagSearchError for a path that does not
    exist or a file that is not `.mcap`."""
    skip = {Path(s).resolve() for s in skip}
    found = set()
    for given in paths:
        path = Path(given)
        if not path.exists():
            raise BagSearchError(f'PATH = {given} does not exist: allowed .mcap files and '
                                 'directories holding bags')
        path = path.resolve()
        if path.is_file():
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
            found.update((here / name).resolve() for name in files
                         if name.lower().endswith('.mcap') and not name.startswith('.'))
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
