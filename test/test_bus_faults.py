"""Faults a real CAN bus has, each with the recovery that plants on (doc/command.md, "Faults and
their recovery"): a drive power-cycled mid-run, bus-off and send errors, 10 % of the frames
lost, a drive slow to answer SDOs, an EMCY storm. The command engine runs two CSP rows on a
virtual bus; the faults come from the simulated drives (`power_cycle`, `sdo_delay`,
`emcy_storm`) and from `FaultBus` around the master's bus (loss, send errors, bus-off).

Plants are counted from the simulated drives' true shaft angle against each row's travelled
distance: a plant where the angle passes a whole plant pitch."""
import logging
import math
import time
import uuid

import can
import numpy as np
import pytest

from drive_helpers import run_engine
from planter_ros.command.engine import CommandEngine
from planter_ros.command.settings import CommandSettings
from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.control.machine_law import TurnConfig
from planter_ros.control.phase_lock import PhaseLockConfig
from planter_ros.design import from_json, to_json
from planter_ros.drive.cia402 import DriveConfig
from planter_ros.drive.errors import DriveError
from planter_ros.simdrive.fault_bus import FaultBus
from planter_ros.simdrive.bus import SimulatedBus
from planter_ros.drive.states import (CYCLIC_SYNC_POSITION, FAULT, OPERATION_ENABLED,
                                      PROFILE_VELOCITY)
from planter_ros.rows import Row
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
from planter_ros.sensing.row_speed import YawRateLimits
from planter_ros.sim.runs import five_bar_design_message

pytestmark = pytest.mark.realtime          # (test/conftest.py)

BOTH = (PROFILE_VELOCITY, CYCLIC_SYNC_POSITION)
D = 0.2                     # m, plant spacing
V = 0.3                     # m/s, ground speed: 1.5 plants per second per row
ROWS = (Row(0, 'a', 0.0, 1), Row(1, 'b', 1.0, 2))


class Rig:
    """Two CSP rows: simulated drives on a virtual channel, the engine's master on a FaultBus
    around its own end; the engine's log lines kept."""

    def __init__(self, sims_kwargs=None, bus_kwargs=None, **drive):
        self.channel = f'planter-faults-{uuid.uuid4().hex}'
        self.sims = SimulatedBus(self.channel, [1, 2], supported_modes=BOTH,
                                 **(sims_kwargs or {}))
        self.sims.start()
        self.bus = FaultBus(can.Bus(interface='virtual', channel=self.channel),
                            **(bus_kwargs or {}))
        drive.setdefault('step_timeout', 0.5)
        config = DriveConfig(can_interface='virtual', can_channel=self.channel, **drive)
        law = (PhaseLockConfig(), GroundSpeedLimits(), YawRateLimits(), TurnConfig())
        self.lines = []
        self.engine = CommandEngine(CommandSettings(config, SyncLoopConfig(), list(ROWS), law),
                                    bus=self.bus,
                                    log=lambda level, text: self.lines.append((level, text)))
        self.trace = []                 # (time, [(s, θ) per row])

    def start(self):
        self.engine.enable()
        assert self.engine.csp
        design = to_json(five_bar_design_message(spacing=D))
        self.engine.set_design(from_json(design), design, time.monotonic())

    def run(self, seconds, v=V, until=None):
        """The command process's loop in miniature (a speed sample every 20 ms, a step every
        SYNC), recording each row's travelled distance and true shaft angle; True once
        `until()` holds (then it stops), else after `seconds`."""
        engine = self.engine

        def record(now):
            self.trace.append((now, [(unit.law.travelled(now), sim.motor_position)
                                     for unit, sim in zip(engine.units, self.sims.drives)]))
            return until is not None and until()
        return run_engine(engine, seconds, v, after_step=record) or until is None

    def plants(self, row, since=0.0):
        """(distance of each plant along the row, and the grid's plant count) since `since`
        (monotonic s): a plant where the true shaft angle passes a whole pitch."""
        trace = [(t, rows[row]) for t, rows in self.trace if t >= since]
        s = np.array([r[0] for _, r in trace])
        theta = np.array([r[1] for _, r in trace])
        law = self.engine.units[row].law
        pitch = 2 * math.pi / law.plants_per_revolution
        k = np.floor(theta / pitch)
        at = np.nonzero(np.diff(k) > 0)[0]
        # distance where the angle reached the pitch (linear between two records)
        frac = (pitch * k[at + 1] - theta[at]) / (theta[at + 1] - theta[at])
        positions = s[at] + frac * (s[at + 1] - s[at])
        return positions, (s[-1] - s[0]) / law.spacing

    def logged(self, text):
        return [line for _, line in self.lines if text in line]

    def close(self):
        self.engine.shutdown()
        self.sims.stop()
        self.bus.shutdown()


