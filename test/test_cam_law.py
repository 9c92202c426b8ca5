"""The cam in the sync law (speed_profile: cam): the row's target is θ(s) of its own
phase-locked travelled distance, a spacing change is continuous, the CSP targets follow it."""
import dataclasses
import math

import pytest

from planter_ros.cam import CamTrack
from planter_ros.control.cam_law import anchored_track, plan_row_cam
from planter_ros.control.phase_lock import ControlConfigError, PhaseLock, PhaseLockConfig
from planter_ros.design.build import design_for_scene

pytestmark = pytest.mark.realtime          # (test/conftest.py)

V = 0.3


@pytest.fixture(scope='module')
def design():
    """A tomato five-bar designed for 0.15 m (D = 45 mm, k = 0.05)."""
    return design_for_scene({'planting_depth': 0.045, 'plant_spacing': 0.15,
                             'nominal_ground_speed': V, 'nozzle_width': 0.04})


@pytest.fixture(scope='module')
def profiles(design):
    return {d: plan_row_cam(dataclasses.replace(design, plant_spacing=d), 'design_speed')
            for d in (0.15, 0.25, 0.35, 0.5)}


def config(**kw):
    return PhaseLockConfig(speed_profile='cam', max_acceleration=500.0, **kw)


def running_law(profile, theta0=0.4):
    law = PhaseLock(config())
    law.row_speed(V, 0.0)
    law.feedback(theta0, 0.0, 0.0)
    law.set_design(profile.spacing, 1, 0.0, cam=profile)
    return law


def drive_to(law, t, step=0.1):
    """The ground-speed sensor's samples at V every `step` s up to t."""
    u = getattr(law, '_test_clock', 0.0)
    while u + step < t:
        u += step
        law.row_speed(V, u)
    law.row_speed(V, t)
    law._test_clock = t


def test_the_scene_option_is_checked():
    assert PhaseLockConfig().speed_profile == 'constant'
    assert PhaseLockConfig().cam_rule == 'design_speed'
    with pytest.raises(ControlConfigError, match='speed_profile'):
        PhaseLockConfig(speed_profile='wobbly')
    with pytest.raises(ControlConfigError, match='cam_rule'):
        PhaseLockConfig(cam_rule='fast')


def test_the_plan_keeps_the_mechanism_and_takes_the_spacing(design, profiles):
    p = profiles[0.35]
    assert (p.mech.l1, p.mech.l2) == (design.l1, design.l2)
    assert p.spacing == 0.35 and p.rule == 'design_speed' and p.blend == 1.0
    # the design hole at every spacing, not constant speed's drag
    assert p.tip_sweep == pytest.approx(profiles[0.15].tip_sweep, abs=1e-9)


def test_a_three_arm_design_has_no_cam():
    from pathlib import Path

    from planter_ros.scene.files import read_parameter_file
    scene = Path(__file__).resolve().parents[1] / 'config' / 'rice_three_arm.yaml'
    arm = design_for_scene(read_parameter_file(scene).entries[0].params)
    with pytest.raises(ValueError, match='five-bar'):
        plan_row_cam(arm, 'design_speed')


def test_anchored_track_starts_at_the_measured_angle(profiles):
    for theta in (-3.0, 0.0, 0.4, math.pi, 7.5, 40.0):
        track = anchored_track(profiles[0.25], theta, 1.7)
        assert track.evaluate(1.7)[0] == pytest.approx(theta, abs=1e-9)


