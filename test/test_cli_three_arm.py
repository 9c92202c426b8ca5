"""`planter design three-arm` and `planter optimize three-arm` as a user runs them."""
import json
import math
import subprocess
import sys

import pytest

from cli_helpers import REPO, planter_here, run_planter

SCENE = REPO / 'config' / 'rice_three_arm.yaml'


def test_design_json_has_goals_centre_distance_and_residual():
    out = planter_here('design', 'three-arm', '--params', SCENE, '--json')
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    assert len(r['goals']) == 8
    for g in r['goals']:
        assert set(g) == {'name', 'value', 'lower', 'upper', 'unit', 'passed', 'basis',
                          'assumed', 'derived'}
        assert g['basis'] in ('paper', 'assumption')
    assert 0.05 < r['centre_distance'] < 0.15 and r['closure_residual'] < 1e-12
    assert (r['paper_goals_passed'], r['paper_goals']) == (3, 5)
    arms = r['paper_comparison']['arms']
    assert [a['arm'] for a in arms] == ['I', 'II', 'III']
    assert arms[1]['paper_planting_phase'] == pytest.approx(math.radians(311))
    assert abs(arms[1]['planting_phase_difference']) < math.radians(4)


def test_design_table_headlines_both_counts_and_table_1(tmp_path):
    out = planter_here('design', 'three-arm', '--params', SCENE)
    assert out.returncode == 0, out.stderr
    assert '5 of 8: 3 of 5 the paper fixes, 2 of 3 on assumptions' in out.stdout
    assert "against the paper's Table 1" in out.stdout and 'zero-slip spacing' in out.stdout
    phased = tmp_path / 'phased.yaml'
    phased.write_text(SCENE.read_text().replace(
        '    arm_width:', '    picking_phase: 0.3490658503988659\n    arm_width:'))
    out = planter_here('design', 'three-arm', '--params', phased, '--json')
    goals = {g['name']: g for g in json.loads(out.stdout)['goals']}
    assert goals['picking_angle']['value'] == pytest.approx(math.radians(30.95), abs=1e-3)


def test_each_pitch_curve_reading_from_a_scene(tmp_path):
    for name in ('bspline_polar', 'bspline_cartesian'):
        scene = tmp_path / f'{name}.yaml'
        scene.write_text(SCENE.read_text().replace('interpolant: periodic_cubic',
                                                   f'interpolant: {name}'))
        out = planter_here('design', 'three-arm', '--params', scene, '--json')
        assert out.returncode == 0, out.stderr
        assert json.loads(out.stdout)['interpolant'] == name
    bad = tmp_path / 'bezier.yaml'
    bad.write_text(SCENE.read_text().replace('interpolant: periodic_cubic', 'interpolant: bezier'))
    out = planter_here('design', 'three-arm', '--params', bad)
    assert out.returncode == 2 and 'bspline_cartesian' in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_design_table_and_plot(tmp_path):
    png = tmp_path / 'rice.png'
    out = planter_here('design', 'three-arm', '--params', SCENE, '--plot', png)
    assert out.returncode == 0, out.stderr
    assert 'picking_angle' in out.stdout and 'deg' in out.stdout and 'goals passed' in out.stdout
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_bad_scene_is_one_line_exit_2(tmp_path):
    out = planter_here('design', 'three-arm', '--params', REPO / 'config' / 'tomato_five_bar.yaml')
    assert out.returncode == 2 and 'three_arm' in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1
    bad = tmp_path / 'bad.yaml'
    bad.write_text(SCENE.read_text().replace('arm_length: 0.145', 'arm_length: -0.1'))
    out = planter_here('design', 'three-arm', '--params', bad)
    assert out.returncode == 2 and 'arm_length' in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_optimize_writes_a_params_file_design_reads(tmp_path):
    target = tmp_path / 'opt.yaml'
    out = planter_here('optimize', 'three-arm', '--seed', 2, '--max-time', 2, '--workers', 1,
                       '--out', target)
    assert out.returncode == 0, out.stderr
    assert 'best so far' in out.stderr
    again = planter_here('design', 'three-arm', '--params', target, '--json')
    assert again.returncode == 0, again.stderr
    assert len(json.loads(again.stdout)['goals']) == 8


def test_optimize_without_out_prints_the_scene_on_stdout_and_writes_nothing(tmp_path):
    """`planter optimize three-arm > rice.yaml`: stdout is the scene file alone, the report
    goes to stderr, and the working directory stays empty."""
    out = run_planter('optimize', 'three-arm', '--seed', 2, '--max-time', 2, '--workers', 1,
                      cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert list(tmp_path.iterdir()) == []
    assert out.stdout.startswith('# written by `planter optimize three-arm --seed 2`')
    assert 'goals passed' in out.stderr and 'search:' in out.stderr
    (tmp_path / 'rice.yaml').write_text(out.stdout)
    again = planter_here('design', 'three-arm', '--params', tmp_path / 'rice.yaml', '--json')
    assert again.returncode == 0, again.stderr
    assert len(json.loads(again.stdout)['goals']) == 8


def test_optimize_two_workers_give_the_one_worker_result(tmp_path):
    one, two = tmp_path / 'one.yaml', tmp_path / 'two.yaml'
    for target, workers in ((one, 1), (two, 2)):
        out = run_planter('optimize', 'three-arm', '--seed', 3, '--max-time', 1000, '--workers',
                          workers, '--out', target)
        assert out.returncode == 0, out.stderr
        assert 'best so far' in out.stderr and 'most goals 8/8' in out.stderr
        assert f"on {workers} process" in out.stdout and '8 of 8' in out.stdout
    strip = [[line for line in f.read_text().splitlines() if not line.startswith('#')]
             for f in (one, two)]
    assert strip[0] == strip[1]


@pytest.mark.parametrize('args, needle', [
    (['--workers', '0'], '--workers'),
    (['--max-time', 'nan'], '--max-time'),
])
def test_optimize_bad_options_are_one_line_exit_2(args, needle):
    out = planter_here('optimize', 'three-arm', *args)
    assert out.returncode == 2 and needle in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_optimize_refuses_a_curve_it_cannot_batch(tmp_path):
    base = tmp_path / 'cartesian.yaml'
    base.write_text(SCENE.read_text().replace('interpolant: periodic_cubic',
                                              'interpolant: bspline_cartesian'))
    out = planter_here('optimize', 'three-arm', '--base', base, '--out', tmp_path / 'x.yaml')
    assert out.returncode == 2 and 'bspline_cartesian' in out.stderr
    assert 'periodic_cubic' in out.stderr and len(out.stderr.strip().splitlines()) == 1


def test_five_bar_never_imports_three_arm():
    code = ('import sys; from planter_ros.cli.main import main; '
            'main(["design", "five-bar", "--depth", "0.045", "--spacing", "0.2", "--json"]); '
            'heavy = [m for m in sys.modules '
            'if "three_arm" in m and not m.startswith("planter_ros.cli")]; '
            'assert not heavy, heavy')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, cwd=REPO)
    assert out.returncode == 0, out.stderr
