"""The cam within the drive, always (issue 32, item 1): every plan and every run-time change of
spacing or rule on the tomato cam scene's schedule, planned at 0.3, 0.6 and 0.9 m/s, is within
the drive's speed, acceleration, jerk and torque limits where it reaches the drive, and what is
refused names the figure and the limit. The loads are checked here by dense sampling of the
track (scipy's PPoly of the same coefficients, the torque from the drive model), not by the
planner's own figures."""
import dataclasses
import math
import re

import numpy as np
import pytest

from planter_ros.cam import (CamLimitError, CamMechanism, CamSpec, CamTrack, DriveLimits,
                             build_profile, constant_law, plan_cam)
from planter_ros.cam.track import plan_transition
from planter_ros.control.cam_law import plan_for_design, plan_row_cam
from planter_ros.kinematics.five_bar import design_five_bar
from planter_ros.scene import open_scene
from planter_ros.scene.schedule import spacing_schedule

SCENE = 'config/tomato_cam.yaml'
SPEEDS = (0.3, 0.6, 0.9)
OTHER = {'design_speed': 'zero_slip', 'zero_slip': 'design_speed'}
LIMIT_WORDS = ('sun-bar speed', 'sun-bar acceleration', 'sun-bar jerk', 'peak motor torque',
               'RMS motor torque')


@pytest.fixture(scope='module')
def scene():
    opened = open_scene(SCENE)
    params = opened.parameters('design_node')
    spacings = [opened.design().plant_spacing]
    for _, d in spacing_schedule(params, opened.path):
        if d != spacings[-1]:
            spacings.append(d)
    return opened.design(), spacings, opened.parameters('sync_node')['cam_rule']


def steps(spacings, rule):
    """The scene's schedule under `rule`, with a change of rule and back at every spacing."""
    out = []
    for d in spacings:
        out += [(rule, d), (OTHER[rule], d), (rule, d)]
    return out


def dense_peaks(track, drive, mech, v, s0, s1, samples=400_001):
    """Peak |ω|, |α|, |jerk| and |motor torque| of the track over [s0, s1] at steady v, from
    dense samples (independent of the planner's figures)."""
    s = np.linspace(s0, s1, samples)
    theta, d1, d2, d3 = (track.values(s, k) for k in range(4))
    k_alpha, k_omega, gravity = drive.torque_terms(mech, theta)
    torque = v * v * (k_alpha * d2 + k_omega * d1 ** 2) + gravity
    return {'speed': v * np.max(np.abs(d1)), 'acceleration': v * v * np.max(np.abs(d2)),
            'jerk': v ** 3 * np.max(np.abs(d3)), 'torque': np.max(np.abs(torque))}


def assert_within(peaks, drive, mech, what):
    lim = drive.effective(mech)
    tol = 1 + 1e-9
    assert peaks['speed'] <= lim.speed * tol, (what, peaks['speed'], lim.speed)
    if lim.acceleration:
        assert peaks['acceleration'] <= lim.acceleration * tol, what
    assert peaks['jerk'] <= lim.jerk * tol, (what, peaks['jerk'], lim.jerk)
    assert peaks['torque'] <= lim.torque * tol, (what, peaks['torque'], lim.torque)


def assert_names_a_limit(text):
    assert '\n' not in text and any(word in text for word in LIMIT_WORDS), text
    assert re.search(r'over its limit [\d.e+]+ \S+ \([\d.]+ %\)', text), text


@pytest.mark.parametrize('speed', SPEEDS)
def test_every_plan_and_change_of_the_schedule_is_within_the_drive_or_refused(scene, speed):
    design, spacings, _ = scene
    drive = DriveLimits()
    mech = CamMechanism(design.l1, design.l2, design.planting_depth)
    for rule in OTHER:
        refused = run_schedule(design, spacings, rule, speed, drive, mech)
        # what is refused at which speed: 0.15 m at 0.9 m/s needs the sun bar at
        # 2π·0.9/0.15 = 37.7 rad/s even at constant speed (its limit: 6000 min⁻¹ over 20:1
        # = 31.4 rad/s)
        if speed < 0.9:
            assert refused == [], rule
        else:
            assert {d for _, d in refused} == {0.15}, rule