def test_targets_follow_theta_of_the_travelled_distance(profiles):
    profile = profiles[0.35]
    law = running_law(profile)
    reference = anchored_track(profile, 0.4, 0.0)
    for t in (0.0, 0.05, 0.37, 0.9, 1.6, 2.35):
        drive_to(law, t)
        s = law.travelled(t)
        assert s == pytest.approx(V * t)
        theta, d1, _ = reference.evaluate(s)
        assert law.target_angle(t) == pytest.approx(theta, abs=1e-12)
        assert law.feed_forward(t) == pytest.approx(d1 * V, abs=1e-12)
    # not the straight line of constant speed: within a plant the rate changes
    rates = set()
    for t in (2.4, 2.6, 2.8, 3.0, 3.2, 3.4):
        drive_to(law, t)
        rates.add(round(law.feed_forward(t), 3))
    assert len(rates) > 2
    # plants every d: θ = π (mod 2π) one spacing apart
    plants = reference.plants(0.0, 2.0)
    assert [b[0] - a[0] for a, b in zip(plants, plants[1:])] == pytest.approx(
        [profile.spacing] * (len(plants) - 1))
    assert all(math.remainder(th - math.pi, 2 * math.pi) == pytest.approx(0, abs=1e-9)
               for _, th in plants)


def test_constant_profile_is_the_straight_line():
    law = PhaseLock(PhaseLockConfig())
    law.row_speed(V, 0.0)
    law.feedback(0.4, 0.0, 0.0)
    law.set_design(0.2, 1, 0.0)
    assert law.speed_profile == 'constant'
    drive_to(law, 1.0)
    assert law.target_angle(1.0) == pytest.approx(0.4 + 2 * math.pi * V / 0.2)
    assert law.feed_forward(1.0) == pytest.approx(2 * math.pi * V / 0.2)


def test_a_spacing_change_is_continuous_and_at_the_next_plant(profiles):
    law = running_law(profiles[0.15])
    t_change = 0.5                             # s = 0.15 m: mid plant
    drive_to(law, t_change)
    law.set_design(0.5, 1, t_change, cam=profiles[0.5])
    assert law.design_pending and law.spacing == 0.15
    dt = 1e-4
    times = [t_change + i * dt for i in range(int(4.0 / dt))]
    thetas, rates = [], []
    for t in times:
        law.row_speed(V, t)             # the sensor's samples
        law.phase_error(t)              # what each control step asks
        thetas.append(law.target_angle(t))
        rates.append(law.feed_forward(t))
    assert law.spacing == 0.5 and not law.design_pending
    # θ continuous: no step beyond what the fastest rate gives in dt
    top = max(rates)
    assert max(b - a for a, b in zip(thetas, thetas[1:])) <= top * dt * 1.01
    assert min(b - a for a, b in zip(thetas, thetas[1:])) >= -1e-12
    # θ′ continuous: no jump beyond a smooth change in dt (θ″·v² bounded by the plan)
    jumps = max(abs(b - a) for a, b in zip(rates, rates[1:]))
    assert jumps <= 100.0 * dt
    # the plants: every 0.15 m up to the change's plant, then every 0.5 m
    track = law._track
    assert isinstance(track, CamTrack)
    plants = [s for s, _ in track.plants(0.0, V * times[-1])]
    gaps = [round(b - a, 9) for a, b in zip(plants, plants[1:])]
    assert set(gaps) == {0.15, 0.5}
    first_new = gaps.index(0.5)
    assert plants[first_new] > V * t_change     # the change waited for the next plant
    assert all(g == 0.15 for g in gaps[:first_new]) and all(g == 0.5 for g in gaps[first_new:])


# ---------------------------------------------------------------- the command path (CSP)

def cam_engine(channel, **drive):
    from planter_ros.command.engine import CommandEngine
    from planter_ros.command.settings import CommandSettings
    from planter_ros.control.loop_timing import SyncLoopConfig
    from planter_ros.control.machine_law import TurnConfig
    from planter_ros.drive.cia402 import DriveConfig
    from planter_ros.rows import Row
    from planter_ros.sensing.ground_speed_filter import GroundSpeedLimits
    from planter_ros.sensing.row_speed import YawRateLimits
    config = DriveConfig(can_interface='virtual', can_channel=channel, step_timeout=0.5,
                         **drive)
    law = (config_for_engine(), GroundSpeedLimits(), YawRateLimits(), TurnConfig())
    logs = []
    engine = CommandEngine(CommandSettings(config, SyncLoopConfig(), [Row(0, 'a', 0.0, 1)], law),
                           log=lambda level, text: logs.append((level, text)))
    return engine, logs