@pytest.fixture
def rig():
    made = []

    def make(**kwargs):
        r = Rig(**kwargs)
        made.append(r)
        return r
    yield make
    for r in made:
        r.close()


def steady_spacing(positions, skip=2):
    spacing = np.diff(positions)[skip:]
    assert spacing.size >= 3
    return spacing


# --------------------------------------------------------------------------- power cycle
def test_a_power_cycled_drive_is_configured_again_resumes_and_the_plants_missed_are_counted(
        rig):
    r = rig()
    r.start()
    r.run(3.0)
    engine, sim_b = r.engine, r.sims.drives[1]
    a, b = engine.units
    cut = time.monotonic()
    sim_b.power_cycle(1.5)
    # it boots (700h + 2, data 00h), the master sees it, writes its configuration again
    # (PDO mapping, CSP, SYNC, heartbeats, watchdogs) through the one start-up path and
    # re-enables it; the row is back in step with its grid
    assert r.run(10.0, until=lambda: b.recovery.recoveries and not b.recovery.episode), \
        r.lines[2:]
    r.run(3.0)
    assert sim_b.power_cycles == 1 and b.recovery.restarts == 1
    assert sim_b.nmt_state == 'OPERATIONAL' and sim_b.state == OPERATION_ENABLED
    assert sim_b.mode_display == CYCLIC_SYNC_POSITION
    assert sim_b.sync_summary()['period'] == pytest.approx(0.01)     # 0x1006 written again
    assert sim_b.heartbeat_period == pytest.approx(0.05)              # 0x1017 written again
    record = b.recovery.recoveries[-1]
    assert record.restarted and record.in_step
    assert r.logged('the drive restarted (boot-up message): configured again')
    # the plants missed, as counted by the engine, are the ones the true shaft angle did not
    # set against the grid of the row's travelled distance
    positions, grid = r.plants(1, since=cut - 0.5)
    set_by_shaft = positions.size
    assert record.plants_missed >= 1, (str(record), str(r.lines[2:]))
    assert abs((grid - set_by_shaft) - record.plants_missed) <= 1.0
    assert b.recovery.plants_missed == record.plants_missed
    assert r.logged(f'{record.plants_missed} plant(s) missed')
    # visible to the user: the row's /diagnostics and the run's final report
    report = dict(next(rep for rep, _ in engine.reports(time.monotonic())
                       if rep.task == 'b').values)
    assert report['plants missed (halts)'] == record.plants_missed
    assert report['drive restarts'] == 1
    final = {row.label: row for row in engine.final_report().rows}
    assert final['b'].plants_missed == record.plants_missed and final['b'].restarts == 1
    # after it, row b plants at the spacing again; row a never stopped
    late = steady_spacing(r.plants(1, since=time.monotonic() - 3.0)[0], skip=0)
    assert np.all(np.abs(late - D) < 0.1 * D)
    assert not a.recovery.recoveries and a.faults == 0
    assert r.sims.watchdog_trips == []


def test_a_restarted_drive_whose_boot_up_message_was_lost_is_found_by_asking_it(rig):
    r = rig()
    r.start()
    r.run(2.0)
    b, sim_b = r.engine.units[1], r.sims.drives[1]
    # its boot-up frame lost on the bus, and (as the EDS default) no heartbeat after a boot
    r.bus.drop(0x702)
    sim_b.power_cycle(0.3)
    assert r.run(10.0, until=lambda: b.recovery.restarts == 1 and b.halt is None)
    assert sim_b.state == OPERATION_ENABLED
    assert r.logged('heartbeat producer 0x1017 reads 0 ms')


