"""Every dependency is declared, once, and resolves on a real ROS machine.

* Every key of package.xml resolves for Ubuntu 24.04 (noble) and ROS 2 Jazzy against a dated
  snapshot of ros/rosdistro's rules (test/data/rosdistro-*: the entries of its rosdep/python.yaml
  and jazzy/distribution.yaml for our keys, copied as they are) plus the rule file the package
  ships (rosdep/planter_ros.yaml): once by our reading of the rule format, once by the real
  `rosdep` (a reference we did not write) run offline against file:// sources. A key without a
  rule fails both.
* Every import of the package, its launch files and its tests maps to a declared dependency:
  a ROS package to a package.xml key, anything else to a distribution of
  planter_ros/dependencies.py (setup.py's roles), each pinned in requirements.txt.
* package.xml says what dependencies.py says, role by role.
"""
import ast
import importlib.metadata
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest
import yaml

from cli_helpers import REPO
from planter_ros import dependencies

SNAPSHOT = sorted((REPO / 'test' / 'data').glob('rosdistro-*'))[-1]
SHIPPED = REPO / 'rosdep' / 'planter_ros.yaml'
OS, VERSION = 'ubuntu', 'noble'
ANALYSIS = '$PLANTER_ANALYSIS == 1'          # package.xml's condition of the analysis extra

# distribution of dependencies.py -> its rosdep key in package.xml
ROSDEP_KEY = {
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'PyYAML': 'python3-yaml',
    'python-can': 'python3-can', 'canopen': 'canopen-pip', 'cantools': 'python3-cantools-pip',
    'mcap': 'python3-mcap-pip', 'zstandard': 'python3-zstandard-pip', 'lz4': 'python3-lz4-pip',
    'isal': 'python3-isal-pip', 'rosbags': 'python3-rosbags-pip', 'pyproj': 'python3-pyproj',
    'dask': 'python3-dask-pip', 'distributed': 'python3-distributed-pip',
    'pyarrow': 'python3-pyarrow-pip', 'pandas': 'python3-pandas', 'duckdb': 'python-duckdb-pip',
    'pyshp': 'python3-pyshp-pip', 'isoxml': 'python3-isoxml-pip',
    'xsdata': 'python3-xsdata-pip', 'matplotlib': 'python3-matplotlib',
    'pytest': 'python3-pytest', 'pytest-xdist': 'python3-pytest-xdist',
    'hypothesis': 'python3-hypothesis', 'mpmath': 'python3-mpmath-pip',
    'ruff': 'python3-ruff-pip', 'mypy': 'python3-mypy',
    'types-PyYAML': 'python3-types-pyyaml', 'scipy-stubs': 'python3-scipy-stubs-pip',
    'xmlschema': 'python3-xmlschema',
    'colcon-common-extensions': 'python3-colcon-common-extensions',
    'pyogrio': 'python3-pyogrio-pip', 'shapely': 'python3-shapely',
    'mcap-ros2-support': 'mcap-ros2-support', 'psutil': 'python3-psutil',
    'rosdep': 'python3-rosdep'}
# ROS packages our code imports that no pip distribution of ours provides: the launch files
# run under `ros2 launch` on a ROS machine only
LAUNCH_ONLY = {'launch', 'launch_ros'}


def package_depends():
    """{key: (tag, condition)} of package.xml."""
    root = ET.parse(REPO / 'package.xml').getroot()
    return {e.text: (e.tag, e.get('condition', '')) for e in root
            if e.tag.endswith('depend')}


def ros_keys():
    """The ROS package keys (imported modules of the ros-jazzy-* distributions, the launch
    packages)."""
    keys = set(LAUNCH_ONLY)
    for requirement in dependencies.BASE:
        name = dependencies.distribution(requirement)
        if name.startswith('ros-jazzy-'):
            keys |= set(dependencies.modules_of(name))
    return keys


def load_rules():
    rules = {}
    for path in (SNAPSHOT / 'python.yaml', SHIPPED):
        for key, rule in yaml.safe_load(path.read_text()).items():
            assert key not in rules, f'{key} is defined twice ({path.name})'
            rules[key] = rule
    return rules


def ros_packages():
    dist = yaml.safe_load((SNAPSHOT / 'jazzy-distribution.yaml').read_text())
    assert VERSION in dist['release_platforms'][OS]
    return {package for name, repo in dist['repositories'].items()
            for package in repo['release'].get('packages', [name])}


