"""Which rows carry a seedling sensor is the scene's to declare (`seedling_sensor`,
`<row>.seedling_sensor`), not guessed from the first reading: a row declared without one gives
unknown instants (`no seedling sensor`) whatever its joint reads, a row declared with one says
`no sensor reading` where none came; the monitor records the declaration, and the demo,
`planter simulate`, `planter replay` and `planter analyze` honour it."""
import numpy as np
import pytest

from cli_helpers import REPO, planter_here, run_planter
from planter_ros.prediction import PLANT_FIELDS, SeedlingAccount
from planter_ros.prediction.seedlings import (EMPTY, NO_READING, NO_SENSOR, PLANTED, SENSED,
                                              UNKNOWN)
from planter_ros.recording.replay import replay
from test_seedlings import D, instants


ROW = PLANT_FIELDS.index('row')


def test_a_declared_sensor_is_not_inferred_from_the_readings():
    counts = [1, 0, 1, 1]
    account = SeedlingAccount({0: False, 1: True, 2: None})
    for row in (0, 1, 2):
        for k, c in enumerate(counts):
            if k >= 2:                          # the sensors read from the third cycle on
                account.add_reading(row, 99.5 + k, c)
    without, with_, undeclared = (account.apply(instants(4, row=row), np.full(4, D))
                                  for row in (0, 1, 2))
    # declared without: every instant unknown, no seedling sensor, its readings not counted
    assert np.all(without.status == UNKNOWN) and np.all(without.reason == NO_SENSOR)
    assert np.all(np.isnan(without.seedlings)) and 0 not in account.readings()
    # declared with: the cycles before its first reading are no sensor reading
    assert [int(r) for r in with_.reason] == [NO_READING, NO_READING, SENSED, SENSED]
    assert [int(s) for s in with_.status] == [UNKNOWN, UNKNOWN, PLANTED, PLANTED]
    # not declared (a bag before the setting): a sensor from its first reading on
    assert [int(r) for r in undeclared.reason] == [NO_SENSOR, NO_SENSOR, SENSED, SENSED]
    account = SeedlingAccount({0: True})
    account.add_reading(0, 99.5, 0)
    assert int(account.apply(instants(1), np.full(1, D)).status[0]) == EMPTY


def scene_with(tmp_path, lines, base='tomato_4row'):
    """`base` with `lines` (row blocks replaced by name, others added under /**)."""
    text = (REPO / 'config' / f'{base}.yaml').read_text().splitlines()
    out = []
    for line in text:
        key = line.strip().split(':', 1)[0]
        replaced = [new for new in lines if new.strip().split(':', 1)[0] == key]
        out.append(replaced[0] if replaced else line)
    added = [new for new in lines if new not in out]
    at = out.index('  ros__parameters:') + 1
    path = tmp_path / 'scene.yaml'
    path.write_text('\n'.join(out[:at] + added + out[at:]) + '\n')
    return path


def test_the_scene_declares_each_rows_sensor_with_the_machines_default(tmp_path):
    from planter_ros.scene import open_scene
    rows = open_scene(REPO / 'config' / 'tomato_4row.yaml').rows()
    assert [r.seedling_sensor for r in rows] == [True] * 4          # the default: every row
    scene = scene_with(tmp_path, [
        '    seedling_sensor: false',
        '    left_inner: {lateral_offset: 0.25, drive_node_id: 2, seedling_sensor: true}'])
    assert [r.seedling_sensor for r in open_scene(scene).rows()] == [False, True, False, False]
    single = scene_with(tmp_path, ['    seedling_sensor: false'], base='tomato_five_bar')
    assert [r.seedling_sensor for r in open_scene(single).rows()] == [False]


