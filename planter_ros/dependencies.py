"""What planter_ros needs, by role: the one declaration (setup.py reads it; requirements.txt pins
every name here; package.xml lists the same by rosdep key; tests check all three agree).

* base (`pip install planter_ros`): what the nodes (design_node, sync_node, monitor_node,
  ground_speed_node), the command process and the machine's own commands (`planter demo`,
  `replay` without exports, `commission`, `design` and `cam` without plots, `optimize`) import:
  a tractor computer needs nothing else.
* `analysis`: a season of bags (`planter analyze`, `planter simulate`), the exports farm software
  reads (Shapefile, ISOXML), the report plots (`--plot`).
* `dev`: the test suite, the bench (`planter bench`), lint, the type checker and the colcon build
  check; it includes `analysis` (the suite tests it).

A command that needs an extra that is not installed says so in one line, naming the extra and
how to install it (`require`, `MissingExtra`; exit code 2 on the command line). Pure: no import
beyond the standard library (and the error root, when it can be imported), so setup.py can read
it before anything is installed.
"""
from __future__ import annotations

import importlib.util
import re

# setup.py execs this file alone, before anything is installed: it reads the roles only, and
# the error root (standard library only itself) may not be importable there
try:
    from planter_ros.errors import PlanterError
except ImportError:
    PlanterError = Exception  # type: ignore[misc,assignment]

__all__ = ['BASE', 'COMMAND_EXTRAS', 'EXTRAS', 'IMPORT_NAMES', 'ROLES', 'MissingExtra',
           'check_command', 'distribution', 'error_line',
           'extra_of_module', 'install_hint', 'missing_modules', 'modules_of', 'require']

# install_requires: the oldest versions each is known to work with (requirements.txt pins
# the exact versions the bootstrap and CI install)
BASE = [
    'ros-jazzy-rclpy[fastrtps]>=7.1.6',        # ROS 2 Jazzy from PyPI wheels (rclpy, Fast DDS)
    'ros-jazzy-common-interfaces>=5.3.6',     # std/geometry/sensor/diagnostic/visualization msgs
    'numpy>=2.0',
    'scipy>=1.13',                            # root finding, splines, optimisers
    'PyYAML>=6.0',                            # scene and machine files
    'python-can>=4.4',                        # the CAN bus
    'canopen>=2.4',                           # CANopen / CiA 402 masters
    'cantools>=39.4',                         # ISOBUS speed messages from a DBC
    'mcap>=1.2',                              # recording
    'zstandard>=0.22',                        # the bags' zstd chunks
    'lz4>=4.0',                               # the lz4 chunks other recorders write
    'isal>=1.6',                              # the chunks' CRC-32, fast
    'rosbags>=0.10',                          # CDR decoding of recorded diagnostics
    'pyproj>=3.6',                            # geodesy of the as-planted map
]
ANALYSIS = [
    'dask[distributed]>=2024.8',              # planter analyze / simulate on a cluster
    'distributed>=2024.8',
    'pyarrow>=15',                            # Parquet tables of a season
    'pandas>=2.2',                            # the season's tables (dask.dataframe needs it)
    'duckdb>=1.0',                            # SQL on the Parquet tables
    'pyshp>=2.3',                             # Shapefile export
    'isoxml>=0.0.4',                          # ISO 11783-10 task data export
    'xsdata>=24.7',                           # isoxml's bindings (its date-time type)
    'matplotlib>=3.8',                        # the report plots (--plot, report.html)
]
DEV_TOOLS = [
    'pytest>=8',
    'pytest-xdist>=3.5',                      # pytest.ini runs the suite on two processes
    'hypothesis>=6.100',                      # property tests
    'mpmath>=1.3',                            # high-precision references (tests, planter bench)
    'ruff>=0.6',                              # lint (test_lint.py)
    'mypy>=1.9',                              # the type checker (mypy.ini)
    'types-PyYAML>=6.0',                      # PyYAML's stubs (typeshed), for mypy
    'scipy-stubs>=1.14',                      # SciPy's stubs, for mypy
    'colcon-common-extensions>=0.3',          # the colcon build check
    'pyogrio>=0.10',                          # GDAL: an independent Shapefile reader (tests)
    'shapely>=2.0',                           # geometry checks of the exports (tests)
    'xmlschema>=3.0',                         # validates ISOXML against the XSD (tests)
    'mcap-ros2-support>=0.5',                 # an independent decoder of every recorded message
    'psutil>=5.9',                            # process trees in the die-with-parent tests
    'rosdep>=0.25',                           # resolves package.xml against rosdistro (tests)
]
EXTRAS = {'analysis': ANALYSIS, 'dev': ANALYSIS + DEV_TOOLS}
ROLES = {'base': BASE, **EXTRAS}