# --------------------------------------------------------------------------- bus-off, send errors
def test_bus_off_and_send_errors_are_counted_reported_and_the_rows_resume(rig):
    r = rig()
    r.start()
    r.run(2.5)
    engine = r.engine
    # a short bus-off (below every watchdog): counted, reported, nothing stops
    r.bus.bus_off(0.1)
    r.run(0.05)
    bus = next(rep for rep, _ in engine.reports(time.monotonic()) if rep.task == 'bus')
    assert bus.level == 2 and 'bus-off' in bus.message          # ERROR on /diagnostics
    r.run(1.0)
    assert engine.send_errors > 0 and r.sims.watchdog_trips == []
    assert all(unit.halt is None for unit in engine.units), r.lines[2:]
    # random send errors (a full transmit queue) for a while: the run goes on
    r.bus.send_error_rate = 0.05
    r.run(1.0)
    r.bus.send_error_rate = 0.0
    assert r.bus.counts['send_errors'] > 0 and r.sims.watchdog_trips == []
    # a long bus-off: the drives' own watchdogs stop them (RPDO deadline, heartbeat), the
    # receive errors do not end the master's bus reader, and once the bus is back the master
    # re-enables them and the rows plant on
    before = engine.send_errors
    r.bus.bus_off(0.8)
    r.run(0.9)
    assert engine.send_errors > before and r.bus.counts['bus_off_receives'] > 0
    assert engine.drives.canbus.receive_errors.count > 0
    assert r.sims.watchdog_trips                                  # they stopped, as they must
    assert r.run(8.0, until=lambda: all(u.recovery.episode is None and u.halt is None
                                        for u in engine.units)), r.lines[2:]
    assert all(sim.state == OPERATION_ENABLED for sim in r.sims.drives)
    for unit in engine.units:
        record = unit.recovery.recoveries[-1]
        assert record.bus and record.in_step and record.auto_resets >= 1
    assert r.logged('back (no error for')
    assert r.logged('the CAN bus is back: re-enabling the drive')
    # feedback flows again: the bus reader survived
    stamp = engine.units[0].status.stamp
    r.run(0.5)
    assert engine.units[0].status.stamp > stamp
    final = engine.final_report()
    assert final.send_errors > 0 and final.receive_errors > 0


def test_a_drive_fault_of_its_own_is_not_reset_by_the_bus_recovery(rig):
    r = rig()
    r.start()
    r.run(2.0)
    r.sims.drives[1].inject_fault(0x7500)
    r.bus.bus_off(0.3)
    r.run(2.5)
    b = r.engine.units[1]
    assert r.sims.drives[1].state == FAULT and b.halt is not None
    assert b.recovery.auto_resets == 0 and b.command == 0.0


# --------------------------------------------------------------------------- 10 % frame loss
def test_ten_percent_of_frames_lost_both_ways_the_plants_still_come_at_the_spacing(rig):
    # at the default settings (heartbeats every 50 ms both ways: doc/command.md)
    r = rig(bus_kwargs={'seed': 7})
    r.start()
    r.run(2.5)
    start = time.monotonic()
    r.bus.loss = 0.10
    r.run(8.0)
    counts = r.bus.counts
    sent = counts['sent'] + counts['lost_sent']
    received = counts['received'] + counts['lost_received']
    assert 0.05 < counts['lost_sent'] / sent < 0.15
    assert 0.05 < counts['lost_received'] / received < 0.15
    assert r.sims.watchdog_trips == []
    assert all(sim.following_error_faults == 0 for sim in r.sims.drives)
    for row, unit in enumerate(r.engine.units):
        assert unit.faults == 0 and unit.halt is None
        positions, grid = r.plants(row, since=start)
        spacing = steady_spacing(positions)
        # every plant within 10 % of d, 3 % RMS, and none missing
        assert np.all(np.abs(spacing - D) < 0.10 * D), spacing
        assert np.sqrt(np.mean((spacing - D) ** 2)) < 0.03 * D, spacing
        assert abs(positions.size - grid) <= 1.0


# --------------------------------------------------------------------------- slow SDO answers
def test_a_drive_slow_to_answer_sdos_is_waited_for_and_the_run_starts(rig):
    # one SDO answer in ten takes 0.2-0.8 s (default sdo_timeout 1 s)
    r = rig(sims_kwargs={'sdo_delay': (0.2, 0.8), 'sdo_slow_share': 0.1, 'seed': 3})
    t0 = time.monotonic()
    r.start()
    took = time.monotonic() - t0
    slow = sum(sim.sdo_slow for sim in r.sims.drives)
    assert slow >= 4 and took > 0.2 * slow / 2        # it really waited (two drives at once)
    assert all(unit.running for unit in r.engine.units)
    r.run(2.0)
    assert all(unit.halt is None for unit in r.engine.units)


