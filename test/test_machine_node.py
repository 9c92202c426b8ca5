"""sync_node driving a machine of several rows, one simulated drive each on one virtual bus:
each row on its own speed on a curve (and on the machine's with turn compensation off), one
joint per row, a fault on one row stops that row only (per-row reset), section control over
the `<row>/section` service, a disabled row never enabled, a drive that does not answer left
out, a three-arm machine, and /diagnostics with one status per row plus the bus."""
import json
import math
import time

import numpy as np
import pytest
from rclpy.parameter import Parameter
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import TwistStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger

from planter_ros import interfaces
from planter_ros.simdrive.bus import SimulatedBus
from planter_ros.nodes.sync_node import SyncNode
from ros_fixtures import unique_channel

pytestmark = pytest.mark.realtime          # (test/conftest.py)

D = 0.2
TOMATO = {'mechanism': 'five_bar', 'plants_per_revolution': 1, 'plant_spacing': D,
          'planting_depth': 0.045, 'l1': 0.0194, 'l2': 0.0512}
ROWS = {'left': (0.75, 1), 'right': (-0.75, 2)}
# the drives' RPDO deadline (s): rows, faults and sections are tested here, in this test process
# (the in-process engine: no command process at real-time priority), and the default 200 ms let
# a loaded host's stall of this process trip the drives while enabling (seen in three full suite
# runs on a 2-core host); the deadline itself: test_drive_faults
DEADLINE = 1.0


class Machine:
    """Simulated drives (the rows' node ids that answer), the sync node with `rows`, and a test
    node publishing ground speed and the design."""

    def __init__(self, ros, rows=ROWS, answering=None, disabled=(), design=TOMATO, **params):
        self.ros = ros
        self.channel = unique_channel('machine')
        ids = [node for name, (_, node) in rows.items()
               if name not in disabled and (answering is None or node in answering)]
        self.sims = SimulatedBus(self.channel, ids)
        self.sims.start()
        self.sim = {d.node_id: d for d in self.sims.drives}
        overrides = [Parameter('can_interface', value='virtual'),
                     Parameter('can_channel', value=self.channel),
                     Parameter('rows', value=list(rows))]
        for name, (y, node) in rows.items():
            overrides += [Parameter(f'{name}.lateral_offset', value=y),
                          Parameter(f'{name}.drive_node_id', value=node),
                          Parameter(f'{name}.enabled', value=name not in disabled)]
        params.setdefault('command_timeout', DEADLINE)
        overrides += [Parameter(k, value=v) for k, v in params.items()]
        self.sync = SyncNode(context=ros.context, parameter_overrides=overrides)
        self.sync.enable_drive()
        ros.add(self.sync)
        self.io = ros.node('machine_io')
        self.speed_pub = interfaces.GROUND_SPEED.publisher(self.io)
        self.joints = []
        self.commands = []
        interfaces.JOINT_STATES.subscribe(self.io, self.joints.append)
        interfaces.SPEED_COMMANDS.subscribe(self.io, self.commands.append)
        interfaces.DESIGN.publisher(self.io).publish(String(data=json.dumps(design)))
        assert ros.spin_until(lambda: self.sync.engine.law.spacing == design['plant_spacing'])

    def drive(self, v, yaw_rate, seconds, rate=50.0):
        """Publish the ground speed at `rate` Hz for `seconds`, spinning the nodes."""
        msg = TwistStamped()
        msg.twist.linear.x = float(v)
        msg.twist.angular.z = float(yaw_rate)
        end = time.monotonic() + seconds
        next_pub = time.monotonic()
        while (now := time.monotonic()) < end:
            if now >= next_pub:
                self.speed_pub.publish(msg)
                next_pub += 1.0 / rate
            self.ros.executor.spin_once(timeout_sec=0.002)

    def average_speeds(self, v, yaw_rate, seconds=1.0):
        """Keep driving for `seconds`; each drive's mean mechanism speed meanwhile (rad/s): the
        angle its motor turned over the motor model's own time. (A mean of instantaneous speeds
        sampled by this loop is not the mean speed on a loaded host: the samples come late and
        unevenly, and the drive's speed ripples with the command's jitter; the angle turned is
        what the planting follows.)"""
        def motors():
            out = {}
            for node, sim in self.sim.items():
                with sim._lock:                  # position and the instant it is for, together
                    out[node] = (sim.motor_position, sim.device.motor.time)
            return out
        start = motors()
        self.drive(v, yaw_rate, seconds)
        end = motors()
        return {node: (end[node][0] - start[node][0]) / (end[node][1] - start[node][1])
                for node in self.sim}

    def call(self, srv, name, request):
        client = self.io.create_client(srv, name)
        assert client.wait_for_service(timeout_sec=2.0)
        future = client.call_async(request)
        assert self.ros.spin_until(future.done)
        return future.result()

    def diag(self, task):
        return next(s for s in self.sync.diagnostics() if s.name == f'sync_node: {task}')

    def speed(self, node):
        """Mechanism speed of the drive `node` (rad/s; gear ratio 1)."""
        return self.sim[node].motor_velocity

    def close(self):
        self.ros.nodes.remove(self.sync)
        self.ros.executor.remove_node(self.sync)
        self.sync.destroy_node()
        self.sims.stop()