def run_schedule(design, spacings, rule, speed, drive, mech):
    """Plan the schedule's every step as the sync node's shell does, run the accepted ones
    on a row's track and check it densely; the refused steps."""
    track, s_now, previous, refused = None, 0.0, None, []
    for step_rule, d in steps(spacings, rule):
        asked = dataclasses.replace(design, plant_spacing=d, top_ground_speed=speed)
        try:
            profile, why = plan_for_design(asked, step_rule, previous)
        except CamLimitError as exc:
            assert_names_a_limit(str(exc))
            refused.append((step_rule, d))
            continue                          # refused: the rows keep what they run
        assert profile is not None and not why
        # the plan itself, over a few of its plants
        assert_within(dense_peaks(CamTrack(profile), drive, mech, speed, 0.0,
                                  2 * profile.spacing, 100_001), drive, mech, (step_rule, d))
        assert profile.figures(speed).rms_torque <= drive.motor_rated_torque * (1 + 1e-9)
        if track is None:
            track = CamTrack(profile)
        else:
            s_k = track.change(profile, s_now)
            transition = plan_transition(previous, profile)
            end = s_k + sum(transition.gaps) + profile.spacing
            assert_within(dense_peaks(track, drive, mech, speed, s_k - previous.spacing, end,
                                      200_001),
                          drive, mech, (previous.rule, previous.spacing, '->', step_rule, d))
            if transition.figures is not None:
                assert transition.figures.feasible
            s_now = end
        previous = profile
    return refused


def test_a_plan_over_the_drive_even_at_constant_speed_is_refused_naming_the_limit(scene):
    design = dataclasses.replace(scene[0], plant_spacing=0.15, top_ground_speed=0.9)
    with pytest.raises(CamLimitError) as caught:
        plan_row_cam(design, 'design_speed')
    text = str(caught.value)
    assert_names_a_limit(text)
    assert 'sun-bar speed 37.7 rad/s over its limit 31.42 rad/s (120.0 %)' in text
    assert 'plant_spacing = 0.15 m' in text and 'top_ground_speed = 0.9 m/s' in text


def test_the_cam_is_planned_for_the_scenes_top_ground_speed(scene):
    design = scene[0]
    # the tomato cam scene cruises at 0.3 m/s and its field run speeds up to 0.45 m/s
    assert design.nominal_ground_speed == pytest.approx(0.3)
    assert design.top_ground_speed == pytest.approx(0.45)
    assert plan_row_cam(design, 'design_speed').speed == pytest.approx(0.45)


MECH = CamMechanism.from_design(design_five_bar(0.045, 0.15, 0.05))


def test_a_change_one_arc_cannot_make_is_spread_over_more_plants():
    # from constant speed at 0.8 m (a long soil arc) to the design-speed cam at 0.15 m at
    # 0.3 m/s: one out-of-soil arc would need the sun bar at 40 rad/s (limit 31.4)
    drive = DriveLimits()
    old = build_profile(CamSpec(MECH, 0.8, 0.3, drive, 'constant'), constant_law(0.8), 0.0)
    new = plan_cam(MECH, 0.15, 0.3, drive, 'design_speed', top_speeds=False).profile
    transition = plan_transition(old, new)
    assert transition.plants >= 2
    # the plants of the change step from the old spacing towards the new one
    gaps = transition.gaps
    assert gaps[-1] == pytest.approx(0.15)
    assert all(a > b for a, b in zip(gaps, gaps[1:])) and gaps[0] < 0.8
    track = CamTrack(old)
    s_k = track.change(new, 0.1)
    assert s_k == pytest.approx(0.8)
    expected = np.cumsum((s_k,) + gaps)
    got = [s for s, _ in track.plants(0.0, expected[-1] + 0.3)]
    assert got[1:len(expected) + 1] == pytest.approx(list(expected), abs=1e-12)
    for k, (_, theta) in enumerate(track.plants(0.0, expected[-1] + 0.3)):
        assert theta == pytest.approx(math.pi + 2 * math.pi * k, abs=1e-8)
    assert_within(dense_peaks(track, drive, MECH, 0.3, 0.0, expected[-1] + 0.3), drive, MECH,
                  'spread')
    # θ never turns back through the change either
    assert np.min(track.values(np.linspace(0.0, expected[-1], 200_001), 1)) >= -1e-9