def test_beyond_the_sdo_timeout_the_start_fails_in_one_line_naming_node_and_object(rig):
    r = rig(sims_kwargs={'sdo_delay': (0.5, 0.5)}, sdo_timeout=0.2)
    with pytest.raises(DriveError) as failed:
        r.engine.enable()
    text = str(failed.value)
    assert '\n' not in text
    assert 'drive node 1' in text and 'drive node 2' in text and '0x1000' in text
    assert 'no SDO answer reading 0x1000 within 2 x 0.2 s' in text


# --------------------------------------------------------------------------- EMCY storm
def test_an_emcy_storm_is_counted_and_logged_without_flooding_and_a_real_fault_still_stops(
        rig):
    r = rig()
    r.start()
    r.run(2.0)
    a, b = r.engine.units
    sim_a, sim_b = r.sims.drives
    start = time.monotonic()
    sim_b.emcy_storm(rate=1000.0, seconds=2.5, code=0x4210)
    r.run(1.0)
    sim_a.inject_fault(0x7500)            # a real fault on the other row, in the storm
    r.run(1.6)
    sent = sim_b.emcy_sent
    assert sent > 2000
    # every EMCY counted; a few log lines, not thousands; canopen's EMCY log stays bounded
    assert b.recovery.emcy_count >= 0.95 * sent
    emcy_lines = r.logged('EMCY from the drive')
    assert 1 <= len(emcy_lines) <= 5
    assert any('EMCY from the drive in the last' in line for line in emcy_lines)
    assert len(b.drive.node.emcy.log) <= 2 * b.drive.EMCY_KEPT
    # the storm's warning latches row b (an EMCY is a fault until reset: commanded 0)
    assert b.halt is not None and b.command == 0.0
    # the real fault stops row a safely: its drive in FAULT at rest, commanded 0
    assert sim_a.state == FAULT and a.halt is not None and a.command == 0.0
    assert abs(sim_a.motor_velocity) < 0.05
    assert r.sims.watchdog_trips == []        # the loop kept feeding both drives
    # row a planted at the spacing until its fault, through the storm
    positions, _ = r.plants(0, since=start)
    assert np.all(np.abs(np.diff(positions)[:-1] - D) < 0.05 * D)
    # the storm over, the operator resets both rows and they plant on
    for unit in (a, b):
        assert r.engine.reset_fault(unit.row.name).ok
    assert r.run(5.0, until=lambda: a.halt is None and b.halt is None)
    assert logging.WARNING in {level for level, line in r.lines if 'EMCY' in line}


# --------------------------------------------------------------------------- drives' own process
def test_faults_are_injected_into_the_drives_process_over_its_stdin():
    from planter_ros.simdrive.process import SimProcess
    from planter_ros.drive.socket_bus import socket_pair
    ours, theirs = socket_pair()
    sims = SimProcess(ours.fileno(), [1, 2], supported_modes=list(BOTH))
    ours.close()
    try:
        theirs.settimeout(0.2)
        with pytest.raises(TimeoutError):          # their boot-up messages at start: read
            while True:
                theirs.recv(64)
        theirs.settimeout(1.0)
        with pytest.raises(ValueError, match='allowed power_cycle, emcy_storm'):
            sims.inject('unplug', 1)
        sims.inject('emcy_storm', 1, 200.0, 0.1)
        sims.inject('power_cycle', 2, 0.05)
        boot = None
        deadline = time.monotonic() + 5.0
        while boot is None and time.monotonic() < deadline:
            packet = theirs.recv(64)
            # a frame: send time (8 bytes), COB-ID (4), DLC, flags, data
            if (packet and int.from_bytes(packet[8:12], 'little') == 0x702
                    and packet[12] == 1 and packet[14] == 0):
                boot = packet                      # its boot-up message: 702h, data 00h
        time.sleep(0.2)
    finally:
        report = sims.stop()
        theirs.close()
    assert boot is not None
    assert report['faults']['1']['emcy_sent'] >= 15 and report['faults']['2']['power_cycles'] == 1
