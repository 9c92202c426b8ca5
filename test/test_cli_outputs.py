"""Output files are checked before any work and written atomically: a path into a missing
directory, onto a directory, into a read-only place or with an unsupported extension is one line
and exit 2 before the command starts; a failed write never replaces the user's file."""
import contextlib
import io
import os
from pathlib import Path
import stat
import tempfile

import pytest

from planter_ros.cli.main import main
from planter_ros.output_files import OutputError, atomic_output, check_output

REPO = Path(__file__).resolve().parents[1]
SAMPLE = str(REPO / 'bags' / 'sample_tomato.mcap')
FIVE_BAR = ['design', 'five-bar', '--depth', '0.045', '--spacing', '0.2']
RICE = str(REPO / 'config' / 'rice_three_arm.yaml')

# (command without the output option, option, a good file name)
WRITERS = [
    (FIVE_BAR, '--plot', 'x.png'),
    (['design', 'three-arm', '--params', RICE], '--plot', 'x.png'),
    (['optimize', 'three-arm', '--max-time', '5'], '--out', 'x.yaml'),
    (['replay', SAMPLE], '--plot', 'x.png'),
    (['bench', '--quick'], '--plot', 'x.png'),
    (['bench', '--quick'], '--markdown', 'x.md'),
    (['demo', '--duration', '8'], '--bag', 'x.mcap'),
    (['demo', '--duration', '8'], '--bag', 'bag_dir'),
]


def run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def read_only_directory(tmp_path):
    """A directory this process cannot create files in (a chmod'ed one; as root, where
    permissions do not bind, a kernel directory that refuses new files)."""
    ro = tmp_path / 'read-only'
    ro.mkdir()
    ro.chmod(stat.S_IRUSR | stat.S_IXUSR)
    for candidate in (ro, Path('/sys'), Path('/proc')):
        try:
            fd, probe = tempfile.mkstemp(dir=candidate)
        except OSError:
            return candidate
        os.close(fd)
        os.unlink(probe)
    pytest.skip('no read-only directory available to this user')


@pytest.mark.parametrize('words, option, name', WRITERS, ids=lambda v: str(v)[:20])
def test_an_unwritable_output_is_refused_before_any_work(words, option, name, tmp_path):
    (tmp_path / 'a_dir.png').mkdir()
    (tmp_path / 'a_dir.yaml').mkdir()
    (tmp_path / 'a_dir.md').mkdir()
    (tmp_path / 'a_dir.mcap').mkdir()
    onto_a_directory = tmp_path / f'a_dir{Path(name).suffix or ".mcap"}'
    bad = {
        'does not exist': tmp_path / 'missing' / name,
        'is a directory' if option != '--bag' else 'exists': onto_a_directory,
        'not writable': read_only_directory(tmp_path) / name,
        'unsupported extension': tmp_path / 'x.txt',
    }
    for words_expected, path in bad.items():
        code, out, err = run(words + [option, path])
        assert code == 2, (option, path, err)
        assert out == '' and err.count('\n') == 1, (option, path, out, err)
        assert words_expected in err and option in err, err
    assert not (tmp_path / 'missing').exists()


def test_optimize_with_a_bad_base_fails_before_the_search_and_keeps_the_old_out(tmp_path):
    out = tmp_path / 'out.yaml'
    out.write_text('# my own scene\n')
    base = tmp_path / 'base.yaml'
    base.write_text(Path(RICE).read_text().replace('plant_spacing: 0.18', 'plant_spacing: 1e9'))
    code, stdout, err = run(['optimize', 'three-arm', '--base', base, '--out', out])
    assert code == 2 and 'plant_spacing = 1e+09 is out of range' in err
    assert 'gen' not in err                          # no search progress: it never started
    reversed_angles = tmp_path / 'reversed.yaml'
    reversed_angles.write_text(Path(RICE).read_text().replace(
        'control_angles: [0.3490658503988659, 0.7853981633974483',
        'control_angles: [0.7853981633974483, 0.3490658503988659'))
    code, stdout, err = run(['optimize', 'three-arm', '--base', reversed_angles, '--out', out])
    assert code == 2 and 'control_angles' in err and 'gen' not in err
    assert out.read_text() == '# my own scene\n'


def test_a_plot_that_fails_midway_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    png = tmp_path / 'design.png'
    png.write_bytes(b'old picture')
    png.chmod(0o640)

    def broken(design, path, ground_speed=None):
        Path(path).write_bytes(b'half a pic')
        raise OutputError('disk full')
    monkeypatch.setattr('planter_ros.plots.five_bar.plot_design', broken)
    code, _, err = run(FIVE_BAR + ['--plot', png])
    assert code == 2 and 'disk full' in err
    assert png.read_bytes() == b'old picture'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['design.png']
    monkeypatch.undo()
    code, _, _ = run(FIVE_BAR + ['--plot', png])
    assert code == 0 and png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert stat.S_IMODE(png.stat().st_mode) == 0o640           # the user's mode is kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ['design.png']


def test_atomic_output_replaces_only_on_success(tmp_path):
    target = tmp_path / 'page.md'
    target.write_text('old')
    with pytest.raises(RuntimeError):
        with atomic_output(target) as tmp:
            assert tmp.parent == tmp_path and tmp.suffix == '.md'
            tmp.write_text('partial')
            raise RuntimeError('interrupted')
    assert target.read_text() == 'old' and len(list(tmp_path.iterdir())) == 1
    with atomic_output(target) as tmp:
        tmp.write_text('new')
    assert target.read_text() == 'new' and len(list(tmp_path.iterdir())) == 1


def test_check_output_refuses_special_and_read_only_files(tmp_path):
    with pytest.raises(OutputError, match='not a regular file'):
        check_output('/dev/null', '--plot', ('',))
    ro = tmp_path / 'ro.png'
    ro.write_bytes(b'x')
    ro.chmod(0o444)
    if os.access(ro, os.W_OK):
        pytest.skip('permissions do not bind this user (root)')
    with pytest.raises(OutputError, match='read-only file'):
        check_output(ro, '--plot', ('.png',))


def test_the_demo_checks_its_default_bag_place_too(tmp_path, monkeypatch):
    monkeypatch.chdir(read_only_directory(tmp_path))
    code, out, err = run(['demo', '--duration', '8'])
    assert code == 2 and out == '' and err.count('\n') == 1
    assert '--bag (default) = bags/planter_<date-time>' in err and 'not writable' in err
