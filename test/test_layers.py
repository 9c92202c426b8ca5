"""The package is built in layers (doc/architecture.md): a module imports only from its own layer
or the layers below it, and no two packages import each other, directly or round a circle.

Every import of every module counts, at the top or inside a function (`import`, `from ... import`,
relative or absolute, `importlib.import_module('...')` with a literal name): the ones inside
functions load late, but they still tie the packages together."""
import ast
from collections import defaultdict

from cli_helpers import REPO

PACKAGE = 'planter_ros'

# bottom to top; a package may import its own layer and every layer below (the one declaration:
# doc/architecture.md shows it and says what lives where)
LAYERS = (
    ('errors', 'config', 'interfaces', 'output_files', 'host', 'diagnostics', 'safe_yaml',
     'shipped', 'dependencies'),      # base: pure declarations and helpers; the host's plumbing
    ('geo', 'rows'),
    ('kinematics', 'drive', 'sensing'),            # core models
    ('design', 'simdrive'),                        # the typed design; simulated drives
    ('prediction',),                               # per-plant predictions from motion
    ('cam', 'control'),                            # cam planning; the sync law, the row loop
    ('recording', 'optimize', 'sim', 'command',    # command: the command process
     'plausibility'),
    ('scene',),                                    # knows every node's configuration
    ('nodes', 'analysis', 'commission'),           # commission: drive + machine file
    ('demo', 'export'),                            # export: of a replay and of a season
    ('bench',),
    ('plots',),
    ('cli',),                                      # nothing imports the command line
)
LAYER = {name: i for i, names in enumerate(LAYERS) for name in names}


def modules():
    """(dotted module name, is a package __init__, path) of every module of the package."""
    root = REPO / PACKAGE
    for path in sorted(root.rglob('*.py')):
        parts = path.relative_to(REPO).with_suffix('').parts
        init = parts[-1] == '__init__'
        yield '.'.join(parts[:-1] if init else parts), init, path


def imported(module, init, tree):
    """Every planter_ros module name `module` imports, anywhere in its body."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split('.')[:len(module.split('.')) - node.level + init]
                name = '.'.join(base + ([node.module] if node.module else []))
            else:
                name = node.module
            yield name
            yield from (f'{name}.{alias.name}' for alias in node.names)
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr == 'import_module' and node.args
              and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)):
            yield node.args[0].value


def top(name):
    """The package (or top-level module) of planter_ros a dotted name is in, else None."""
    parts = name.split('.')
    if parts[0] != PACKAGE or len(parts) < 2:
        return None
    return parts[1]


def edges():
    """{(from package, to package): [module -> imported name, ...]} across packages."""
    known = {top(module) for module, _, _ in modules()} - {None}
    out = defaultdict(list)
    for module, init, path in modules():
        source = top(module)
        for name in imported(module, init, ast.parse(path.read_text(), str(path))):
            target = top(name or '')
            if source in known and target in known and target != source:
                out[(source, target)].append(f'{module} -> {name}')
    return out


def test_every_package_has_a_layer():
    found = {top(module) for module, _, _ in modules()} - {None}
    assert sorted(found - set(LAYER)) == [], 'declare the layer of these in LAYERS'


def test_no_import_runs_up_the_layers():
    upward = [f'{via[0]} ({source}: layer {LAYER[source]} imports {target}: layer '
              f'{LAYER[target]})' for (source, target), via in sorted(edges().items())
              if LAYER.get(target, -1) > LAYER.get(source, -1)]
    assert upward == []


def test_no_packages_import_each_other_in_a_circle():
    graph = defaultdict(set)
    for source, target in edges():
        graph[source].add(target)
    cycles = [sorted(c) for c in strongly_connected(graph) if len(c) > 1]
    assert cycles == [], {tuple(c): [v for (s, t), v in edges().items() if s in c and t in c]
                          for c in map(tuple, cycles)}


def strongly_connected(graph):
    """Tarjan's strongly connected components of {node: {successors}}."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            out.append(component)

    for v in list(graph):
        if v not in index:
            visit(v)
    return out


def test_the_walk_sees_imports_inside_functions_and_relative_ones():
    """The test itself: a late import and a relative one are found (so a cycle hidden in a
    function cannot pass unseen)."""
    tree = ast.parse('def f():\n    from planter_ros.cli.main import main\n'
                     'from ..scene import open_scene\n')
    names = set(imported('planter_ros.demo.run', False, tree))
    assert {'planter_ros.cli.main', 'planter_ros.scene', 'planter_ros.scene.open_scene'} <= names


def test_the_layers_are_the_ones_the_architecture_page_shows():
    page = (REPO / 'doc' / 'architecture.md').read_text()
    for i, names in enumerate(LAYERS):
        row = f'| {i} | ' + ', '.join(f'`{name}`' for name in names) + ' |'
        assert row in page, f'doc/architecture.md lacks the row starting {row!r}'


def test_the_command_line_only_parses_and_calls():
    """cli/ parses arguments and calls the packages: all of it stays within 1000 lines (the
    house issue's budget), so logic that grows goes where it can be tested alone."""
    lines = sum(len(p.read_text().splitlines())
                for p in (REPO / 'planter_ros' / 'cli').glob('*.py'))
    assert lines <= 1000, f'planter_ros/cli/ has {lines} lines'


def test_no_modules_import_each_other_in_a_circle():
    """Inside a package too, modules depend one way (a package's __init__, which gathers its
    modules' names, is left out)."""
    names = {module for module, init, _ in modules() if not init}
    graph = defaultdict(set)
    for module, init, path in modules():
        if init:
            continue
        for name in imported(module, init, ast.parse(path.read_text(), str(path))):
            target = name if name in names else (name or '').rpartition('.')[0]
            if target in names and target != module:
                graph[module].add(target)
    cycles = [sorted(c) for c in strongly_connected(graph) if len(c) > 1]
    assert cycles == []