@pytest.fixture
def machine(ros):
    made = []

    def make(**kwargs):
        made.append(Machine(ros, **kwargs))
        return made[-1]
    yield make
    for m in made:
        m.close()


def values(status):
    return {kv.key: kv.value for kv in status.values}


def test_each_row_follows_its_own_speed_on_a_curve_with_one_joint_per_row(machine):
    m = machine()
    v, w = 0.2, 0.02                                  # a 10 m left turn
    m.drive(v, w, 2.0)
    speeds = m.average_speeds(v, w)
    for name, (y, node) in ROWS.items():
        expected = 2 * math.pi * (v - w * y) / D
        assert speeds[node] == pytest.approx(expected, rel=0.03), name
    last = m.joints[-1]
    assert last.name == ['left/sun_bar', 'right/sun_bar']
    assert last.velocity[0] < last.velocity[1]        # the left row is inside
    assert m.commands[-1].name == ['left/sun_bar', 'right/sun_bar']
    assert [s.name for s in m.sync.diagnostics()] == [
        'sync_node: ground speed', 'sync_node: bus', 'sync_node: left', 'sync_node: right',
        'sync_node: control loop', 'sync_node: design']
    left = m.diag('left')
    assert left.level == DiagnosticStatus.OK and values(left)['row speed'] == '0.1850 m/s'
    assert values(m.diag('ground speed'))['yaw rate'] == '0.0200 rad/s'
    bus = values(m.diag('bus'))
    assert bus['drives on the bus'] == '2' and bus['bus load'].endswith('%')
    # compensation off: every row on the machine's speed
    assert m.sync.set_parameters([Parameter('turn_compensation', value=False)])[0].successful
    m.drive(v, w, 1.5)
    speeds = m.average_speeds(v, w)
    for _, node in ROWS.values():
        assert speeds[node] == pytest.approx(2 * math.pi * v / D, rel=0.03)


def test_a_fault_on_one_row_stops_that_row_only_and_its_own_reset_clears_it(machine):
    m = machine()
    m.drive(0.2, 0.0, 2.0)
    m.sim[2].inject_fault(0x7500)
    m.drive(0.2, 0.0, 1.0)
    assert m.sim[2].state == 'FAULT' and m.speed(2) == pytest.approx(0.0, abs=0.05)
    speeds = m.average_speeds(0.2, 0.0)
    assert speeds[1] == pytest.approx(2 * math.pi * 0.2 / D, rel=0.03)   # left plants on
    right = m.diag('right')
    assert right.level == DiagnosticStatus.ERROR and '0x7500' in right.message
    assert m.diag('left').level == DiagnosticStatus.OK
    assert not m.call(Trigger, 'left/reset_fault', Trigger.Request()).success
    assert m.call(Trigger, 'right/reset_fault', Trigger.Request()).success
    m.drive(0.2, 0.0, 1.0)
    assert m.sim[2].state == 'OPERATION ENABLED'
    # running again, back towards its grid (at most one plant pitch away: feed-forward ±
    # max_correction 2 rad/s)
    assert 2 * math.pi * 0.2 / D - 2.1 <= m.speed(2) <= 2 * math.pi * 0.2 / D + 2.1
    # a lost heartbeat is one row's too
    m.sim[1].set_heartbeat_enabled(False)
    m.drive(0.2, 0.0, 1.0)
    assert 'heartbeat' in m.diag('left').message and m.sync.engine.unit('left').command == 0.0
    # the right row still runs (on its way back to its grid after its own reset)
    assert m.sync.engine.unit('right').halt is None and m.speed(2) > 0.5 * 2 * math.pi * 0.2 / D


