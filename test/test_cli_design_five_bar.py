"""`planter design five-bar` as a user runs it: JSON, table, plot, and one-line errors."""
import json
import math

import pytest

from cli_helpers import run_planter

TOMATO = ['design', 'five-bar', '--depth', '0.045', '--spacing', '0.2']


def test_json_has_the_contract_keys_in_si_units():
    out = run_planter(*TOMATO, '--hole-ratio', '0.05', '--speed', '0.2', '--json')
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    for key in ('l1', 'l2', 'l3', 'l4', 'l5', 'hole_width', 'method', 'sun_bar_speed',
                'assemblable', 'min_transmission_angle'):
        assert key in r
    assert r['method'] == 'exact'
    assert r['l1'] == pytest.approx(0.11294, abs=1e-5)
    assert r['hole_width'] == pytest.approx(0.05 * 0.045, rel=1e-12)
    assert r['sun_bar_speed'] == pytest.approx(2 * math.pi, rel=1e-12)
    assert r['assemblable'] is True
    assert 0 < r['min_transmission_angle'] < math.pi / 2


def test_paper_method_and_no_speed():
    r = json.loads(run_planter(*TOMATO, '--method', 'paper', '--json').stdout)
    assert r['method'] == 'paper' and 'sun_bar_speed' not in r
    assert r['l3'] * 1000 == pytest.approx(365, abs=1)


def test_table_is_in_mm_and_degrees():
    out = run_planter(*TOMATO, '--speed', '0.2')
    assert out.returncode == 0
    assert '112.938 mm' in out.stdout and 'deg' in out.stdout and 'r/min' in out.stdout


def test_plot_writes_a_png(tmp_path):
    path = tmp_path / 'tomato.png'
    out = run_planter(*TOMATO, '--plot', path)
    assert out.returncode == 0, out.stderr
    data = path.read_bytes()
    assert data[:8] == b'\x89PNG\r\n\x1a\n' and len(data) > 20000


@pytest.mark.parametrize('args, needle', [
    (['--depth', '0.045', '--spacing', '0.2', '--hole-ratio', '5'], '--hole-ratio'),
    (['--depth', '0.045', '--spacing', '0.2', '--hole-ratio', '2'], 'l1 > 0'),
    (['--depth', '-1', '--spacing', '0.2'], 'depth'),
    (['--depth', 'nan', '--spacing', '0.2'], 'depth'),
    (['--depth', '0.045', '--spacing', 'inf'], 'spacing'),
    (['--depth', 'abc', '--spacing', '0.2'], '--depth'),
    (['--spacing', '0.2'], '--depth'),
    (['--depth', '0.045', '--spacing', '0.2', '--method', 'guess'], '--method'),
    (['--depth', '0.045', '--spacing', '0.2', '--speed', '-0.1'], '--speed'),
    (['--depth', '0.045', '--spacing', '0.2', '--plot', 'out.pdf'], '--plot'),
])
def test_bad_input_is_one_line_on_stderr_with_exit_code_2(args, needle):
    out = run_planter('design', 'five-bar', *args)
    assert out.returncode == 2
    assert out.stdout == ''
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and 'Traceback' not in out.stderr
