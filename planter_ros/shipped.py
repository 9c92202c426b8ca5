"""The files the package ships in `config/` (the scenes, the drive's EDS, the Foxglove layout),
found in one place: the clone's `config/`, else the installed share directory
(`<prefix>/share/planter_ros/config`, pip or colcon), else the ament index's."""

from pathlib import Path
import re
import sys

__all__ = ['package_version', 'shipped_file']

PACKAGE = 'planter_ros'


def shipped_file(name: str) -> Path:
    """The path of `config/<name>`; FileNotFoundError naming every place looked in."""
    candidates = [Path(__file__).resolve().parents[1] / 'config' / name,
                  Path(sys.prefix) / 'share' / PACKAGE / 'config' / name]
    try:
        # lazy: the ament index of a ROS install, looked in last; without one the import
        # itself may fail (caught below)
        from ament_index_python.packages import get_package_share_directory
        candidates.append(Path(get_package_share_directory(PACKAGE)) / 'config' / name)
    except Exception:                     # not a ROS install, or the package is not indexed
        pass
    for path in candidates:
        if path.is_file():
            return path
    raise FileNotFoundError(f'{name} not found in: ' + ', '.join(str(p) for p in candidates))


def package_version() -> str:
    """planter_ros's version: the installed distribution's, else the clone's package.xml (the
    one `--version` of every executable prints). Reads, never writes."""
    # lazy: importlib.metadata costs 19 ms and only --version asks (every executable's --help
    # loads this module: test_help_opens_nothing)
    from importlib import metadata
    try:
        return metadata.version(PACKAGE)
    except metadata.PackageNotFoundError:
        pass
    for path in (Path(__file__).resolve().parents[1] / 'package.xml',
                 Path(sys.prefix) / 'share' / PACKAGE / 'package.xml'):
        if path.is_file():
            found = re.search(r'<version>\s*([^<\s]+)\s*</version>', path.read_text())
            if found:
                return found.group(1)
    return 'unknown'