def test_section_off_stops_a_row_on_and_it_plants_again_the_other_row_runs_on(machine):
    m = machine()
    m.drive(0.2, 0.0, 2.0)
    res = m.call(SetBool, 'left/section', SetBool.Request(data=False))
    assert res.success and 'off' in res.message
    m.drive(0.2, 0.0, 1.5)
    assert m.speed(1) == pytest.approx(0.0, abs=0.05)
    assert m.sim[1].state == 'OPERATION ENABLED'            # stopped, not disabled
    assert m.average_speeds(0.2, 0.0)[2] == pytest.approx(2 * math.pi * 0.2 / D, rel=0.03)
    left = m.diag('left')
    assert values(left)['section'] == 'off' and 'section off (at rest)' in \
        values(left)['state']
    # at rest out of the soil: away from the planting angle π (five-bar, nozzle at the bottom)
    rest = m.joints[-1].position[0] % (2 * math.pi)
    assert abs(rest - math.pi) > 0.5
    assert m.call(SetBool, 'left/section', SetBool.Request(data=True)).success
    m.drive(0.2, 0.0, 1.5)
    assert m.average_speeds(0.2, 0.0)[1] == pytest.approx(2 * math.pi * 0.2 / D, rel=0.03)


def test_a_disabled_row_is_never_enabled_and_a_silent_drive_is_left_out(machine):
    rows = {'a': (1.0, 1), 'b': (0.0, 2), 'c': (-1.0, 3)}
    m = machine(rows=rows, disabled=('b',), answering=(1,), step_timeout=0.2)
    # b is disabled in the scene: no simulated drive answers to it and none is asked for;
    # c's drive (node 3) is absent: left out, a keeps running
    m.drive(0.2, 0.0, 2.0)
    assert m.average_speeds(0.2, 0.0)[1] == pytest.approx(2 * math.pi * 0.2 / D, rel=0.03)
    assert [u.running for u in m.sync.engine.units] == [True, False, False]
    b, c = m.diag('b'), m.diag('c')
    assert b.level == DiagnosticStatus.OK and 'disabled in the scene' in b.message
    assert c.level == DiagnosticStatus.ERROR and 'left out' in c.message
    assert 'drive node 3' in c.message
    res = m.call(SetBool, 'b/section', SetBool.Request(data=True))
    assert not res.success and 'disabled' in res.message
    assert values(m.diag('bus'))['drives on the bus'] == '2'


def test_a_disabled_row_gets_no_frame_on_the_bus(ros):
    """Its drive on the bus stays switched-on-disabled and never sees an RPDO."""
    channel = unique_channel('disabled')
    sims = SimulatedBus(channel, [1, 2])
    sims.start()
    try:
        overrides = [Parameter('can_interface', value='virtual'),
                     Parameter('can_channel', value=channel),
                     Parameter('rows', value=['a', 'b']),
                     Parameter('command_timeout', value=DEADLINE)]
        for name, node, on in (('a', 1, True), ('b', 2, False)):
            overrides += [Parameter(f'{name}.lateral_offset', value=0.0 if on else 1.0),
                          Parameter(f'{name}.drive_node_id', value=node),
                          Parameter(f'{name}.enabled', value=on)]
        sync = ros.add(SyncNode(context=ros.context, parameter_overrides=overrides))
        sync.enable_drive()
        ros.spin_for(0.5)
        a, b = sims.drives
        assert a.state == 'OPERATION ENABLED' and a.rpdo_count > 0
        assert b.state == 'SWITCH ON DISABLED' and b.rpdo_count == 0
        assert b.nmt_state == 'PRE-OPERATIONAL'
        sync.shutdown_drive()
    finally:
        sims.stop()


