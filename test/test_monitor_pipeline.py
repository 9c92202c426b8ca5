"""One monitor pipeline (prediction.pipeline): the live monitor node and the season simulator run
the same one, so a simulated bag carries what the node would have published, bit for bit.

The season simulator writes a run's bag (its inputs as the monitor receives them, and the plants
its pipeline released); the real MonitorNode is then fed every input message of that bag, in
the bag's order, with its log time as the receive time, and records its own bag. Every `plants`
and `uprightness_rate` message of the two bags must be the same bytes: every plant's every
field (spacing, hole, tilt, seedlings, latitude and longitude ...) to the bit, in the same
batches at the same instants."""
import dataclasses

from mcap.reader import make_reader
import numpy as np
import pytest
from rclpy.parameter import Parameter

from planter_ros import interfaces
from planter_ros.nodes.monitor_node import MonitorNode
from planter_ros.prediction import PLANT_FIELDS, Plants
from planter_ros.sim.field import Curve, Stop
from planter_ros.sim.season import (
    Glitch, RunPlan, Stall, machine_rows, season_design, simulate_plan, write_monitor_bag)

pytestmark = pytest.mark.realtime          # a live node (no graph spun, but a DDS participant)

INPUTS = {topic.resolved(): topic for topic in interfaces.MONITOR_INPUTS}
OUTPUTS = (interfaces.PLANTS.resolved(), interfaces.UPRIGHTNESS_RATE.resolved())


def messages(path, topics):
    """[(topic, log time ns, CDR bytes)] of `topics`, in the order the bag holds them."""
    with open(path, 'rb') as f:
        return [(channel.topic, message.log_time, bytes(message.data))
                for _, channel, message in make_reader(f).iter_messages(
                    topics=list(topics), log_time_order=False)]


def plan_with_everything():
    """Three rows, the middle one disabled (it turns, but plants nothing the monitor scores),
    the left one 0.375 m ahead of the reference point; two stops, a curve, every glitch, a
    stall, a tray with empty and double cells, and a spacing change 0.2 -> 0.25 m at 9 s."""
    rows = machine_rows(3)
    rows = (dataclasses.replace(rows[0], longitudinal_offset=0.375),
            dataclasses.replace(rows[1], enabled=False), rows[2])
    design = season_design()
    return RunPlan(index=2, seed=31, duration=18.0, rows=rows, cruise=0.3, change=1.25,
                   stops=(Stop(4.0, 1.0),), curves=(Curve(10.0, 15.0, 8.0),),
                   glitches=(Glitch('spike', 3.02, factor=3.0), Glitch('nan', 6.51),
                             Glitch('dropout', 12.0, length=0.8)),
                   stall=Stall(2, 7.0, 1.0, 0.1), empty_rate=0.125, double_rate=0.0625,
                   designs=((9.0, dataclasses.replace(design, plant_spacing=0.25)),))


def test_the_node_and_the_season_simulator_publish_the_same_plants_to_the_bit(ros, tmp_path):
    plan = plan_with_everything()
    simulated = tmp_path / 'simulated.mcap'
    summary = write_monitor_bag(simulate_plan(plan), simulated)
    params = [Parameter('bag_path', value=str(tmp_path / 'live.mcap')),
              Parameter('rows', value=[row.name for row in plan.rows])]
    for row in plan.rows:
        params += [Parameter(f'{row.name}.{key}', value=getattr(row, key))
                   for key in ('lateral_offset', 'drive_node_id', 'enabled',
                               'longitudinal_offset')]
    node = MonitorNode(context=ros.context, parameter_overrides=params)
    try:
        for topic, log, raw in messages(simulated, INPUTS):
            node.receive(INPUTS[topic], raw, log)
    finally:
        node.destroy_node()               # the monitor's end: the plants still held, placed
    live = node.recorder.path
    simulated_out, live_out = messages(simulated, OUTPUTS), messages(live, OUTPUTS)
    assert len(simulated_out) == len(live_out) > 50
    assert [raw for _, _, raw in live_out] == [raw for _, _, raw in simulated_out]
    # the same instants too (the last batches: at the node's own end, after the inputs)
    inputs_end = max(log for _, log, _ in messages(simulated, INPUTS))
    assert [(t, log) for t, log, _ in live_out if log <= inputs_end] == \
        [(t, log) for t, log, _ in simulated_out if log <= inputs_end]
    # what the comparison covered: every planting row, the design change, the tray, the map
    plants = Plants.from_table(np.vstack(node.published_tables()))
    assert len(plants) == summary['plants']
    assert sorted(set(plants.row.astype(int).tolist())) == [0, 2]
    d = plants.spacing - plants.spacing_error
    assert {0.2, 0.25} <= set(np.round(d[np.isfinite(d)], 9).tolist())
    assert {0.0, 1.0, 2.0} <= set(plants.seedlings[np.isfinite(plants.seedlings)].tolist())
    assert np.isfinite(plants.latitude).mean() > 0.9
    assert len(PLANT_FIELDS) == plants.table().shape[1]
