"""Hundreds of bad inputs thrown at the command line in-process (`cli.main.main`): every one ends
in exit code 2 and exactly one line on stderr naming the value and a non-empty allowed range, no
traceback, no warning of any kind (numpy's overflow warnings included), nothing on stdout; and a
design that exists is printed without NaN or infinity."""
import contextlib
import io
import json
import math
from pathlib import Path
import re
import warnings

from hypothesis import HealthCheck, given, settings, strategies as st
import pytest
import yaml

from planter_ros.cli.main import main

REPO = Path(__file__).resolve().parents[1]
SAMPLE = str(REPO / 'bags' / 'sample_tomato.mcap')
RICE = yaml.safe_load((REPO / 'config' / 'rice_three_arm.yaml').read_text())
TOMATO = yaml.safe_load((REPO / 'config' / 'tomato_five_bar.yaml').read_text())
FUZZ = settings(deadline=None, suppress_health_check=[HealthCheck.too_slow])

# (command words before the option, option, kind, low, high): the allowed domain written out
# here, independently of the code under test, so the strategies only produce values outside it
FIVE_BAR = ['design', 'five-bar', '--depth', '0.045', '--spacing', '0.2']
OPTIONS = [
    (['design', 'five-bar', '--spacing', '0.2'], '--depth', float, 0.001, 0.5),
    (['design', 'five-bar', '--depth', '0.045'], '--spacing', float, 0.05, 2.0),
    (FIVE_BAR, '--hole-ratio', float, 1e-4, 2.0),
    (FIVE_BAR, '--speed', float, 0.01, 3.0),
    (['replay', SAMPLE], '--upright-threshold', float, 0.0, math.pi / 2),
    (['replay', SAMPLE], '--nozzle-width', float, 0.0, 0.5),
    (['replay', SAMPLE], '--window', int, 1, 10000),
    (['replay', SAMPLE], '--max-input-gap', float, 0.01, 3600.0),
    (['optimize', 'three-arm'], '--seed', int, 0, 2 ** 32 - 1),
    (['optimize', 'three-arm'], '--max-time', float, 0.01, 86400.0),
    (['demo'], '--duration', float, 8.0, 3600.0),
    (['demo'], '--seed', int, 0, 2 ** 32 - 1),
]

ODD_TEXT = ['nan', 'NaN', '-nan', 'inf', '-inf', 'Infinity', '1e309', '-1e309', '1e300',
            '-1e300', '1e-320', '5e-324', '-0', '0', '-1', '', ' ', 'abc', '0x10', '1,5', '1e',
            '--', '\n', '0.1\n0.2', '١', '½', '1_0e9', '9' * 400, '\x00', '\udcff', 'é']


def in_domain(text, kind, low, high):
    try:
        value = kind(text)
    except ValueError:
        return False
    return (kind is int or math.isfinite(value)) and low <= value <= high


def bad_text(kind, low, high):
    numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                        st.integers(-2 ** 70, 2 ** 70).map(str),
                        st.floats(-1e6, 1e6).map(lambda x: f'{x:.3e}'))
    return st.one_of(st.sampled_from(ODD_TEXT), numbers, st.text(max_size=12)).filter(
        lambda text: not in_domain(text, kind, low, high))


def run(argv):
    """main(argv) in-process: (exit code, stdout, stderr, warnings raised)."""
    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(err):
        warnings.simplefilter('always')
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue(), [str(w.message) for w in caught]


def assert_one_line_refusal(argv, code, out, err, caught):
    assert code == 2, (argv, code, err)
    assert out == '', argv
    assert err.startswith('planter: error: ') and err.endswith('\n'), (argv, err)
    assert err.count('\n') == 1 and 'Traceback' not in err, (argv, err)
    assert caught == [], (argv, caught)
    assert len(err) < 400, (argv, err)
    assert_ranges_not_empty(err)


def assert_ranges_not_empty(text):
    """'allowed a..b' has a <= b and 'allowed 0 < k < x' has x > 0."""
    number = r'(-?[\d.]+(?:e[+-]?\d+)?)'
    for low, high in re.findall(rf'allowed (?:\w+ )?{number}\.\.{number}', text):
        assert float(low) <= float(high), text
    for high in re.findall(rf'0 < k < {number}', text):
        assert float(high) > 0, text


@settings(FUZZ, max_examples=250)
@given(data=st.data())
def test_a_bad_option_value_is_one_line_and_exit_2(data):
    words, option, kind, low, high = data.draw(st.sampled_from(OPTIONS))
    text = data.draw(bad_text(kind, low, high))
    argv = words + [f'{option}={text}']          # '=' so a value may start with '-'
    assert_one_line_refusal(argv, *run(argv))


@settings(FUZZ, max_examples=150)
@given(depth=st.floats(0.001, 0.5), spacing=st.floats(0.05, 2.0), ratio=st.floats(1e-4, 2.0),
       method=st.sampled_from(['exact', 'paper']), speed=st.floats(0.01, 3.0))
