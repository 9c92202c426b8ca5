"""The demo's simulated seedling sensor: each row's cup sensor on a simulated tray (sim.tray, the
tray `planter simulate` uses), so the demo's bag and verdict show planted, empty and double
instants."""
import math

import numpy as np
import pytest

from planter_ros.prediction import PLANT_FIELDS, planting_model_from_design
from planter_ros.sim.season import season_design
from planter_ros.sim.tray import SensedCycles, Tray, sense_angle

from cli_helpers import REPO, run_planter

pytestmark = pytest.mark.realtime          # (test/conftest.py)


def test_the_cup_sensor_reads_every_cycle_once_half_a_cycle_before_planting():
    model = planting_model_from_design(season_design())
    sensor = SensedCycles(model, Tray(0.2, 0.1, np.random.default_rng(5)))
    rng = np.random.default_rng(6)
    # the measured angle: from the start, forward in uneven steps, now and then back a little
    theta = np.concatenate(([0.0], np.cumsum(rng.uniform(-0.05, 0.4, 3000))))
    read = []
    for angle in theta:
        read += [(k, c, angle) for k, c in sensor.add(angle)]
    ks = [k for k, _, _ in read]
    assert ks == list(range(0, ks[-1] + 1))                   # every cup once, the first too
    top = np.maximum.accumulate(theta)
    assert sense_angle(model, ks[-1] + 1) > top[-1]           # none left out at the end
    for k, _, angle in read:                                  # read when the angle passed it
        assert sense_angle(model, k) <= angle
        assert sense_angle(model, k) < model.planting_phase + k * 2 * math.pi
    counts = np.array([c for _, c, _ in read])
    assert set(counts.tolist()) == {0, 1, 2}
    # the same seed, the same tray as planter simulate's draw
    again = Tray(0.2, 0.1, np.random.default_rng(5)).cells(len(counts))
    assert np.array_equal(counts, again)


def test_the_demo_with_a_tray_records_planted_empty_and_double_instants(tmp_path):
    """A short demo with a tray of 25 % empty cells and 15 % doubles: the bag holds the cup
    sensor's readings, every planting instant replay finds is planted, empty or double by its
    cycle's reading (as the live monitor published it), and the verdict judges the misses and
    multiples they make against the crop's limits."""
    from planter_ros.recording.replay import replay
    bag = tmp_path / 'tray.mcap'
    out = run_planter('demo', '--duration', '12', '--empty-rate', '0.25', '--double-rate',
                      '0.15', '--seed', '3', '--bag', bag, timeout=240)
    assert out.returncode in (0, 1), out.stdout[-3000:] + out.stderr[-3000:]
    assert 'seedling sensor: a cup sensor on 1 of 1 row(s) on a simulated tray, 25% empty ' \
        'cells, 15% doubles' in out.stdout
    result = replay(bag, with_recorded=True)
    plants = result.plants
    assert len(plants) >= 6
    status = plants.status.astype(int).tolist()
    assert 1 in status and 2 in status                        # empty cups and doubles
    assert status.count(3) == 0                               # every instant sensed
    readings = result.seedling_readings[0]
    assert set(readings[1].tolist()) <= {0.0, 1.0, 2.0}
    # each instant's count is its own cycle's reading (the last one before it)
    for t, count in zip(plants.time, plants.seedlings):
        assert readings[1][np.searchsorted(readings[0], t, side='right') - 1] == count
    # the live monitor counted the same
    live = result.recorded_plants
    for field in ('status', 'seedlings'):
        k = PLANT_FIELDS.index(field)
        assert np.array_equal(plants.table()[:, k], live[np.argsort(live[:, 0]), k])
    counted = result.summary['instants']
    assert f"{counted['empty']} empty, {counted['double']} double" in out.stdout
    verdict = out.stdout.rstrip().splitlines()[-1]
    if result.acceptance['passed']:
        assert verdict.startswith('verdict: PASS')
    else:
        assert verdict.startswith('verdict: FAIL')
        assert 'index' in verdict or 'quality of feed' in verdict


def test_bad_tray_rates_are_one_line_errors(tmp_path):
    for args, words in ((('--empty-rate', '1.5'), '--empty-rate'),
                        (('--empty-rate', '0.7', '--double-rate', '0.5'), 'at most 1')):
        out = run_planter('demo', *args, '--bag', tmp_path / 'x.mcap', cwd=REPO, timeout=60)
        assert out.returncode == 2
        assert words in out.stderr and len(out.stderr.strip().splitlines()) == 1
