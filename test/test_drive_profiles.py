"""Every dictionary profile (test/eds/*.eds, modelled on real drives' dictionaries) on the strict
simulated drive, as a machine with one row per profile on one bus, the way the command process
runs it: start-up by each drive's plan with SYNC from the NMT start, homing (method 34, the
index pulse) in the start, 30 s of cyclic synchronous position phase-locked to the ground, and
a power cycle of every running drive, each configured again and back in step. The profiles a
CSP row cannot run on (EPOS2-like: no CSP; PRL-like: 607Ah not mappable) are left out before
anything moves, each in one line naming the object it lacks."""
from __future__ import annotations

import logging
import time
import uuid

import numpy as np
import pytest

from cli_helpers import REPO
from drive_helpers import run_engine
from planter_ros.command.engine import CommandEngine
from planter_ros.control.loop_timing import SyncLoopConfig
from planter_ros.control.machine import TurnConfig
from planter_ros.control.phase_lock import PhaseLockConfig
from planter_ros.design import from_json, to_json
from planter_ros.drive.cia402 import DriveConfig
from planter_ros.drive.plan import plan_for_file
from planter_ros.drive.setup import DriveSetup
from planter_ros.drive.states import CYCLIC_SYNC_POSITION, OPERATION_ENABLED
from planter_ros.rows import Row
from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
from planter_ros.sensing.row_speed import YawRateLimits
from planter_ros.simdrive.bus import SimulatedBus
from planter_ros.sim.runs import five_bar_design_message

EDS = REPO / 'test' / 'eds'
PROFILES = sorted(p.stem for p in EDS.glob('*.eds'))
GEAR, COUNTS = 20.0, 4096
REFUSED = {'epos2_like': '0x6502 supported drive modes', 'prl_like': '0x607A target position'}


@pytest.mark.slow
def test_every_profile_runs_start_up_csp_homing_and_a_power_cycle_or_is_refused_first():
    channel = f'planter-test-{uuid.uuid4().hex}'
    rows = [Row(i, name, 0.5 * i, i + 1) for i, name in enumerate(PROFILES)]
    setups = {row.name: DriveSetup(modes=('csp', 'pv'), homing_method=34,
                                   eds=str(EDS / f'{row.name}.eds'), gear_ratio=GEAR,
                                   encoder_counts=COUNTS) for row in rows}
    # each drive serves its own profile's dictionary and offers what its 6502h says
    sims = SimulatedBus(channel, [row.drive_node_id for row in rows], supported_modes=None,
                        gear_ratio=GEAR, counts_per_motor_rev=COUNTS,
                        node_kwargs={row.drive_node_id: {'eds_path': setups[row.name].eds}
                                     for row in rows})
    sims.start()
    lines = []
    config = DriveConfig(can_interface='virtual', can_channel=channel, can_bitrate=1_000_000,
                         step_timeout=0.5)
    law = (PhaseLockConfig(), GroundSpeedLimits(), YawRateLimits(), TurnConfig())
    engine = CommandEngine(config, SyncLoopConfig(), rows, law, setups=setups,
                           log=lambda level, text: lines.append((level, text)))
    try:
        engine.enable()
        units = {unit.label: unit for unit in engine.units}
        for name in PROFILES:
            sim = sims.drives[PROFILES.index(name)]
            if name in REFUSED:
                # left out before enabling, in one line naming the object it lacks
                left = units[name].left_out
                assert REFUSED[name] in left and '\n' not in left, left
                assert sim.state != OPERATION_ENABLED and sim.nmt_state == 'PRE-OPERATIONAL'
                continue
            unit = units[name]
            assert unit.running and unit.csp, (name, unit.left_out)
            # the plan the start carried out is the one the machine file's check makes
            assert unit.drive.plan == plan_for_file(setups[name].eds, unit.drive.config,
                                                    setups[name])
            assert sim.mode_display == CYCLIC_SYNC_POSITION and sim.state == OPERATION_ENABLED
            assert sim.device.homing.homed == 1, name         # homed in the start
        running = [units[name] for name in PROFILES if name not in REFUSED]
        assert len(running) == 5
        design = to_json(five_bar_design_message(spacing=0.3))
        engine.set_design(from_json(design), design, time.monotonic())
        start = {u.label: sims.drives[PROFILES.index(u.label)].motor_position for u in running}
        errors = {u.label: [] for u in running}

        def record(now):
            for unit in running:
                errors[unit.label].append(unit.law.phase_error(now))
        run_engine(engine, 30.0, 0.3, after_step=record)
        for unit in running:
            sim = sims.drives[PROFILES.index(unit.label)]
            turned = (sim.motor_position - start[unit.label]) / GEAR
            # 30 s at 0.3 m/s with a plant every 0.3 m: 30 plants, 2π each (the ramp up)
            assert 25 * 2 * np.pi < turned < 31 * 2 * np.pi, (unit.label, turned)
            assert np.median(np.abs(errors[unit.label][-1000:])) < 0.15, unit.label
            assert sim.state == OPERATION_ENABLED and sim.following_error_faults == 0
            assert sim.watchdog_trips == [], unit.label
        # no error but the two left out, up to here
        assert not [text for level, text in lines if level >= logging.ERROR and not
                    text.startswith(('row epos2_like left out', 'row prl_like left out'))]
        # a power cycle of every running drive: each boots, is configured again by its plan
        # (SYNC flowing meanwhile) and comes back in step
        for unit in running:
            sims.drives[PROFILES.index(unit.label)].power_cycle(1.0)
        done = run_engine(engine, 20.0, 0.3, after_step=lambda now: all(
            u.recovery.restarts == 1 and not u.recovery.episode for u in running))
        assert done, [text for _, text in lines if 'restart' in text or 'again' in text]
        for unit in running:
            sim = sims.drives[PROFILES.index(unit.label)]
            assert sim.power_cycles == 1 and sim.state == OPERATION_ENABLED, unit.label
            assert sim.mode_display == CYCLIC_SYNC_POSITION
            assert unit.recovery.recoveries[-1]['in_step'], unit.recovery.recoveries[-1]
    finally:
        engine.shutdown()
        sims.stop()
