"""Every package of planter_ros says what it offers in `__all__`, and every name there exists:
an attribute of the package (a name it re-exports) or a module of it. A star import, a
documentation tool or a reader of the package sees the same list."""
import ast
import importlib.util

from cli_helpers import REPO

ROOT = REPO / 'planter_ros'


def packages():
    """(dotted name, __init__ path) of planter_ros and every package in it."""
    for init in sorted(ROOT.rglob('__init__.py')):
        parts = init.parent.relative_to(REPO).parts
        yield '.'.join(parts), init


def declared(init):
    """The names of the `__all__ = [...]` assignment at the top level of a module, else None."""
    for node in ast.parse(init.read_text()).body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == '__all__' for t in node.targets):
            return [ast.literal_eval(e) for e in node.value.elts]
    return None


def test_every_package_declares_what_it_offers():
    missing = [name for name, init in packages() if declared(init) is None]
    assert missing == []


def test_every_name_a_package_declares_exists():
    """Checked without importing: a re-exported name must be bound in the __init__ (imported,
    defined, or served by a module __getattr__ that names it), a module name must be a
    module or package beside it."""
    wrong = []
    for name, init in packages():
        names = declared(init)
        tree = ast.parse(init.read_text())
        bound = set()
        for node in tree.body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                bound |= {(a.asname or a.name).split('.')[0] for a in node.names}
            elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                bound.add(node.name)
            elif isinstance(node, ast.Assign):
                bound |= {t.id for t in node.targets if isinstance(t, ast.Name)}
        lazy = '__getattr__' in bound and {
            k.value for node in tree.body if isinstance(node, ast.Assign)
            for t in node.targets if isinstance(t, ast.Name) and t.id == '_HOME'
            for k in node.value.keys}
        for item in names:
            here = init.parent
            is_module = (here / f'{item}.py').is_file() or (here / item / '__init__.py').is_file()
            if not (item in bound or is_module or (lazy and item in lazy)):
                wrong.append(f'{name}.{item}')
        assert len(names) == len(set(names)), f'{name}: a name listed twice'
    assert wrong == []


def test_a_star_import_gives_exactly_the_declared_names():
    """The light packages, imported for real: what `from package import *` binds."""
    for name in ('planter_ros.scene', 'planter_ros.prediction', 'planter_ros.kinematics.three_arm',
                 'planter_ros.cam', 'planter_ros.recording', 'planter_ros.kinematics'):
        assert importlib.util.find_spec(name) is not None
        space = {}
        exec(f'from {name} import *', space)  # noqa: S102
        got = {k for k in space if k != '__builtins__'}
        assert got == set(declared(ROOT.parent.joinpath(*name.split('.'), '__init__.py')))
