"""The row loop as a pure step (control.row_loop): made-up drive snapshots in, each row's command
and status out; no ROS, no CAN."""
from dataclasses import dataclass, replace
import math

import pytest

from planter_ros.control import sync_status
from planter_ros.control.machine_law import Machine
from planter_ros.control.row_loop import CSP_LEAD, RowLoop, csp_setpoint
from planter_ros.drive.state_names import FAULT, OPERATION_ENABLED

D = 0.2


@dataclass(frozen=True)
class Snap:                         # the fields of drive.cia402.DriveStatus the loop reads
    state: str = OPERATION_ENABLED
    fault: bool = False
    fault_reason: str = ''
    error_code: int = 0
    heartbeat_age: float = 0.01
    position: float = 0.0
    velocity: float = 0.0
    stamp: float = 0.0


def machine_loop(offsets=(0.0,)):
    machine = Machine(list(offsets))
    loop = RowLoop(machine, heartbeat_period=0.125, heartbeat_timeout=0.35)
    for i in range(len(offsets)):
        loop.enabled(i)
    return machine, loop


def run(loop, machine, v, seconds, dt=0.01, t0=0.0, snaps=None, w=0.0):
    """Feed v and a drive that does exactly what it is told; returns the last step."""
    n = len(machine.laws)
    angle = [0.0] * n
    speed = [0.0] * n
    t = t0
    step = None
    while t < t0 + seconds - 1e-9:
        machine.sample(v, w, t)
        statuses = snaps(t) if snaps else [Snap(position=angle[i], velocity=speed[i], stamp=t)
                                          for i in range(n)]
        step = loop.step(statuses, [True] * n, t)
        for i, row in enumerate(step.rows):
            speed[i] = row.command
            angle[i] += row.command * dt
        t += dt
    return step, angle


def test_a_row_follows_the_phase_locked_speed_of_its_ground():
    machine, loop = machine_loop()
    machine.set_design(D, 1, 0.0)
    step, angle = run(loop, machine, 0.5, 8.0)
    assert step.rows[0].halt is None and step.rows[0].running
    assert step.rows[0].command == pytest.approx(2 * math.pi * 0.5 / D, rel=0.02)
    # locked to travelled distance: the start-up lag is made up (to within a whole pitch)
    assert machine.laws[0].phase_error(8.0) == pytest.approx(0.0, abs=0.05)


def test_rows_on_a_curve_run_at_their_own_speeds():
    machine, loop = machine_loop((-1.0, 1.0))
    machine.set_design(D, 1, 0.0)
    step, _ = run(loop, machine, 0.4, 8.0, w=0.1)        # left turn: left row slower
    right, left = (row.command for row in step.rows)
    assert right == pytest.approx(2 * math.pi * 0.5 / D, rel=0.03)
    assert left == pytest.approx(2 * math.pi * 0.3 / D, rel=0.03)


def test_a_faulted_drive_gets_zero_and_the_change_is_flagged_once():
    machine, loop = machine_loop((0.0, 0.5))
    machine.set_design(D, 1, 0.0)
    run(loop, machine, 0.5, 1.0)
    faulted = [Snap(state=FAULT, fault=True, fault_reason='EMCY 0x7500', error_code=0x7500,
                    stamp=1.0), Snap(stamp=1.0)]
    first = loop.step(faulted, [True, True], 1.0)
    second = loop.step(faulted, [True, True], 1.01)
    assert first.rows[0].command == 0.0 and first.rows[0].changed
    assert first.rows[0].halt.kind == sync_status.FAULTED and '0x7500' in first.rows[0].halt.text
    assert not second.rows[0].changed and second.rows[0].command == 0.0
    assert first.rows[1].halt is None and first.rows[1].command > 0.0   # the other row runs


def test_a_lost_heartbeat_halts_and_recovery_ramps_up_from_zero():
    machine, loop = machine_loop()
    machine.set_design(D, 1, 0.0)
    run(loop, machine, 0.5, 1.0)
    lost = loop.step([Snap(heartbeat_age=1.0, stamp=1.0)], [True], 1.0)
    assert lost.rows[0].halt.kind == sync_status.HEARTBEAT_LOST and lost.rows[0].command == 0
    machine.sample(0.5, 0.0, 1.01)
    back = loop.step([Snap(stamp=1.01)], [True], 1.01)
    assert back.rows[0].changed and back.rows[0].halt is None
    # acceleration-limited from 0 (max_acceleration 20 rad/s² × 10 ms)
    assert 0.0 < back.rows[0].command <= 0.2 + 1e-9


