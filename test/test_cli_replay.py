"""`planter replay`: the sample bags, JSON, plot, and bad input (one line, exit 2)."""
import json
from pathlib import Path

import pytest

from cli_helpers import run_planter
from planter_ros.cli.main import main

REPO = Path(__file__).resolve().parents[1]
SAMPLES = sorted((REPO / 'bags').glob('sample_*.mcap'))


def test_sample_bags_exist_and_are_small():
    assert len(SAMPLES) >= 1
    assert all(p.stat().st_size < 1_000_000 for p in SAMPLES)


@pytest.mark.parametrize('bag', SAMPLES, ids=lambda p: p.stem)
def test_replay_of_a_sample_bag_matches_what_its_monitor_published(bag, capsys):
    from planter_ros.recording.replay import replay
    import numpy as np
    result = replay(bag, with_recorded=True)
    assert len(result.plants) >= 10
    # the sample bags predate tip_sweep and the map: compared on the fields they have
    columns = result.recorded_columns()
    assert 'tip_sweep' not in result.recorded_fields and len(columns) == 13
    assert np.allclose(result.plants.table()[:, columns], result.recorded_plants[:, columns],
                       rtol=0, atol=1e-12, equal_nan=True)
    # holes of a bag older than the nozzle width in the design: tip sweep + the recorded 0 m
    assert np.array_equal(result.plants.hole_width, result.plants.tip_sweep)
    assert main(['replay', str(bag), '--json']) == 0
    out = json.loads(capsys.readouterr().out)
    assert out['summary']['plants'] == len(result.plants)
    assert set(out['plants'][1]) >= {'position', 'spacing_error', 'hole_width', 'tilt',
                                     'upright', 'uprightness_rate'}
    assert out['plants'][0]['spacing'] is None          # no previous plant


def test_table_and_plot(tmp_path, capsys):
    png = tmp_path / 'replay.png'
    assert main(['replay', str(SAMPLES[0]), '--plot', str(png)]) == 0
    out = capsys.readouterr().out
    assert 'spacing error: mean' in out and 'uprightness:' in out
    assert png.stat().st_size > 10_000


def test_bad_input_is_one_line_and_exit_2(tmp_path):
    (tmp_path / 'notes.mcap').write_text('not a bag at all\n')
    (tmp_path / 'empty').mkdir()
    from std_msgs.msg import Float64
    from planter_ros.recording.recorder import Recorder
    with Recorder(tmp_path / 'foreign.mcap') as rec:       # a valid bag without our topics
        rec.add_topic('/camera/rate', 'std_msgs/msg/Float64')
        rec.write_message('/camera/rate', Float64(data=1.0), 1)
    cases = {
        tmp_path / 'notes.mcap': 'is not an MCAP file',
        tmp_path / 'empty': 'holds no .mcap files',
        tmp_path / 'missing.mcap': 'does not exist',
        tmp_path / 'foreign.mcap': 'lacks .../ground_speed',
    }
    for path, words in cases.items():
        r = run_planter('replay', path) if path.name == 'notes.mcap' else None
        if r is not None:       # one real subprocess, as a user runs it
            assert r.returncode == 2 and words in r.stderr
            assert r.stderr.count('\n') == 1 and 'Traceback' not in r.stderr
            continue
        assert main(['replay', str(path)]) == 2, path


def test_bad_input_messages(tmp_path, capsys):
    (tmp_path / 'empty').mkdir()
    assert main(['replay', str(tmp_path / 'empty')]) == 2
    err = capsys.readouterr().err
    assert err.startswith('planter: error: bag directory') and err.count('\n') == 1
    assert main(['replay', str(SAMPLES[0]), '--window', '0']) == 2
    assert 'window' in capsys.readouterr().err
