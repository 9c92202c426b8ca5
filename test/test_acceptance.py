"""A crop's acceptance limits: read strictly from the scene, recorded by the monitor, and the run
judged by them in replay, analyze and the demo, each failure naming the row and the index."""
import json
from pathlib import Path

import numpy as np
import pytest

from planter_ros.cli.main import main
from planter_ros.demo.verdict import RowResult, judge
from planter_ros.prediction import AcceptanceLimits, judge_acceptance
from planter_ros.scene import SceneError, open_scene

from cli_helpers import REPO, run_planter

TOMATO = REPO / 'config' / 'tomato_five_bar.yaml'
RICE = REPO / 'config' / 'rice_three_arm.yaml'
SAMPLE = REPO / 'bags' / 'sample_tomato.mcap'
RICE_SAMPLE = REPO / 'bags' / 'sample_rice_three_arm.mcap'


def strict_scene(tmp_path, **limits):
    """The tomato scene with `limits` set under /**."""
    lines = TOMATO.read_text().splitlines()
    for name, value in limits.items():
        lines = [line for line in lines if not line.strip().startswith(f'{name}:')]
        lines.append(f'    {name}: {value}')
    path = tmp_path / 'strict.yaml'
    path.write_text('\n'.join(lines) + '\n')
    return path


def summary(feed=0.95, multiple=0.02, miss=0.03, cv=0.1, upright=1.0, hole=0.045):
    return {'spacing_quality': {'quality_of_feed_index': feed, 'multiple_index': multiple,
                                'miss_index': miss, 'precision': cv, 'spacings': 40},
            'uprightness_rate': upright, 'hole_width_mean': hole}


def test_every_shipped_scene_states_its_limits_and_the_defaults_are_the_stated_ones():
    defaults = AcceptanceLimits()
    assert (defaults.min_quality_of_feed, defaults.max_precision, defaults.max_miss_index,
            defaults.max_multiple_index) == (0.80, 0.30, 0.08, 0.08)
    for scene in sorted((REPO / 'config').glob('*.yaml')):
        if scene.name == 'foxglove_layout.json':
            continue
        limits = open_scene(scene).acceptance()
        assert 0 < limits.max_hole_width < 0.1, scene     # every crop sets its hole limit
        assert 'max_hole_width' in scene.read_text()


def test_each_index_fails_alone_and_is_named_with_its_row():
    limits = AcceptanceLimits(max_hole_width=0.05)
    assert judge_acceptance(limits, [('left', summary())])['passed']
    cases = {'min_quality_of_feed': summary(feed=0.79), 'max_multiple_index':
             summary(multiple=0.09), 'max_miss_index': summary(miss=0.081),
             'max_precision': summary(cv=0.31), 'min_uprightness_rate': summary(upright=0.0),
             'max_hole_width': summary(hole=0.173)}
    for index, figures in cases.items():
        result = judge_acceptance(limits, [('left', summary()), ('right', figures)])
        assert not result['passed']
        assert [(f['row'], f['index']) for f in result['failed']] == [('right', index)]
        assert result['failed'][0]['text'].startswith('row right: ')
    # hole width 0 = not judged; a figure a run cannot give is listed, never passed as failed
    result = judge_acceptance(AcceptanceLimits(), [('', summary(hole=9.0, cv=None))])
    assert result['passed'] and [n['index'] for n in result['not_judged']] == ['max_precision']


# Exact boundaries: a design spacing and spacings that are binary fractions, so every ratio x/d
# and every index below is exact, and each figure can sit exactly on its limit.
D_EXACT = 0.25
# 8 spacings: one multiple at exactly 0.5 d, one miss, six singles whose CV is exactly 0.25
# (x/d = 1 + (3, -3, 1, -1, 0, 0)/8: mean 1, squared deviations 5/16, / (6 - 1) = 1/16)
SPACINGS = (0.125, 0.4375, 0.34375, 0.15625, 0.28125, 0.21875, 0.25, 0.25)
AT = {'min_quality_of_feed': 0.75, 'max_multiple_index': 0.125, 'max_miss_index': 0.125,
      'max_precision': 0.25, 'min_uprightness_rate': 0.75, 'max_hole_width': 0.0625}


def exact_plants():
    """Nine plants of one row (the first without a spacing), six of the eight with a known
    uprightness upright, every hole 62.5 mm wide: each figure exactly one of AT."""
    from planter_ros.prediction import PLANT_FIELDS, Plants
    table = np.full((9, len(PLANT_FIELDS)), np.nan)
    column = {name: i for i, name in enumerate(PLANT_FIELDS)}
    table[:, column['index']] = np.arange(9)
    table[:, column['row']] = 0.0
    table[:, column['status']] = 3.0                     # unknown: no seedling sensor
    table[1:, column['spacing']] = SPACINGS
    table[1:, column['spacing_error']] = np.array(SPACINGS) - D_EXACT
    table[1:, column['upright']] = (1, 1, 0, 1, 1, 0, 1, 1)
    table[1:, column['hole_width']] = 0.0625
    return Plants.from_table(table)