# distribution -> the top-level modules it provides, where that is not its own name
IMPORT_NAMES = {
    'ros-jazzy-rclpy': ('rclpy', 'rcl_interfaces', 'builtin_interfaces', 'rosgraph_msgs',
                        'ament_index_python'),
    'ros-jazzy-common-interfaces': ('std_msgs', 'std_srvs', 'geometry_msgs', 'sensor_msgs',
                                    'diagnostic_msgs', 'visualization_msgs'),
    'PyYAML': ('yaml',),
    'python-can': ('can',),
    'pyshp': ('shapefile',),
    'pytest': ('pytest', '_pytest'),
    'pytest-xdist': ('xdist',),
    'mcap-ros2-support': ('mcap_ros2',),
    'colcon-common-extensions': ('colcon_core',),
    'rosdep': ('rosdep2',),
    'types-PyYAML': ('yaml-stubs',),
    'scipy-stubs': ('scipy-stubs',),
}


# what a `planter` command needs beyond the base install: command words -> [(extra, the
# distributions of it it uses (all: ()), the option that needs them (None: the command itself))]
COMMAND_EXTRAS: dict[tuple[str, ...], list[tuple[str, tuple[str, ...], str | None]]] = {
    ('analyze',): [('analysis', (), None)],
    ('simulate',): [('analysis', (), None)],
    ('bench',): [('dev', ('mpmath',), None), ('analysis', (), None)],
    ('replay',): [('analysis', ('matplotlib',), 'plot'), ('analysis', ('pyshp',), 'shapefile'),
                  ('analysis', ('isoxml', 'xsdata'), 'isoxml')],
    ('design', 'five-bar'): [('analysis', ('matplotlib',), 'plot')],
    ('design', 'three-arm'): [('analysis', ('matplotlib',), 'plot')],
    ('cam', 'five-bar'): [('analysis', ('matplotlib',), 'plot')],
}


class MissingExtra(PlanterError):
    """A command needs an extra that is not installed (one line: which, and how to get it)."""

    def __init__(self, what: str, extra: str, missing: list[str]) -> None:
        self.what, self.extra, self.missing = what, extra, list(missing)
        super().__init__(f'{what} needs the {extra!r} extra, not installed here (missing: '
                         f'{", ".join(self.missing)}): {install_hint(extra)}')


def install_hint(extra: str) -> str:
    return (f"pip install 'planter_ros[{extra}]' (on a ROS machine: doc/deploy.md, "
            '"Install by role")')


def distribution(requirement: str) -> str:
    """The distribution name of a requirement string ('dask[distributed]>=1' -> 'dask')."""
    return re.split(r'[\[<>=!~; ]', requirement, maxsplit=1)[0]


def modules_of(name: str) -> tuple[str, ...]:
    """The top-level modules distribution `name` provides."""
    return IMPORT_NAMES.get(name, (name.replace('-', '_').lower(),))


def extra_of_module(module: str) -> str | None:
    """The extra whose distributions provide top-level module `module` (None: the base or
    nobody's); 'analysis' before 'dev'."""
    top = module.split('.')[0]
    if any(top in modules_of(distribution(r)) for r in BASE):
        return None
    for extra, requirements in EXTRAS.items():
        if any(top in modules_of(distribution(r)) for r in requirements):
            return extra
    return None


def missing_modules(extra: str, names: tuple[str, ...] = ()) -> list[str]:
    """The distributions of `extra` (only `names` of them, if given) whose modules cannot be
    found here (nothing is imported)."""
    missing = []
    for requirement in EXTRAS[extra]:
        name = distribution(requirement)
        if names and name not in names:
            continue
        if any(importlib.util.find_spec(module) is None for module in modules_of(name)):
            missing.append(name)
    return sorted(set(missing))


def require(extra: str, what: str, names: tuple[str, ...] = ()) -> None:
    """Raise MissingExtra unless every distribution of `extra` (or only `names` of them) is
    installed (`what`: the command, for the message)."""
    missing = missing_modules(extra, names)
    if missing:
        raise MissingExtra(what, extra, missing)


def check_command(words: tuple[str, ...] | None, args: object) -> None:
    """MissingExtra when the `planter` command `words`, with the options in `args` (argparse's
    namespace), needs an extra that is not installed (before any work starts)."""
    words = words or ()
    for extra, names, option in COMMAND_EXTRAS.get(words, []):
        if option is None or getattr(args, option, None):
            what = 'planter ' + ' '.join(words) + (f' --{option}' if option else '')
            require(extra, what, names)


def error_line(words: tuple[str, ...] | None, exc: Exception) -> str:
    """The command line's one line for `exc`; for a module of an extra that a command reached,
    which extra to install (`exc` re-raised when the module is nobody's extra: a bug, not an
    install)."""
    if not isinstance(exc, ModuleNotFoundError):
        return str(exc)
    name = exc.name or ''
    extra = extra_of_module(name)
    if extra is None:
        raise exc
    return str(MissingExtra('planter ' + ' '.join(words or ()), extra, [name]))
