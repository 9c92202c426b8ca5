"""`planter cam five-bar`: its JSON (SI, every key a consumer reads), its table, its plot, and
bad input refused in one line with exit code 2 before any work."""
import json
import math

import pytest

from test_cli_bad_input import assert_one_line_refusal, run

BASE = ['cam', 'five-bar', '--depth', '0.045', '--design-spacing', '0.15']
GOOD = BASE + ['--spacing', '0.15,0.4', '--speed', '0.3']


@pytest.fixture(scope='module')
def result():
    code, out, err, caught = run(GOOD + ['--json'])
    assert code == 0, err
    assert caught == []
    return json.loads(out)


def test_json_has_the_mechanism_limits_and_per_case_figures_in_si(result):
    assert set(result) == {'mechanism', 'rule', 'drive', 'limits', 'drive_source', 'cases',
                           'top_speeds'}
    m = result['mechanism']
    assert m['design_hole'] == pytest.approx(0.05 * 0.045, rel=1e-9)
    assert {'l1', 'l2', 'depth', 'design_spacing', 'hole_ratio', 'nozzle_width'} <= set(m)
    assert result['rule'] == 'design_speed'
    assert result['drive']['gear_ratio'] == 20.0
    assert result['limits']['sun_bar_speed'] == pytest.approx(6000 * 2 * math.pi / 60 / 20)
    assert 'SGM7J-08A' in result['drive_source']
    assert [(c['spacing'], c['ground_speed']) for c in result['cases']] == [(0.15, 0.3),
                                                                           (0.4, 0.3)]
    for case in result['cases']:
        for key in ('constant', 'cam'):
            p = case[key]
            assert {'law', 'tip_sweep', 'hole_width', 'tilt', 'loads', 'sweep_check',
                    'feasible'} <= set(p)
            assert {'peak_sun_bar_speed', 'peak_sun_bar_acceleration', 'peak_sun_bar_jerk',
                    'peak_motor_torque', 'rms_motor_torque', 'peak_sun_bar_torque',
                    'utilisation', 'feasible', 'binding'} <= set(p['loads'])
            assert p['sweep_check']['samples_per_revolution'] >= 100_000
            assert p['sweep_check']['error'] <= 1e-6
        cam = case['cam']
        assert {'rule', 'blend', 'blend_of', 'blended_with', 'binding', 'rule_exceeds',
                'rule_loads', 'plan_time'} <= set(cam)
        assert cam['feasible'] and cam['blend'] == 1.0
        assert cam['tip_sweep'] == pytest.approx(0.00225, abs=1e-9)
        assert abs(cam['tilt']) <= 1e-9                        # rad, not degrees
    wide = result['cases'][1]['constant']
    assert wide['tip_sweep'] > 0.05 and math.radians(25) < wide['tilt'] < math.radians(35)
    for t in result['top_speeds']:
        assert set(t) == {'spacing', 'zero_slip', 'design_speed', 'constant'}
        assert 0.0 < t['zero_slip']['ground_speed'] < t['design_speed']['ground_speed']


def test_the_table_shows_both_profiles_the_limits_and_the_check_beside_the_time():
    code, out, err, _ = run(GOOD + ['--nozzle-width', '0.01', '--rule', 'zero-slip'])
    assert code == 0, err
    assert 'constant speed' in out and 'cam: exact zero slip' in out
    assert 'sweep check' in out and ' ms ' in out
    assert 'rad/s³' in out and 'N·m' in out and 'SGM7J-08A' in out
    assert '10.0000' in out                          # the hole: a point + the 10 mm nozzle
    assert 'up to what ground speed' in out


def test_a_drive_that_cannot_follow_is_reported_not_refused():
    code, out, err, _ = run(BASE + ['--spacing', '0.3', '--speed', '0.6', '--max-speed', '20',
                                    '--json'])
    assert code == 0, err
    cam = json.loads(out)['cases'][0]['cam']
    assert cam['feasible'] and cam['blend'] < 1.0 and cam['rule_exceeds'] == ['speed']
    assert cam['binding'] == 'speed' and cam['blended_with'] == 'constant speed'


