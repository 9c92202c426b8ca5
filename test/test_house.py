"""The house's own measures (doc/architecture.md, "Reading the code"): what a newcomer meets in
every module. Imports at the top of a module, each one left inside a function with its written
reason (`# lazy: ...` on its line or the line before); few functions with many parameters (a
concept with no name yet); no class owning so much state that it runs over 400 lines."""
import ast

import pytest

from cli_helpers import REPO

PACKAGE = REPO / 'planter_ros'
INSIDE_SHARE = 0.05          # of all imports, at most this share inside functions
MANY_PARAMETERS = 7          # a function taking this many (self/cls not counted) ...
AT_MOST_MANY = 10            # ... at most this many such functions in the package
CLASS_LINES = 400


def _modules():
    for path in sorted(PACKAGE.rglob('*.py')):
        text = path.read_text()
        yield path.relative_to(REPO), text.splitlines(), ast.parse(text)


def _walk(node, inside, found):
    """found: lists 'top', 'inside' (import nodes), 'functions', 'classes'."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, (ast.Import, ast.ImportFrom)):
            found['inside' if inside else 'top'].append(child)
        if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
            found['functions'].append(child)
            _walk(child, True, found)
        elif isinstance(child, ast.ClassDef):
            found['classes'].append(child)
            _walk(child, inside, found)
        else:
            _walk(child, inside, found)


def _parameters(function):
    arguments = function.args
    positional = arguments.posonlyargs + arguments.args
    count = (len(positional) + len(arguments.kwonlyargs) + bool(arguments.vararg)
             + bool(arguments.kwarg))
    return count - bool(positional and positional[0].arg in ('self', 'cls'))


def _comment_above(lines, lineno):
    """The comment lines right above line `lineno` (1-based), nearest first."""
    above = []
    for line in reversed(lines[:lineno - 1]):
        if not line.strip().startswith('#'):
            break
        above.append(line.strip())
    return above


def _explained(lines, tree):
    """The line numbers of the imports that carry a `# lazy:` reason: on their line, in the
    comment block right above them, or above the run of imports they are part of."""
    explained = set()
    for node in ast.walk(tree):
        for field in ('body', 'orelse', 'finalbody'):
            statements = getattr(node, field, None)
            previous = None
            for statement in statements if isinstance(statements, list) else ():
                if isinstance(statement, (ast.Import, ast.ImportFrom)):
                    block = _comment_above(lines, statement.lineno)
                    if ('# lazy:' in lines[statement.lineno - 1]
                            or any(line.startswith('# lazy:') for line in block)
                            or (previous in explained and not block)):
                        explained.add(statement.lineno)
                    previous = statement.lineno
                else:
                    previous = None
    return explained


def _survey():
    top, inside, unexplained, many, big = 0, 0, [], [], []
    for path, lines, tree in _modules():
        found = {'top': [], 'inside': [], 'functions': [], 'classes': []}
        _walk(tree, False, found)
        top += len(found['top'])
        inside += len(found['inside'])
        explained = _explained(lines, tree)
        unexplained += [f'{path}:{node.lineno}' for node in found['inside']
                        if node.lineno not in explained]
        many += [f'{path}:{f.lineno} {f.name} ({_parameters(f)})' for f in found['functions']
                 if _parameters(f) >= MANY_PARAMETERS]
        big += [f'{path}:{c.lineno} {c.name} ({c.end_lineno - c.lineno + 1} lines)'
                for c in found['classes'] if c.end_lineno - c.lineno + 1 > CLASS_LINES]
    return top, inside, unexplained, many, big


@pytest.fixture(scope='module')
def survey():
    """The package read once for the tests below (in the process that runs them: every test
    process collects this module, few run it)."""
    return _survey()


def test_imports_are_at_the_top_and_each_one_left_inside_says_why(survey):
    top, inside, unexplained, _, _ = survey
    share = inside / (top + inside)
    assert share <= INSIDE_SHARE, f'{inside} of {top + inside} imports inside functions ' \
        f'({share:.1%} > {INSIDE_SHARE:.0%})'
    assert not unexplained, 'imports inside functions without a `# lazy:` reason: ' + \
        ', '.join(unexplained)


def test_few_functions_take_seven_or_more_parameters(survey):
    many = survey[3]
    assert len(many) <= AT_MOST_MANY, f'{len(many)} functions with >= {MANY_PARAMETERS} ' \
        f'parameters (at most {AT_MOST_MANY}): ' + '; '.join(many)


def test_no_class_runs_over_400_lines(survey):
    assert not survey[4], survey[4]


def test_the_survey_sees_what_it_counts(tmp_path):
    """The counting itself, on a module written here: one import inside a function with its
    reason (two imports under one two-line reason), one without after other code, a
    seven-parameter method (self not counted) and a six-parameter one."""
    source = ('import os\n'
              'def f(a, b, c, d, e, f, g):\n'
              '    # lazy: a reason that runs\n'
              '    # over two lines\n'
              '    import json\n'
              '    import csv\n'
              '    x = 1\n'
              '    import re\n'
              'class C:\n'
              '    def m(self, a, b, c, d, e, f):\n'
              '        pass\n')
    tree = ast.parse(source)
    found = {'top': [], 'inside': [], 'functions': [], 'classes': []}
    _walk(tree, False, found)
    assert (len(found['top']), len(found['inside'])) == (1, 3)
    assert [_parameters(f) for f in found['functions']] == [7, 6]
    assert sorted(_explained(source.splitlines(), tree)) == [5, 6]       # not `re`