def resolve(key, rules, packages):
    """What rosdep installs for `key` on noble/Jazzy, as (installer, packages); None: no rule.
    The rule format (REP 111): os -> list | {installer: ...} | {version or '*': ...}."""
    if key in packages:
        return 'apt', [f'ros-jazzy-{key.replace("_", "-")}']
    rule = rules.get(key)
    if rule is None:
        return None
    entry = rule.get(OS, rule.get('*'))
    if isinstance(entry, dict) and set(entry) - {'pip', 'apt', 'source'}:
        entry = entry.get(VERSION, entry.get('*'))      # per version
    if entry is None:
        return None
    if isinstance(entry, list):
        return ('apt', entry) if entry else None
    installer = next(iter(entry))
    body = entry[installer]
    found = body.get('packages') if isinstance(body, dict) else body
    return (installer, found) if found else None


def test_every_package_xml_key_resolves_for_noble_and_jazzy():
    rules, packages = load_rules(), ros_packages()
    keys = package_depends()
    resolved = {key: resolve(key, rules, packages) for key in keys}
    unresolved = sorted(key for key, found in resolved.items() if found is None)
    assert unresolved == [], f'no rosdep rule for noble/Jazzy: {unresolved}'
    assert len(keys) >= 40
    # the reader itself is not lenient: a made-up key and another OS's only rule do not resolve
    assert resolve('python3-no-such-library', rules, packages) is None
    assert resolve('python3-canopen', rules, packages) is None     # (canopen-pip is the key)


def test_the_shipped_rules_only_fill_what_rosdistro_lacks():
    """Our file defines no key rosdistro's snapshot has (a rule of our own would shadow
    theirs), each installs from PyPI on Ubuntu, and each is used by package.xml."""
    ours = yaml.safe_load(SHIPPED.read_text())
    theirs = yaml.safe_load((SNAPSHOT / 'python.yaml').read_text())
    assert not set(ours) & set(theirs)
    used = set(package_depends())
    for key, rule in ours.items():
        assert key.endswith('-pip') and key in used, key
        assert list(rule[OS]) == ['pip'] and rule[OS]['pip']['packages'], key


def rosdep_env(tmp_path):
    sources = tmp_path / 'sources.list.d'
    sources.mkdir()
    (sources / '20-default.list').write_text(
        f'yaml file://{SNAPSHOT / "python.yaml"}\nyaml file://{SHIPPED}\n')
    env = dict(os.environ, ROSDEP_SOURCE_PATH=str(sources), ROS_HOME=str(tmp_path / 'home'),
               ROSDISTRO_INDEX_URL=f'file://{SNAPSHOT / "index-v4.yaml"}', ROS_DISTRO='jazzy',
               ROS_PYTHON_VERSION='3', PLANTER_ANALYSIS='1')
    # nothing of this process's ROS (rclpy's wheels set AMENT_PREFIX_PATH when imported):
    # with --ignore-src rosdep would take those packages for sources and skip their keys
    for name in ('PYTHONPATH', 'AMENT_PREFIX_PATH', 'ROS_PACKAGE_PATH', 'COLCON_PREFIX_PATH',
                 'CMAKE_PREFIX_PATH'):
        env.pop(name, None)
    return env


def rosdep(env, *args, cwd=None):
    exe = Path(sys.executable).with_name('rosdep')
    return subprocess.run([str(exe), *args], capture_output=True, text=True, env=env,
                          timeout=120, cwd=cwd)


@pytest.mark.skipif(shutil.which('rosdep', path=str(Path(sys.executable).parent)) is None,
                    reason='rosdep (the dev extra) is not installed')
