"""The model version (the re-run key of `planter analyze`) changes with what can change a replay's
result and with nothing else: a docstring, a comment or an edit in a package replay does not
import keeps it (no season analysed again for nothing), any change of the model's code or of a
library it imports changes it (no season kept that the new code would read differently)."""
from pathlib import Path
import shutil

import pytest

from planter_ros.analysis import model_code
from planter_ros.analysis.task import model_version

from cli_helpers import REPO

TASK = 'planter_ros.analysis.task'


@pytest.fixture
def package(tmp_path):
    """A copy of the package's sources: the root holding it."""
    shutil.copytree(REPO / 'planter_ros', tmp_path / 'planter_ros',
                    ignore=shutil.ignore_patterns('__pycache__'))
    return tmp_path


def version(root, versions=lambda name: '1.0'):
    return model_code.closure_version([TASK], root, versions)


@pytest.fixture(scope='module')
def unedited(tmp_path_factory):
    """The version of an unedited copy of the package: what each test's edited copy (another
    directory: the version does not depend on where the sources are, or the tests that keep
    it fail) is compared with, worked out once."""
    root = tmp_path_factory.mktemp('unedited')
    shutil.copytree(REPO / 'planter_ros', root / 'planter_ros',
                    ignore=shutil.ignore_patterns('__pycache__'))
    return version(root)


def edit(root, relative, old, new):
    path = root / 'planter_ros' / relative
    text = path.read_text()
    assert text.count(old) >= 1, f'{relative} no longer holds {old!r}'
    path.write_text(text.replace(old, new, 1))


def test_the_closure_is_what_replay_imports_and_not_the_rest():
    trees, outside = model_code.import_closure([TASK], REPO)
    for module in ('planter_ros.recording.replay', 'planter_ros.recording.cdr',
                   'planter_ros.prediction.model', 'planter_ros.prediction',
                   'planter_ros.kinematics.five_bar', 'planter_ros.sensing.plant_map',
                   'planter_ros.analysis.tables', 'planter_ros'):
        assert module in trees
    for package in ('drive', 'command', 'nodes', 'cli', 'bench', 'demo', 'plots', 'sim',
                    'optimize', 'commission', 'export', 'scene'):
        assert not [m for m in trees if m.startswith(f'planter_ros.{package}')], package
    assert {'numpy', 'scipy', 'mcap', 'pyproj'} <= outside


def test_the_shipped_version_is_the_closure_of_the_task():
    assert model_version() == model_code.closure_version(
        [TASK], Path(model_code.__file__).resolve().parents[2])


def test_docstrings_comments_and_blank_lines_keep_the_version(package, unedited):
    before = unedited
    edit(package, 'prediction/model.py', '"""', '"""A reworded docstring. ')
    edit(package, 'recording/replay.py', '\nimport ', '\n# a new comment\n\n\nimport ')
    # a docstring of a function inside (not the module's)
    path = package / 'planter_ros' / 'recording' / 'cdr.py'
    text = path.read_text()
    inner = text.index('    """', text.index('\ndef '))
    path.write_text(text[:inner] + '    """Reworded.\n    """\n' + text[inner:])
    assert version(package) == before


def test_an_edit_in_a_package_replay_does_not_import_keeps_the_version(package, unedited):
    before = unedited
    edit(package, 'drive/cia402.py', '\nimport ', '\nANSWER = 42\nimport ')
    edit(package, 'nodes/monitor_node.py', '\nimport ', '\nANSWER = 42\nimport ')
    assert version(package) == before


@pytest.mark.parametrize('relative', ['prediction/model.py', 'recording/cdr.py',
                                      'kinematics/five_bar.py', 'analysis/tables.py'])
def test_a_change_of_the_models_code_changes_the_version(package, relative, unedited):
    before = unedited
    edit(package, relative, '\nimport ', '\nANSWER = 42\nimport ')
    assert version(package) != before


def test_a_changed_constant_changes_the_version(package, unedited):
    """Not only a new statement: one number of the model changed."""
    before = unedited
    path = package / 'planter_ros' / 'prediction' / 'quality.py'
    text = path.read_text()
    assert 'MULTIPLE_LIMIT = 0.5 ' in text
    path.write_text(text.replace('MULTIPLE_LIMIT = 0.5 ', 'MULTIPLE_LIMIT = 0.51 ', 1))
    assert version(package) != before


def test_a_new_module_the_model_imports_counts(package, unedited):
    before = unedited
    (package / 'planter_ros' / 'prediction' / 'extra.py').write_text('FACTOR = 2\n')
    assert version(package) == before           # not imported: not part of the model
    edit(package, 'prediction/model.py', '\nimport ', '\nfrom . import extra  # noqa\nimport ')
    changed = version(package)
    assert changed != before
    (package / 'planter_ros' / 'prediction' / 'extra.py').write_text('FACTOR = 3\n')
    assert version(package) != changed


def test_a_library_version_changes_the_version(package, unedited):
    before = unedited
    assert version(package, lambda name: '2.0' if name == 'numpy' else '1.0') != before
    # canopen: the drives' library, which replay does not import
    assert 'canopen' not in model_code.import_closure([TASK], package)[1]
    assert version(package, lambda name: '2.0' if name == 'canopen' else '1.0') == before


def test_a_library_is_known_by_its_distribution():
    import numpy
    import yaml
    assert model_code.library_version('numpy') == numpy.__version__
    assert model_code.library_version('yaml') == f'PyYAML=={yaml.__version__}'
    assert model_code.library_version('json') == ''