def test_any_five_bar_in_range_is_a_finite_design_or_a_one_line_refusal(depth, spacing, ratio,
                                                                        method, speed):
    argv = ['design', 'five-bar', '--depth', repr(depth), '--spacing', repr(spacing),
            '--hole-ratio', repr(ratio), '--method', method, '--speed', repr(speed), '--json']
    code, out, err, caught = run(argv)
    if code == 0:       # an unusual value is a warning line (planter_ros.plausibility), no more
        assert caught == [] and all(line.startswith('planter: warning: ')
                                    for line in err.splitlines()), (argv, err, caught)

        def no_constant(name):
            raise AssertionError(f'{name} printed by {argv}')
        json.loads(out, parse_constant=no_constant)
    else:
        assert_one_line_refusal(argv, code, out, err, caught)


# values no scene key allows (wrong type, not finite, out of every range, empty, unusable)
SCENE_VALUES = ['.nan', '.inf', '-.inf', '1e999', '-1e999', '~', '{a: 1}', 'true', "''",
                'abc', '[]', '[.nan, 0.02]', '99999999999999999999999', '[abc]']


@settings(FUZZ, max_examples=100)
@given(data=st.data())
def test_a_bad_scene_value_is_one_line_and_exit_2(data, tmp_path_factory):
    out = tmp_path_factory.mktemp('out') / 'optimized.yaml'
    base, words, option = data.draw(st.sampled_from([
        (RICE, ['design', 'three-arm'], '--params'),
        (RICE, ['optimize', 'three-arm', '--max-time', '1', '--out', out], '--base'),
        (TOMATO, ['demo'], '--scene')]))
    params = base['/**']['ros__parameters']
    # the search replaces the base's radii: only their ranges matter there, not their count
    skip = ('crop', 'mechanism') + (('control_radii',) if option == '--base' else ())
    key = data.draw(st.sampled_from(sorted(k for k in params if k not in skip)))
    value = data.draw(st.sampled_from(SCENE_VALUES))
    text = yaml.safe_dump(base, default_flow_style=None, width=1_000_000)
    text = text.replace(f' {key}: ', f' {key}: {value} #', 1)
    scene = tmp_path_factory.mktemp('scene') / 'scene.yaml'
    scene.write_text(text)
    assert yaml.safe_load(text)['/**']['ros__parameters'].get(key) != params[key]
    argv = words + [option, scene]
    assert_one_line_refusal(argv, *run(argv))


@pytest.mark.parametrize('argv', [
    ['design', 'five-bar', '--depth', '1e300', '--spacing', '0.2'],
    ['design', 'five-bar', '--depth', '0.045', '--spacing', '1e300'],
    ['design', 'five-bar', '--depth', '0.045', '--spacing', '0.2', '--speed', '1e308'],
    ['design', 'five-bar', '--depth', '0.045', '--spacing', '0.2', '--hole-ratio', '1e-300'],
    ['design', 'five-bar', '--depth', '0.5', '--spacing', '0.05', '--hole-ratio', '2'],
    ['optimize', 'three-arm', '--seed', '-1'],
    ['optimize', 'three-arm', '--seed', '4294967296'],
    ['demo', '--seed', '99999999999'],
    ['design', 'five-bar', '--depth', '0.045', '--spacing', '0.2', 'a\nb'],
])
def test_the_edges_the_issue_met(argv):
    """Overflowing values, seeds outside 0..2^32-1, an empty range, a newline in an argument."""
    assert_one_line_refusal(argv, *run(argv))


def test_an_alias_bomb_is_refused_in_one_short_line(tmp_path):
    lines = ['/**:', '  ros__parameters:', '    a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol]']
    for i in range(1, 10):
        lines.append(f'    a{i}: &a{i} [' + ', '.join([f'*a{i - 1}'] * 8) + ']')
    bomb = tmp_path / 'bomb.yaml'
    bomb.write_text('\n'.join(lines) + '\n')
    for argv in (['demo', '--scene', bomb], ['design', 'three-arm', '--params', bomb]):
        code, out, err, caught = run(argv)
        assert_one_line_refusal(argv, code, out, err, caught)
        assert 'aliases expand to over' in err
    loop = tmp_path / 'loop.yaml'
    loop.write_text('/**:\n  ros__parameters: &p\n    crop: *p\n')
    argv = ['demo', '--scene', loop]
    code, out, err, caught = run(argv)
    assert_one_line_refusal(argv, code, out, err, caught)
    assert 'refers to its own anchor' in err


def test_a_huge_or_special_scene_file_is_refused_unread(tmp_path):
    big = tmp_path / 'big.yaml'
    big.write_bytes(b'#' * (2 << 20))
    for path, words in ((big, 'allowed at most 1048576 bytes'),
                        ('/dev/zero', 'not a regular file')):
        argv = ['demo', '--scene', path]
        code, out, err, caught = run(argv)
        assert_one_line_refusal(argv, code, out, err, caught)
        assert words in err


def test_anchors_and_aliases_of_ordinary_size_still_work(tmp_path):
    scene = tmp_path / 'anchors.yaml'
    scene.write_text((REPO / 'config' / 'rice_three_arm.yaml').read_text().replace(
        'arm_width: 0.02', 'arm_width: &w 0.02').replace('nozzle_width: 0.02', 'nozzle_width: *w'))
    code, out, err, caught = run(['design', 'three-arm', '--params', scene, '--json'])
    assert code == 0 and caught == [], err
    assert json.loads(out)['goals_passed'] >= 0