def test_stale_ground_speed_ramps_the_command_to_zero():
    machine, loop = machine_loop()
    machine.set_design(D, 1, 0.0)
    run(loop, machine, 0.5, 1.0)
    t, command = 1.0, None
    while t < 4.0:                          # no more samples
        command = loop.step([Snap(stamp=t)], [True], t).rows[0].command
        t += 0.01
    assert command == 0.0
    assert machine.laws[0].state(t).startswith('halted')


def test_a_row_switched_off_comes_to_rest_and_the_heartbeat_is_due_once_per_period():
    machine, loop = machine_loop()
    machine.set_design(D, 1, 0.0)
    run(loop, machine, 0.5, 1.0)
    machine.laws[0].switch(False, 1.0)
    step, _ = run(loop, machine, 0.5, 3.0, t0=1.0)
    assert step.rows[0].command == 0.0 and machine.laws[0].parked
    beats = [loop.step([Snap(stamp=t)], [True], t).heartbeat
             for t in (16.0, 16.0625, 16.125, 16.1875, 16.25)]
    assert beats == [True, False, True, False, True]


def test_rows_not_running_are_not_commanded_and_no_heartbeat_without_any():
    machine, loop = machine_loop((0.0, 1.0))
    step = loop.step([None, replace(Snap())], [False, False], 0.0)
    assert not any(row.running for row in step.rows) and not step.heartbeat
    with pytest.raises(ValueError, match='2 rows'):
        loop.step([None], [False], 0.0)


def test_stop_ramps_every_row_to_zero_at_its_acceleration_limit_whatever_the_ground():
    machine, loop = machine_loop((0.0, 0.5))
    machine.set_design(D, 1, 0.0)
    step, _ = run(loop, machine, 0.5, 8.0)
    before = [row.command for row in step.rows]
    loop.stop(8.0)
    assert loop.stopping
    machine.sample(0.5, 0.0, 8.5)                        # the ground still moves
    half = loop.step([Snap(stamp=8.5)] * 2, [True, True], 8.5)
    for row, was in zip(half.rows, before):             # 20 rad/s² for 0.5 s
        assert row.command == pytest.approx(max(was - 10.0, 0.0))
    done = loop.step([Snap(stamp=9.5)] * 2, [True, True], 9.5)
    assert all(row.command == 0.0 for row in done.rows)


def test_a_csp_drive_reaching_its_targets_two_syncs_later_does_not_trail_the_law_in_a_ramp():
    # CiA 402 interpolation: a target sent after SYNC k is reached at SYNC k+2. With the lead
    # the drive's set point is on the law's angle through a ramp (off by α·P²·2 only); sent
    # bare it trails by 2·P·ω, more the faster the row turns
    period, alpha = 0.01, 3.0                    # s, rad/s² (the demo's 0.1 m/s² at d = 0.2)
    law_angle = lambda t: 0.5 * alpha * t * t    # noqa: E731
    led, bare = [], []
    for k in range(300):
        t = k * period
        reached = t + CSP_LEAD * period          # when the drive's set point gets there
        led.append(csp_setpoint(law_angle(t), alpha * t, period) - law_angle(reached))
        bare.append(law_angle(t) - law_angle(reached))
    assert max(abs(e) for e in led) <= 2 * alpha * period ** 2 + 1e-12
    assert min(bare) < -0.15                     # 2·P·ω at 9 rad/s: 0.18 rad (5.7 mm)
    # a target already the angle one SYNC ahead (a cam row's) gets the rest of the lead
    assert csp_setpoint(1.0, 5.0, period, ahead=period) == pytest.approx(1.0 + 5.0 * period)


def test_csp_feedback_is_stamped_at_the_sync_that_measured_it():
    syncs = [10.00, 10.01, 10.02]
    arrived = Snap(position=1.0, stamp=10.0115)        # the TPDO of the SYNC at 10.01
    assert sync_status.at_sync(arrived, syncs).stamp == 10.01
    assert sync_status.at_sync(Snap(stamp=9.99), syncs).stamp == 9.99      # none before it
    assert sync_status.at_sync(Snap(stamp=0.0), syncs).stamp == 0.0        # no feedback yet