def test_the_plot_is_written(tmp_path):
    plot = tmp_path / 'cam.png'
    code, out, err, caught = run(BASE + ['--spacing', '0.15,0.5', '--speed', '0.3,0.5',
                                         '--plot', plot])
    assert code == 0, err
    assert caught == []
    assert plot.stat().st_size > 50_000 and f'plot: {plot}' in out
    assert not list(tmp_path.glob('.*.tmp'))


BAD = [
    (['--spacing', '0.15,abc', '--speed', '0.3'], '--spacing = abc is not a number'),
    (['--spacing', '0.01', '--speed', '0.3'], '--spacing = 0.01 is out of range'),
    (['--spacing', '', '--speed', '0.3'], '--spacing'),
    (['--spacing', ','.join(['0.2'] * 21), '--speed', '0.3'], 'allowed 1..20'),
    (['--spacing', '0.2', '--speed', '0.3,nan'], '--speed = nan'),
    (['--spacing', '0.2', '--speed', '4'], '--speed = 4 is out of range'),
    (['--spacing', '0.2', '--speed', '0.3', '--rule', 'fast'], '--rule = fast'),
    (['--spacing', '0.2', '--speed', '0.3', '--gear-ratio', '0'], '--gear-ratio = 0'),
    (['--spacing', '0.2', '--speed', '0.3', '--gearbox-efficiency', '1.5'],
     '--gearbox-efficiency = 1.5'),
    (['--spacing', '0.2', '--speed', '0.3', '--tip-mass', '-1'], '--tip-mass = -1'),
    (['--spacing', '0.2', '--speed', '0.3', '--nozzle-width', '0.9'], '--nozzle-width = 0.9'),
    (['--spacing', '0.2', '--speed', '0.3', '--plot', 'x.jpg'], 'png'),
    (['--spacing', '0.2', '--speed', '0.3', '--hole-ratio', '2.5'], '--hole-ratio = 2.5'),
    (['--spacing', '0.2', '--speed', '0.3', '--design-spacing', '0.06', '--hole-ratio', '1.9'],
     'hole_ratio = 1.9'),
    # limits no drive has: a jerk or acceleration limit so small the arc's linear programme
    # cannot be solved (was a traceback), a rated torque above the peak torque (was accepted)
    (['--spacing', '0.3', '--speed', '0.3', '--max-jerk', '1e-6'], 'max_jerk = 1e-06'),
    (['--spacing', '0.3', '--speed', '0.3', '--max-acceleration', '1e-6'],
     'max_acceleration = 1e-06'),
    (['--spacing', '0.3', '--speed', '0.3', '--motor-rated-torque', '20'],
     'motor_rated_torque = 20 is out of range: allowed <= motor_peak_torque = 8.36'),
]


@pytest.mark.parametrize('extra, text', BAD)
def test_bad_input_is_refused_in_one_line(extra, text):
    argv = BASE + extra
    code, out, err, caught = run(argv)
    assert_one_line_refusal(argv, code, out, err, caught)
    assert text in err and 'allowed' in err


def test_a_spacing_shorter_than_the_soil_arc_is_refused_in_one_line():
    argv = ['cam', 'five-bar', '--depth', '0.1', '--design-spacing', '1.5', '--hole-ratio',
            '0.3', '--spacing', '0.05', '--speed', '0.3']
    code, out, err, caught = run(argv)
    assert_one_line_refusal(argv, code, out, err, caught)
    assert 'spacing = 0.05 is out of range' in err


def test_required_options_are_named():
    code, out, err, caught = run(['cam', 'five-bar', '--depth', '0.045'])
    assert_one_line_refusal(['cam'], code, out, err, caught)
    assert '--design-spacing' in err


@pytest.mark.parametrize('extra', [['--max-jerk', '1'], ['--max-acceleration', '0.1'],
                                   ['--gear-ratio', '1000'], ['--rotor-inertia', '10']])
def test_the_least_and_largest_limits_allowed_give_a_report_not_a_traceback(extra):
    code, out, err, caught = run(BASE + ['--spacing', '0.3', '--speed', '0.3', '--json']
                                 + extra)
    assert code == 0 and err == '' and caught == [], (extra, err)
    case = json.loads(out)['cases'][0]['cam']
    assert case['loads']['feasible'] == case['feasible']