def test_a_three_arm_machine_with_rows(machine):
    from pathlib import Path
    from planter_ros.design import design_for_scene, to_dict
    from planter_ros.scene import load_scene
    scene = load_scene(Path(__file__).resolve().parents[1] / 'config' / 'rice_three_arm.yaml')
    design = design_for_scene(scene)
    d = design.plant_spacing
    m = machine(design=to_dict(design))                # as the topic carries it
    v, w = 0.3, -0.03                                 # a 10 m right turn
    m.drive(v, w, 2.0)
    assert m.joints[-1].name == ['left/carrier', 'right/carrier']
    speeds = m.average_speeds(v, w)
    for y, node in ROWS.values():
        assert speeds[node] == pytest.approx(2 * math.pi * (v - w * y) / (3 * d), rel=0.03)
    assert m.sync.engine.unit('left').law.planting is not None     # section stops know the arms


def test_joint_states_carry_every_row_at_one_instant(machine):
    m = machine()
    m.drive(0.2, 0.0, 1.0)
    msg: JointState = m.joints[-1]
    assert len(msg.position) == len(msg.velocity) == 2
    # both rows run in step: their angles at one stamp agree to the feedback period's travel
    assert abs(msg.position[0] - msg.position[1]) < 0.3


def test_a_section_off_and_on_reaches_the_monitor_through_the_sections_topic(machine, ros):
    """The sync node says each switch on `sections` (latched, stamped at the switch); the
    monitor ends that row's spacing sequence there, so the first plant after the section is on
    again has no spacing instead of reading as a miss. The monitor reads nothing from
    /diagnostics: the old form of the section states there changes nothing."""
    from diagnostic_msgs.msg import DiagnosticArray
    from planter_ros import diagnostics
    from planter_ros.nodes.monitor_node import MonitorNode
    from planter_ros.prediction import Plants
    params = [Parameter('record', value=False), Parameter('rows', value=list(ROWS))]
    for name, (y, node) in ROWS.items():
        params += [Parameter(f'{name}.lateral_offset', value=y),
                   Parameter(f'{name}.drive_node_id', value=node)]
    # first: once the drives are enabled, nothing may keep the executor from the control loop
    monitor = ros.add(MonitorNode(context=ros.context, namespace='/',
                                  parameter_overrides=params))
    m = machine(design={**TOMATO, 'nozzle_width': 0.02})
    sections = []
    interfaces.SECTIONS.subscribe(m.io, sections.append)
    assert ros.spin_until(lambda: monitor.has_design and sections)
    assert list(sections[-1].name) == ['left', 'right'] and list(sections[-1].position) == [1, 1]
    m.drive(0.2, 0.0, 2.0)
    assert m.call(SetBool, 'left/section', SetBool.Request(data=False)).success
    m.drive(0.2, 0.0, 1.5)
    # the old form on /diagnostics, as the sync node published it before `sections`: the right
    # row "off" and "on" again; a monitor reading it would break the right row's sequence
    fake = m.io.create_publisher(DiagnosticArray, '/diagnostics', 10)
    for state in ('off', 'on'):
        fake.publish(diagnostics.array([(diagnostics.Report(
            'right', diagnostics.OK, 'tracking', ((diagnostics.SECTION, state),)), 'x')],
            'sync_node'))
        m.drive(0.2, 0.0, 0.1)
    assert m.call(SetBool, 'left/section', SetBool.Request(data=True)).success
    on = m.sync.get_clock().now().nanoseconds * 1e-9
    m.drive(0.2, 0.0, 3.0)
    assert [list(s.position) for s in sections[-2:]] == [[0, 1], [1, 1]]
    plants = Plants.from_table(np.vstack(monitor.published_tables()))
    left = plants.row == 0
    right = plants.row == 1
    first_after = np.flatnonzero(left & (plants.time > on))[0]
    assert np.isnan(plants.spacing[first_after])            # a new sequence, not a miss
    assert np.count_nonzero(np.isnan(plants.spacing[left])) == 2
    assert np.nanmax(plants.spacing[left]) < 1.5 * D
    assert np.count_nonzero(np.isnan(plants.spacing[right])) == 1    # only its first
