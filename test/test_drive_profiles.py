"""Every dictionary profile (test/eds/*.eds, modelled on real drives' dictionaries) on the strict
simulated drive, as a machine with one row per profile on one bus, the way the demo runs it (the
drives in a process of their own, on their own clock, over a CAN socket pair): start-up by each
drive's plan with SYNC from the NMT start, homing (method 34, the index pulse) in the start,
CSP_S (15 s) of cyclic synchronous position phase-locked to the ground, and a power cycle of every
running drive, each configured again and back in step. The profiles a CSP row cannot run on
(EPOS2-like: no CSP; PRL-like: 607Ah not mappable) are left out before anything moves, each in
one line naming the object it lacks."""
from __future__ import annotations

import logging
import math
import time

import numpy as np
import pytest

from cli_helpers import REPO
from drive_helpers import run_engine
from planter_ros.command.engine import CommandEngine
from planter_ros.command.settings import CommandSettings
from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.control.machine_law import TurnConfig
from planter_ros.control.phase_lock import PhaseLockConfig
from planter_ros.design import from_json, to_json
from planter_ros.drive.cia402 import DriveConfig
from planter_ros.drive.plan import plan_for_file
from planter_ros.drive.setup import DriveSetup
from planter_ros.drive.socket_bus import SocketPairBus, socket_pair
from planter_ros.drive.states import CYCLIC_SYNC_POSITION, SWITCH_ON_DISABLED
from planter_ros.rows import Row
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
from planter_ros.sensing.row_speed import YawRateLimits
from planter_ros.simdrive.process import SimProcess
from planter_ros.sim.runs import five_bar_design_message

EDS = REPO / 'test' / 'eds'
PROFILES = sorted(p.stem for p in EDS.glob('*.eds'))
GEAR, COUNTS, SPACING, SPEED = 20.0, 4096, 0.3, 0.3
# s of CSP at SPEED: the phase lock is judged over its last 10 s. Measured (30 s run): every
# profile's median |phase error| is 0.015 rad in the 2nd second and <= 0.005 rad from the 3rd
# on, against 0.15 allowed, so 5 s before the judged 10 s leave the lock ample time.
CSP_S = 15.0
REFUSED = {'epos2_like': '0x6502 supported drive modes', 'prl_like': '0x607A target position'}

pytestmark = pytest.mark.realtime


@pytest.mark.slow
def test_every_profile_runs_start_up_csp_homing_and_a_power_cycle_or_is_refused_first():
    rows = [Row(i, name, 0.5 * i, i + 1) for i, name in enumerate(PROFILES)]
    setups = {row.name: DriveSetup(modes=('csp', 'pv'), homing_method=34,
                                   eds=str(EDS / f'{row.name}.eds'), gear_ratio=GEAR,
                                   encoder_counts=COUNTS) for row in rows}
    # each drive serves its own profile's dictionary and offers what its 6502h says; the
    # drives stand for hardware: SCHED_FIFO just below the command process's priority, as in
    # the demo (at nice 0 a 58 ms stall of their process beside the suite's other work once
    # tripped every drive's following-error window)
    ours, theirs = socket_pair()
    sims = SimProcess(ours.fileno(), [row.drive_node_id for row in rows], supported_modes=None,
                      priority=SyncLoopConfig().realtime_priority - 1,
                      gear_ratio=GEAR, counts_per_motor_rev=COUNTS,
                      node_kwargs={row.drive_node_id: {'eds_path': setups[row.name].eds}
                                   for row in rows})
    ours.close()
    lines = []
    config = DriveConfig(can_interface='socketpair', can_channel='profiles',
                         can_bitrate=1_000_000, step_timeout=0.5)
    law = (PhaseLockConfig(), GroundSpeedLimits(), YawRateLimits(), TurnConfig())
    bus = SocketPairBus(theirs)
    engine = CommandEngine(CommandSettings(config, SyncLoopConfig(), rows, law, setups=setups),
                           bus=bus, log=lambda level, text: lines.append((level, text)))
    try:
        engine.enable()
        units = {unit.label: unit for unit in engine.units}
        for name in REFUSED:                # left out before enabling, one line naming it
            left = units[name].left_out
            assert REFUSED[name] in left and '\n' not in left, left
        running = [units[name] for name in PROFILES if name not in REFUSED]
        for unit in running:
            assert unit.running and unit.csp, (unit.label, unit.left_out)
            # the plan the start carried out is the one the machine file's check makes
            assert unit.drive.plan == plan_for_file(setups[unit.label].eds, unit.drive.config,
                                                    setups[unit.label])
        design = to_json(five_bar_design_message(spacing=SPACING))
        engine.set_design(from_json(design), design, time.monotonic())
        start = {unit.label: unit.drive.status().position for unit in running}
        errors = {unit.label: [] for unit in running}

        def record(now):
            for unit in running:
                errors[unit.label].append(unit.law.phase_error(now))
        run_engine(engine, CSP_S, SPEED, after_step=record)
        turns = CSP_S * SPEED / SPACING             # a plant (a turn) every SPACING m
        for unit in running:
            turned = unit.status.position - start[unit.label]
            # that many turns, less at most 5 for the ramp up (30.0 of 30 measured)
            assert (turns - 5) * 2 * math.pi < turned < (turns + 1) * 2 * math.pi, (
                unit.label, turned, [text for _, text in lines if unit.label in text])
            assert unit.halt is None and unit.faults == 0, unit.last_fault
            # phase-locked: the last 10 s within 0.15 rad of the ground's phase (median)
            assert np.median(np.abs(errors[unit.label][-1000:])) < 0.15, unit.label
        assert not [text for level, text in lines if level >= logging.ERROR and not
                    text.startswith(('row epos2_like left out', 'row prl_like left out'))]
        # a power cycle of every running drive: each boots, is configured again by its plan
        # (SYNC flowing meanwhile) and comes back in step
        for unit in running:
            sims.inject('power_cycle', unit.row.drive_node_id, 1.0)
        done = run_engine(engine, 20.0, SPEED, after_step=lambda now: all(
            u.recovery.restarts == 1 and not u.recovery.episode for u in running))
        assert done, [text for _, text in lines if 'restart' in text or 'again' in text]
        for unit in running:
            assert unit.recovery.recoveries[-1].in_step, unit.recovery.recoveries[-1]
            assert unit.status.enabled and unit.status.mode == CYCLIC_SYNC_POSITION
    finally:
        engine.shutdown()
        report = sims.stop()
        bus.shutdown()
    drives = report['end']
    for row in rows:
        node = str(row.drive_node_id)
        if row.name in REFUSED:
            end = {key: drives[node][key] for key in ('state', 'mode', 'nmt', 'homed')}
            assert end == {'state': SWITCH_ON_DISABLED, 'mode': 0,
                           'nmt': 'PRE-OPERATIONAL', 'homed': 0}, (row.name, drives[node])
            continue
        # the drive itself ran cyclic synchronous position to the end
        assert drives[node]['mode'] == CYCLIC_SYNC_POSITION, (row.name, drives[node])
        # homed at the start and again after the power cycle (its encoder counts on)
        assert drives[node]['homed'] == 1 and report['faults'][node]['power_cycles'] == 1
        assert report['sync'][node]['following_error_faults'] == 0, row.name
    assert report['watchdog_trips'] == []