def test_real_rosdep_resolves_every_key_offline_and_fails_on_one_without_a_rule(tmp_path):
    env = rosdep_env(tmp_path)
    update = rosdep(env, 'update')
    assert update.returncode == 0, update.stdout + update.stderr
    assert 'Add distro "jazzy"' in update.stdout
    src = tmp_path / 'src' / 'planter_ros'
    src.mkdir(parents=True)
    shutil.copy(REPO / 'package.xml', src / 'package.xml')
    listed = rosdep(env, 'keys', '--from-paths', str(src.parent), '--ignore-src')
    assert listed.returncode == 0, listed.stderr
    keys = sorted(listed.stdout.split())
    assert keys == sorted(package_depends())           # every key, the analysis ones too
    out = rosdep(env, 'resolve', *keys, f'--os={OS}:{VERSION}', '--rosdistro=jazzy')
    assert out.returncode == 0 and 'ERROR' not in out.stderr, out.stdout + out.stderr
    blocks = re.findall(r'^#ROSDEP\[(\S+)\]\n#(apt|pip)\n(.+)$', out.stdout, re.M)
    assert sorted(key for key, _, _ in blocks) == keys, out.stdout
    libraries = {library for _, _, line in blocks for library in line.split()}
    for library in ('ros-jazzy-rclpy', 'ros-jazzy-visualization-msgs', 'ros-jazzy-launch-ros',
                    'python3-numpy', 'canopen', 'pandas', 'mcap', 'lz4', 'isal', 'psutil'):
        assert library in libraries or f'python3-{library}' in libraries, (library, out.stdout)
    # the tractor's install: the base only (no test_depend, no analysis without the condition)
    env_base = dict(env)
    env_base.pop('PLANTER_ANALYSIS')
    base = rosdep(env_base, 'keys', '--from-paths', str(src.parent), '--ignore-src', '-t', 'exec')
    assert base.returncode == 0, base.stderr
    assert sorted(base.stdout.split()) == sorted(
        key for key, (tag, condition) in package_depends().items()
        if tag == 'exec_depend' and not condition)
    # a key without a rule: rosdep refuses, naming it
    xml = (src / 'package.xml').read_text()
    (src / 'package.xml').write_text(xml.replace(
        '<exec_depend>rclpy</exec_depend>',
        '<exec_depend>rclpy</exec_depend>\n  <exec_depend>python3-zstandard</exec_depend>'))
    bad_keys = rosdep(env, 'keys', '--from-paths', str(src.parent), '--ignore-src')
    assert 'python3-zstandard' in bad_keys.stdout.split()
    bad = rosdep(env, 'resolve', *bad_keys.stdout.split(), f'--os={OS}:{VERSION}',
                 '--rosdistro=jazzy')
    assert bad.returncode != 0
    assert "no rosdep rule for 'python3-zstandard'" in bad.stdout + bad.stderr


def test_package_xml_says_what_dependencies_py_says_role_by_role():
    depends = package_depends()
    for key in ros_keys():
        assert depends.get(key) == ('exec_depend', ''), key
    roles = {'base': ('exec_depend', ''), 'analysis': ('exec_depend', ANALYSIS),
             'dev': ('test_depend', '')}
    wanted = {}
    for role, requirements in (('base', dependencies.BASE), ('analysis', dependencies.ANALYSIS),
                               ('dev', dependencies.DEV_TOOLS)):
        for requirement in requirements:
            name = dependencies.distribution(requirement)
            if name.startswith('ros-jazzy-'):
                continue
            assert name in ROSDEP_KEY, f'{name}: which rosdep key? (ROSDEP_KEY, package.xml)'
            wanted[ROSDEP_KEY[name]] = roles[role]
    wanted.update({key: ('exec_depend', '') for key in ros_keys()})
    assert depends == wanted


def requirement_pins():
    pins = {}
    for line in (REPO / 'requirements.txt').read_text().splitlines():
        line = line.split('#', 1)[0].strip()
        if line:
            name, sep, version = line.partition('==')
            assert sep and version, f'requirements.txt: {line} is not pinned'
            pins[dependencies.distribution(name).lower()] = version
    return pins


def test_requirements_txt_pins_every_declared_distribution_at_or_above_its_floor():
    pins = requirement_pins()
    for role, requirements in dependencies.ROLES.items():
        for requirement in requirements:
            name = dependencies.distribution(requirement).lower()
            assert name in pins, f'{name} ({role}) is not pinned in requirements.txt'
            floor = re.search(r'>=([\d.]+)', requirement)
            if floor:
                assert _version(pins[name]) >= _version(floor.group(1)), requirement


def _version(text):
    return tuple(int(part) for part in re.findall(r'\d+', text)[:3])


# modules typeshed keeps among the standard library's stubs (`_typeshed`, `typing_extensions`):
# every type checker carries them (mypy, the dev extra); allowed only under `if TYPE_CHECKING:`,
# never imported at run time
TYPESHED = {'_typeshed', 'typing_extensions'}