@pytest.mark.parametrize('line, words', [
    ('    seedling_sensor: maybe', 'seedling_sensor'),
    ('    left_inner: {lateral_offset: 0.25, drive_node_id: 2, seedling_sensor: 3}',
     'left_inner.seedling_sensor'),
    ('    left_inner: {lateral_offset: 0.25, drive_node_id: 2, seedling_sensr: true}',
     'seedling_sensor'),
])
def test_a_bad_seedling_sensor_setting_is_one_line(line, words, tmp_path, capsys):
    from planter_ros.cli.main import main
    scene = scene_with(tmp_path, [line])
    assert main(['simulate', str(tmp_path / 'x'), '--bags', '1', '--scene', str(scene)]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count('\n') == 1, err
    assert not (tmp_path / 'x').exists()


@pytest.mark.realtime          # (test/conftest.py)
def test_the_monitor_node_takes_each_rows_declaration(ros, tmp_path):
    from rclpy.parameter import Parameter

    from planter_ros.nodes.monitor_node import MonitorNode
    params = [Parameter('bag_path', value=str(tmp_path / 'live.mcap')),
              Parameter('rows', value=['a', 'b', 'c']), Parameter('seedling_sensor', value=False),
              Parameter('b.seedling_sensor', value=True)]
    for k, name in enumerate('abc'):
        params += [Parameter(f'{name}.lateral_offset', value=0.5 - 0.5 * k),
                   Parameter(f'{name}.drive_node_id', value=k + 1)]
    node = MonitorNode(context=ros.context, parameter_overrides=params)
    try:
        assert [row.seedling_sensor for row in node.rows] == [False, True, False]
    finally:
        node.destroy_node()


def test_simulate_replay_and_analyze_honour_a_row_without_a_sensor(tmp_path):
    """The 4-row tomato machine, its right outer row declared without a sensor, on a tray
    with 10 % empty cells: that row's instants are all unknown (no seedling sensor), its joint
    reads nothing; the other rows are sensed, empties included, live and in replay alike; the
    analysis table counts them so."""
    import pyarrow.parquet as pq
    scene = scene_with(tmp_path, [
        '    right_outer: {lateral_offset: -0.75, drive_node_id: 4, enabled: true, '
        'seedling_sensor: false}'])
    out = tmp_path / 'season'
    # (both commands in this process: what they write is the question, not their process)
    done = planter_here('simulate', out, '--bags', 1, '--duration', 20, '--seed', 2,
                        '--scene', scene, '--empty-rate', 0.1, '--workers', 1, '--json')
    assert done.returncode == 0, done.stderr[-2000:]
    bag = out / 'run_2_00000.mcap'
    result = replay(bag, with_recorded=True)
    assert [row.seedling_sensor for row in result.rows] == [True, True, True, False]
    assert sorted(result.seedling_readings) == [0, 1, 2]
    plants = result.plants
    mine = plants.row == 3
    assert mine.sum() > 10
    assert np.all(plants.status[mine] == UNKNOWN) and np.all(plants.reason[mine] == NO_SENSOR)
    others = plants.status[~mine]
    assert np.all(plants.reason[~mine] != NO_SENSOR) and np.any(others == EMPTY)
    live = result.recorded_plants
    for field in ('status', 'reason'):
        k = PLANT_FIELDS.index(field)
        order = np.lexsort((live[:, PLANT_FIELDS.index('index')], live[:, ROW]))
        mine_order = np.lexsort((plants.index, plants.row))
        assert np.array_equal(plants.table()[mine_order, k], live[order, k])
    tables = tmp_path / 'tables'
    done = planter_here('analyze', out, '--out', tables, '--workers', 1)
    assert done.returncode == 0, done.stderr[-2000:]
    table = pq.read_table(tables / 'plants').to_pandas()
    right = table[table['row_name'] == 'right_outer']
    assert len(right) == int(mine.sum()) and set(right['status']) == {'unknown'}
    assert set(right['reason']) == {'no seedling sensor'}
    assert 'no seedling sensor' not in set(table[table['row_name'] != 'right_outer']['reason'])


@pytest.mark.slow
@pytest.mark.realtime
def test_the_demo_gives_a_row_without_a_sensor_no_tray(tmp_path):
    """`planter demo` of a scene whose one row has no sensor: no cup sensor, and every
    instant the live monitor published and replay finds is unknown (no seedling sensor)."""
    scene = scene_with(tmp_path, ['    seedling_sensor: false'], base='tomato_five_bar')
    bag = tmp_path / 'demo.mcap'
    out = run_planter('demo', '--scene', scene, '--duration', '10', '--empty-rate', '0.3',
                      '--bag', bag, timeout=240)
    assert out.returncode in (0, 1), out.stdout[-3000:] + out.stderr[-3000:]
    assert 'seedling sensor: none (the scene declares no row with one)' in out.stdout
    result = replay(bag, with_recorded=True)
    assert [row.seedling_sensor for row in result.rows] == [False]
    assert len(result.plants) >= 5 and not result.seedling_readings
    assert np.all(result.plants.reason == NO_SENSOR)
    live = result.recorded_plants
    assert np.all(live[:, PLANT_FIELDS.index('reason')] == NO_SENSOR)
    assert result.summary['instants']['unknown'] == len(result.plants)


@pytest.mark.parametrize('rows', [1, 4])
def test_an_unnamed_reading_is_one_rows_only_on_a_machine_of_one_row(rows):
    """A seedling reading whose JointState names no joint is the only row's on a one-row
    machine; on a machine of four rows it is none of them for sure: skipped with a warning,
    not credited to all four (a fifth of the cups it would have filled)."""
    from types import SimpleNamespace

    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    from planter_ros import interfaces
    from planter_ros.recording.replay import _seedlings
    from planter_ros.sim.season import machine_rows
    planting = machine_rows(rows)
    joint = planting[0].joint('five_bar')
    msgs = [JointState(name=[joint], position=[1.0]), JointState(position=[2.0])]
    topic = SimpleNamespace(raw=[serialize_message(m) for m in msgs],
                            log=[1_000_000_000, 2_000_000_000])
    rec = SimpleNamespace(topics={interfaces.SEEDLINGS: topic}, warnings=[])
    segments = [(None, [(0, 0, SimpleNamespace(mechanism='five_bar'))])]
    readings = _seedlings(rec, None, planting, segments).readings()
    counts = {row: list(c) for row, (_, c) in readings.items()}
    if rows == 1:
        assert counts == {planting[0].index: [1.0, 2.0]} and rec.warnings == []
    else:
        assert counts == {planting[0].index: [1.0]}
        assert rec.warnings == ['1 seedling reading(s) without a row name on a machine of 4 '
                                'rows: skipped']