def test_a_change_nothing_brings_within_the_drive_is_refused_and_the_track_kept():
    drive = DriveLimits(gear_ratio=30.0)
    old = build_profile(CamSpec(MECH, 1.2, 0.4, drive, 'constant'), constant_law(1.2), 0.0)
    new = plan_cam(MECH, 0.15, 0.4, drive, 'design_speed', top_speeds=False).profile
    track = CamTrack(old)
    before = track.values(np.linspace(0.0, 5.0, 1001))
    with pytest.raises(CamLimitError) as caught:
        track.change(new, 0.1)
    assert_names_a_limit(str(caught.value))
    assert 'spread over 6 plants' in str(caught.value)
    assert np.array_equal(track.values(np.linspace(0.0, 5.0, 1001)), before)
    assert track.joins == []


def test_the_peak_loads_are_the_continuous_maxima_of_the_pieces():
    drive = DriveLimits()
    for rule, d, v in (('design_speed', 0.35, 0.45), ('zero_slip', 0.25, 0.6)):
        profile = plan_cam(MECH, d, v, drive, rule, top_speeds=False).profile
        figures = profile.figures(v)
        brute = dense_peaks(CamTrack(profile), drive, MECH, v, 0.0, d, 2_000_001)
        for name, got in (('speed', figures.peak_speed), ('jerk', figures.peak_jerk),
                          ('acceleration', figures.peak_acceleration),
                          ('torque', figures.peak_torque)):
            # never below what dense sampling finds, and within its resolution above it (a
            # step of 1.25e-7 m where θ‴ reaches 1e5 rad/m³: 1e-5 of the peak)
            assert got >= brute[name] * (1 - 1e-12), (rule, name, got, brute[name])
            assert got <= brute[name] * (1 + 1e-4), (rule, name, got, brute[name])


def cam_scene(tmp_path, **values):
    """The tomato cam scene with some design values replaced (a file in tmp_path)."""
    import yaml
    data = yaml.safe_load(open(SCENE).read())
    data['/**']['ros__parameters'].update(values)
    path = tmp_path / 'scene.yaml'
    path.write_text(yaml.safe_dump(data))
    return path


def test_a_cam_scene_whose_design_spacing_leaves_no_cam_is_refused_naming_it(tmp_path):
    from planter_ros.scene import SceneError
    # built for 2 m, the design-speed rule's soil arc (0.18 m) is longer than 0.15 m
    with pytest.raises(SceneError) as caught:
        open_scene(cam_scene(tmp_path, design_spacing=2.0))
    text = str(caught.value)
    assert 'speed_profile = cam cannot run' in text and 'design_spacing' in text
    assert 'plant_spacing = 0.15' in text and '\n' not in text


def test_a_cam_scene_over_the_drive_is_refused_before_it_runs(tmp_path):
    from planter_ros.scene import SceneError
    # its schedule's first spacing, 0.15 m, at 0.9 m/s: 120 % of the sun bar's speed limit
    with pytest.raises(SceneError) as caught:
        open_scene(cam_scene(tmp_path, top_ground_speed=0.9))
    assert_names_a_limit(str(caught.value))
    assert 'top_ground_speed = 0.9 m/s' in str(caught.value)


def test_simulated_runs_keep_below_the_scenes_top_ground_speed():
    from planter_ros.analysis.simulate import scene_machine
    from planter_ros.sim.season import SPEED_CHANGE_MAX
    machine = scene_machine(SCENE)
    assert machine.cruise[1] * SPEED_CHANGE_MAX <= machine.design.top_ground_speed + 1e-12
    assert machine.cruise[0] < machine.cruise[1]