def test_every_figure_exactly_at_its_limit_passes_and_one_step_past_fails_alone():
    """ISO 7256-1 counts x <= 0.5 d as a multiple and x > 1.5 d as a miss; a maximum holds
    while the figure is not above it, a minimum while it is not below it. Every figure here
    is computed from the plants (prediction.summarize) and lands exactly on its limit; then
    each limit in turn moves by the smallest step a float has, to the figure's wrong side."""
    from planter_ros.prediction import summarize
    summary = summarize(exact_plants(), D_EXACT)
    quality = summary['spacing_quality']
    assert (quality['quality_of_feed_index'], quality['multiple_index'], quality['miss_index'],
            quality['precision'], summary['uprightness_rate'], summary['hole_width_mean']) == (
        0.75, 0.125, 0.125, 0.25, 0.75, 0.0625)
    at = judge_acceptance(AcceptanceLimits(**AT), [('left', summary)])
    assert at['passed'] and at['failed'] == [] and at['not_judged'] == []
    for name, limit in AT.items():
        past = np.nextafter(limit, 2.0 if name.startswith('min_') else -1.0)
        judged = judge_acceptance(AcceptanceLimits(**{**AT, name: float(past)}),
                                  [('left', summary)])
        assert [f['index'] for f in judged['failed']] == [name], name
        assert judged['failed'][0]['value'] == limit


def test_a_bad_limit_in_a_scene_is_refused_naming_it(tmp_path):
    with pytest.raises(SceneError, match='max_miss_index'):
        open_scene(strict_scene(tmp_path, max_miss_index=1.5))
    with pytest.raises(SceneError, match='did you mean `max_miss_index`'):
        open_scene(strict_scene(tmp_path, max_mis_index=0.1))


def test_replay_judges_by_the_scene_given_and_names_the_failed_index(tmp_path, capsys):
    assert main(['replay', str(SAMPLE), '--json']) == 0
    plain = json.loads(capsys.readouterr().out)['acceptance']
    assert plain['passed'] and plain['source'].startswith('the defaults')
    strict = strict_scene(tmp_path, max_precision=0.001, min_quality_of_feed=1.0)
    assert main(['replay', str(SAMPLE), '--json', '--scene', str(strict)]) == 0
    judged = json.loads(capsys.readouterr().out)['acceptance']
    assert not judged['passed'] and judged['source'] == 'the scene given'
    assert [f['index'] for f in judged['failed']] == ['max_precision']
    assert judged['failed'][0]['value'] > 0.001 and judged['limits']['max_precision'] == 0.001
    main(['replay', str(SAMPLE), '--scene', str(strict)])
    assert 'acceptance (limits: the scene given): FAIL: precision (CV)' in \
        capsys.readouterr().out


def test_the_rice_sample_fails_its_crops_limits_on_uprightness_and_hole_width(capsys):
    assert main(['replay', str(RICE_SAMPLE), '--json', '--scene', str(RICE)]) == 0
    judged = json.loads(capsys.readouterr().out)['acceptance']
    assert {f['index'] for f in judged['failed']} == {'min_uprightness_rate', 'max_hole_width'}


def test_the_demo_verdict_lists_every_acceptance_failure():
    rows = [RowResult('', 34, 0.01)]
    from planter_ros.demo.sync_process import DesignReport, DrivesReport, SyncReport
    report = SyncReport(None, DrivesReport(), DesignReport(), 'none in this test')
    result = judge_acceptance(AcceptanceLimits(max_hole_width=0.05),
                              [('', summary(upright=0.0, hole=0.173))])
    verdict = judge(rows, report, acceptance=result)
    assert not verdict.passed and verdict.exit_code == 1
    assert 'uprightness rate 0.0 % < 90.0 % (min_uprightness_rate)' in verdict.line()
    assert 'hole width (mean) 173.0 mm > 50.0 mm (max_hole_width)' in verdict.line()
    assert judge(rows, report, acceptance=judge_acceptance(
        AcceptanceLimits(), [('', summary())])).passed


@pytest.mark.slow
@pytest.mark.realtime
def test_a_demo_under_strict_limits_fails_naming_the_index(tmp_path):
    strict = strict_scene(tmp_path, max_precision=0.0001)
    bag = tmp_path / 'run.mcap'
    done = run_planter('demo', '--scene', strict, '--duration', '8', '--bag', bag, timeout=240)
    verdict = [line for line in done.stdout.splitlines() if line.startswith('verdict:')]
    assert done.returncode == 1, done.stdout + done.stderr
    assert verdict and 'precision (CV)' in verdict[0] and '(max_precision)' in verdict[0]
    # the limits are recorded: replay without a scene judges the bag by them
    replayed = run_planter('replay', bag, '--json')
    judged = json.loads(replayed.stdout)['acceptance']
    assert judged['source'].startswith("the run's scene")
    assert judged['limits']['max_precision'] == 0.0001
    assert 'max_precision' in {f['index'] for f in judged['failed']}
    assert Path(bag).is_file()


def test_the_season_maps_mark_misses_and_multiples_by_the_indices_own_limits():
    """The season report's maps ring a spacing as a miss or a multiple exactly where the ISO
    7256-1 indices count it: a spacing of exactly 1.5 d or just above 0.5 d is a single
    (binary fractions of d = 0.25 m: 0.375 / 0.25 and 0.125 / 0.25 are exact)."""
    from planter_ros.plots.season import _miss_or_multiple
    ratio = np.array([0.125, np.nextafter(0.125, 1.0), 0.375, np.nextafter(0.375, 1.0),
                      np.nan]) / 0.25
    assert _miss_or_multiple(ratio).tolist() == [True, False, False, True, False]
