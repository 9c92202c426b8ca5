"""`planter demo` as a user runs it: bad input is one line; Ctrl-C stops cleanly with a summary."""
import os
import signal
import subprocess
import sys
import time

from cli_helpers import REPO, run_planter


def test_bad_duration_and_scene_are_one_line_errors(tmp_path):
    out = run_planter('demo', '--duration', '2')
    assert out.returncode == 2 and out.stderr.count('\n') == 1
    assert '--duration = 2 is out of range: allowed number 8..3600 s' in out.stderr
    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    mechanism: five_bar\n    planting_depth: 0.045\n'
                   '    plant_spacing: 0.2\n    hole_ratio: 1.9\n    nominal_ground_speed: 0.2\n')
    out = run_planter('demo', '--scene', bad)
    assert out.returncode == 2 and 'hole_ratio = 1.9 is out of range' in out.stderr
    assert 'Traceback' not in out.stderr


def test_an_existing_bag_is_never_overwritten(tmp_path):
    bag = tmp_path / 'run.mcap'
    bag.write_bytes(b'precious')
    out = run_planter('demo', '--bag', bag)
    assert out.returncode == 2 and out.stderr.count('\n') == 1
    assert 'exists' in out.stderr and 'never overwritten' in out.stderr
    assert bag.read_bytes() == b'precious'


def test_ctrl_c_stops_the_demo_cleanly_with_a_summary_and_a_finalised_bag(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    proc = subprocess.Popen([sys.executable, '-m', 'planter_ros.cli', 'demo', '--duration', '60'],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                            cwd=tmp_path)
    lines = []
    deadline = time.monotonic() + 60
    for line in proc.stdout:                       # wait until plants are being placed
        lines.append(line)
        if line.startswith('t =   4.0 s') or time.monotonic() > deadline:
            break
    proc.send_signal(signal.SIGINT)
    rest, _ = proc.communicate(timeout=30)
    out = ''.join(lines) + rest
    assert proc.returncode == 130, out
    assert 'interrupted: stopping' in out
    assert 'drive shut down (target 0, disabled, pre-operational)' in out
    assert 'Traceback' not in out
    placed = next(line for line in out.splitlines() if 'plants placed' in line)
    assert int(placed.split()[-1]) >= 1
    # the default bag lands under ./bags, finalised, and the demo ends with its replay
    bags = list((tmp_path / 'bags').glob('planter_*'))
    assert len(bags) == 1
    assert f'recorded bags/{bags[0].name}' in out
    replayed = next(line for line in out.splitlines() if line.strip().startswith('plants:'))
    assert int(replayed.split()[1]) >= 1
    assert 'spacing error: mean' in out and 'uprightness:' in out


def test_the_four_row_demo_plants_every_row_through_the_turns_and_replays_per_row(tmp_path):
    import numpy as np
    from planter_ros.recording.replay import replay
    bag = tmp_path / 'four_rows.mcap'
    out = run_planter('demo', '--scene', REPO / 'config' / 'tomato_4row.yaml', '--duration',
                      '12', '--bag', bag, timeout=180)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    names = ['left_outer', 'left_inner', 'right_inner', 'right_outer']
    for name in names:
        assert f'  row {name} (y = ' in out.stdout                  # the demo's own summary
        assert f'row {name} (y = ' in out.stdout.split('replay')[-1]  # and the replay's
    assert out.stdout.count('    left turn R = 10 m') == 4
    assert 'without compensation expect -15.00 mm (-y·d/R)' in out.stdout
    assert 'drive watchdog trips     none' in out.stdout
    result = replay(bag, with_recorded=True)
    assert [r.name for r in result.rows] == names
    assert all(s['plants'] >= 5 for s in result.row_summaries)
    # replay reproduces what the monitor published, row by row
    def by_row(table):
        return table[np.lexsort((table[:, 0], table[:, -1]))]
    assert np.allclose(by_row(result.plants.table()), by_row(result.recorded_plants),
                       rtol=0, atol=1e-12, equal_nan=True)
