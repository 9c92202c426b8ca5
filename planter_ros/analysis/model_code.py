"""The code a worker of `planter analyze` runs, and its version: what decides whether a bag
analysed before must be analysed again.

The model is the import closure of the worker's task (`analysis.task`: replay and the tables it
fills), walked in the source (every `import` and `from ... import` of a module, at the top and
inside functions, relative or absolute, and `importlib.import_module` with a literal name), so a
module replay does not reach (the drives, the nodes, the command line, the bench) is not part of
it. Each module counts by its code alone: its syntax tree without docstrings (comments are not in
it, nor are line numbers), so a reworded docstring or comment, or code moved down a line, keeps
the version; any change to what runs changes it. The versions of the libraries the closure
imports (and of Python, major.minor) count too: a new numpy can change a number.
"""

import ast
from collections.abc import Callable, Iterable
import hashlib
import importlib.metadata
from pathlib import Path
import sys

__all__ = ['closure_version', 'code_digest', 'import_closure', 'library_version']

PACKAGE = 'planter_ros'


def module_path(root: Path, module: str) -> tuple[Path | None, bool]:
    """(the file of dotted `module` under `root` (the directory holding the package), whether it
    is a package's `__init__`); (None, False) for a name that is not a module (a class, a
    function imported by name)."""
    base = root.joinpath(*module.split('.'))
    if (base / '__init__.py').is_file():
        return base / '__init__.py', True
    if base.with_suffix('.py').is_file():
        return base.with_suffix('.py'), False
    return None, False


def imported_names(module: str, init: bool, tree: ast.AST, source: str | None = None
                   ) -> Iterable[str]:
    """Every dotted name `module` imports anywhere in its body (`from a import b` gives `a` and
    `a.b`: b may be a module or a name). `source`, its text: where it does not name
    import_module, its expressions are not searched for an import_module call."""
    for node in statements(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = module.split('.')
                base = parts[:len(parts) - node.level + init]
                name = '.'.join(base + ([node.module] if node.module else []))
            else:
                name = node.module or ''
            yield name
            yield from (f'{name}.{alias.name}' for alias in node.names)
    if source is not None and 'import_module' not in source:
        return
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr == 'import_module' and node.args
                and isinstance(node.args[0], ast.Constant)
                and isinstance(node.args[0].value, str)):
            yield node.args[0].value


# the fields of a node that hold statements (or the except handlers and match cases holding
# them): an import statement and a docstring are found there; expressions hold none
_BLOCKS = ('body', 'orelse', 'finalbody', 'handlers', 'cases')


def statements(tree: ast.AST) -> Iterable[ast.AST]:
    """`tree` and every statement in it, at any depth (in classes, functions, compound
    statements, except handlers and match cases, which are yielded too), not its expressions:
    a walk of a tenth of the nodes."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        for name in _BLOCKS:
            block = getattr(node, name, None)
            if isinstance(block, list):
                todo.extend(block)


def import_closure(roots: Iterable[str], root: Path) -> tuple[dict[str, ast.Module], set[str]]:
    """({module: its parsed tree} of every package module the `roots` import, directly or
    through others, with the packages holding them; the top-level names of the other modules
    they import (libraries and the standard library))."""
    trees: dict[str, ast.Module] = {}
    outside: set[str] = set()
    todo = list(roots)
    while todo:
        module = todo.pop()
        if module in trees:
            continue
        path, init = module_path(root, module)
        if path is None:
            continue
        source = path.read_text(encoding='utf-8')
        trees[module] = tree = ast.parse(source, str(path))
        parts = module.split('.')
        todo.extend('.'.join(parts[:i]) for i in range(1, len(parts)))   # its packages run first
        for name in imported_names(module, init, tree, source):
            if name.split('.')[0] == PACKAGE:
                todo.append(name)
            elif name:
                outside.add(name.split('.')[0])
    return trees, outside


def without_docstrings(tree: ast.Module) -> ast.Module:
    """`tree` with every statement that is a string constant alone removed (the docstrings of
    the module, its classes and functions, and strings used as comments): they run as nothing."""
    for node in statements(tree):
        if isinstance(node, _WITH_BODY):
            node.body = [statement for statement in node.body
                         if not (isinstance(statement, ast.Expr)
                                 and isinstance(statement.value, ast.Constant)
                                 and isinstance(statement.value.value, str))]
    return tree


# the nodes whose `body` is a list of statements
_WITH_BODY = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef, ast.For,
              ast.AsyncFor, ast.While, ast.If, ast.With, ast.AsyncWith, ast.Try, ast.TryStar,
              ast.ExceptHandler, ast.match_case)


def code_digest(tree: ast.Module) -> bytes:
    """The bytes a module's code is known by: its syntax tree without docstrings, with no
    positions (a comment or a blank line moves code, it does not change it)."""
    return ast.dump(without_docstrings(tree), include_attributes=False).encode()


def library_version(name: str) -> str:
    """The installed version(s) of the distribution(s) providing top-level module `name`, '' for
    the standard library and for a module no distribution names."""
    if name in sys.stdlib_module_names or name == '__future__':
        return ''
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        pass
    distributions = _distributions().get(name, [])
    return ','.join(f'{d}=={importlib.metadata.version(d)}' for d in sorted(set(distributions)))


_DISTRIBUTIONS: dict[str, list[str]] = {}


def _distributions() -> dict[str, list[str]]:
    # every installed distribution's metadata read (a quarter of a second): only for a module
    # whose name is not its distribution's (yaml: PyYAML)
    if not _DISTRIBUTIONS:
        _DISTRIBUTIONS.update(importlib.metadata.packages_distributions())
    return _DISTRIBUTIONS


def closure_version(roots: Iterable[str], root: Path,
                    versions: Callable[[str], str] = library_version) -> str:
    """A short hash of the code the `roots` run: each module of their import closure by its code
    (`code_digest`), the version of each library it imports (`versions` of its top-level name)
    and Python's major.minor."""
    trees, outside = import_closure(roots, root)
    digest = hashlib.sha256()
    for module in sorted(trees):
        digest.update(module.encode() + b'\0' + code_digest(trees[module]) + b'\0')
    for name in sorted(outside):
        version = versions(name)
        if version:
            digest.update(f'{name}=={version}\0'.encode())
    digest.update('python=={}.{}\0'.format(*sys.version_info[:2]).encode())
    return digest.hexdigest()[:16]