def _typing_only(tree):
    """The import statements of `tree` under `if TYPE_CHECKING:` (never run)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and 'TYPE_CHECKING' in ast.unparse(node.test):
            out |= {id(n) for stmt in node.body for n in ast.walk(stmt)
                    if isinstance(n, (ast.Import, ast.ImportFrom))}
    return out


def imported_modules():
    """{top-level module: [files]} of every import (at the top or in a function) in the
    package, its launch files, its tests and setup.py; the standard library and our own
    modules left out (TYPESHED's too, where only the type checker reads them)."""
    local = {'planter_ros'} | {p.stem for p in (REPO / 'test').glob('*.py')}
    found = {}
    files = [*(REPO / 'planter_ros').rglob('*.py'), *(REPO / 'launch').glob('*.py'),
             *(REPO / 'test').glob('*.py'), REPO / 'setup.py']
    for path in files:
        tree = ast.parse(path.read_text())
        typing_only = _typing_only(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split('.')[0]
                if top in TYPESHED and id(node) in typing_only:
                    continue
                if top not in sys.stdlib_module_names and top not in local:
                    found.setdefault(top, []).append(str(path.relative_to(REPO)))
    return found


def test_every_import_maps_to_a_declared_dependency():
    declared = {}
    for requirements in dependencies.ROLES.values():
        for requirement in requirements:
            name = dependencies.distribution(requirement)
            for module in dependencies.modules_of(name):
                declared.setdefault(module, name)
    depends = package_depends()
    found = imported_modules()
    undeclared = []
    for module, files in sorted(found.items()):
        if module in ros_keys():                   # a ROS package: package.xml
            if module not in depends:
                undeclared.append(f'{module} (package.xml) in {files[0]}')
            continue
        if module == 'setuptools':                 # the build's own (pyproject, pip)
            continue
        if module not in declared:
            undeclared.append(f'{module} (planter_ros/dependencies.py) in {files[0]}')
    assert undeclared == []
    for module in ('pandas', 'lz4', 'psutil', 'isal', 'visualization_msgs', 'launch_ros'):
        assert module in found, module             # the walk sees what it must


def test_each_declared_distribution_provides_the_modules_it_is_named_for():
    """dependencies.IMPORT_NAMES against the installed distributions' own records (the full
    install): a module is provided by the distribution, or by one it requires (the ROS
    meta-packages)."""
    provided = importlib.metadata.packages_distributions()
    # stub-only distributions (scipy-stubs) ship .pyi files, which packages_distributions()
    # does not infer top-level names from
    for dist in importlib.metadata.distributions():
        for path in dist.files or ():
            if path.suffix == '.pyi' and len(path.parts) > 1:
                provided.setdefault(path.parts[0], []).append(dist.metadata['Name'])
    for requirement in {r for rs in dependencies.ROLES.values() for r in rs}:
        name = dependencies.distribution(requirement)
        closure = _requirement_closure(name)
        for module in dependencies.modules_of(name):
            owners = {_norm(d) for d in provided.get(module, [])}
            assert owners & closure, (name, module, owners)


def _norm(name):
    return re.sub(r'[-_.]+', '-', name).lower()


def _requirement_closure(name, seen=None):
    seen = set() if seen is None else seen
    if _norm(name) in seen:
        return seen
    seen.add(_norm(name))
    try:
        requires = importlib.metadata.requires(name) or []
    except importlib.metadata.PackageNotFoundError:
        return seen
    for requirement in requires:
        if 'extra ==' in requirement and 'fastrtps' not in requirement:
            continue
        _requirement_closure(dependencies.distribution(requirement), seen)
    return seen


def test_a_command_needing_a_missing_extra_says_which_in_one_line(monkeypatch, capsys):
    from planter_ros.cli import main
    real = dependencies.importlib.util.find_spec
    monkeypatch.setattr(dependencies.importlib.util, 'find_spec',
                        lambda name, *a: None if name == 'pandas' else real(name, *a))
    code = main.main(['analyze', str(REPO / 'bags'), '--out', '/nonexistent/out'])
    err = capsys.readouterr().err
    assert code == 2 and err.count('\n') == 1, err
    assert ("planter analyze needs the 'analysis' extra, not installed here (missing: pandas): "
            "pip install 'planter_ros[analysis]'") in err