def config_for_engine():
    return PhaseLockConfig(speed_profile='cam', max_acceleration=100.0, max_speed=30.0)


def run_cam(engine, seconds, record=None):
    """drive_helpers.run_engine at V; `record` gets (integrated target, θ(s) at the next SYNC)
    of the row after each step."""
    from drive_helpers import run_engine
    unit = engine.units[0]

    def step(now):
        if record is not None and unit.target is not None:
            record.append((unit.target, unit.law.target_angle(now + engine.period)))
    run_engine(engine, seconds, V, after_step=step)


def send_design(engine, design):
    import time

    from planter_ros.design import from_json, to_json
    text = to_json(design)
    engine.set_design(from_json(text), text, time.monotonic())


def test_csp_targets_follow_the_cam(channel, design):
    import time

    from drive_helpers import wait_until
    from planter_ros.simdrive.bus import SimulatedBus
    from planter_ros.drive.states import CYCLIC_SYNC_POSITION, OPERATION_ENABLED, PROFILE_VELOCITY
    sims = SimulatedBus(channel, [1], supported_modes=(PROFILE_VELOCITY, CYCLIC_SYNC_POSITION))
    sims.start()
    engine, logs = cam_engine(channel)
    try:
        engine.enable()
        assert engine.csp
        send_design(engine, dataclasses.replace(design, plant_spacing=0.35))
        law = engine.units[0].law
        assert wait_until(lambda: law.speed_profile == 'cam', 5.0)
        run_cam(engine, 2.0)
        record = []
        run_cam(engine, 3.0, record)
        errors = [abs(target - theta) for target, theta in record]
        # the targets are θ(s) at the SYNC they apply at (while θ′ changes within every
        # plant); a step the host made late is made up over the next SYNCs, bounded
        on_cam = sum(e < 1e-6 for e in errors) / len(errors)
        assert on_cam > 0.9 and max(errors) < 0.1, (on_cam, max(errors))
        sim = sims.drives[0]
        assert sim.state == OPERATION_ENABLED and sim.following_error_faults == 0
        # the drive follows its targets (its own following error), one to two SYNCs behind
        # (≈ 0.01-0.02 s · 12.6 rad/s in the soil): the measured phase error
        assert abs(sim.following_error) < 0.2
        assert abs(law.phase_error(time.monotonic())) < 0.3
        row = [r for r, _ in engine.reports(time.monotonic()) if r.task == 'a']
        assert ('speed profile', 'cam') in row[0].values
        assert not [text for level, text in logs if 'falls back' in text]
    finally:
        engine.shutdown()
        sims.stop()


def test_a_drive_without_csp_falls_back_to_the_mean_speed_with_a_warning(channel, design):
    import logging
    import time

    from drive_helpers import wait_until
    from planter_ros.diagnostics import WARN
    from planter_ros.simdrive.bus import SimulatedBus
    from planter_ros.drive.states import PROFILE_VELOCITY
    sims = SimulatedBus(channel, [1], supported_modes=(PROFILE_VELOCITY,))
    sims.start()
    engine, logs = cam_engine(channel)
    try:
        engine.enable()
        assert not engine.csp
        send_design(engine, dataclasses.replace(design, plant_spacing=0.35))
        law = engine.units[0].law
        assert wait_until(lambda: law.spacing == 0.35, 5.0)
        assert law.speed_profile == 'constant'
        warnings = [text for level, text in logs if level == logging.WARNING]
        assert any('profile velocity' in text and 'mean speed' in text for text in warnings)
        run_cam(engine, 1.0)
        assert law.feed_forward(time.monotonic()) == pytest.approx(2 * math.pi * V / 0.35)
        row = [r for r, _ in engine.reports(time.monotonic()) if r.task == 'a']
        assert row[0].level == WARN and 'mean speed' in row[0].message
        assert ('speed profile', 'constant') in row[0].values
    finally:
        engine.shutdown()
        sims.stop()
