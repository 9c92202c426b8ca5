"""A row's cam across run-time spacing changes (planter_ros.cam.CamTrack): the change takes
effect at the next planting instant, the plants follow the new spacing from there, and θ, θ′
and θ″ do not jump."""
import math

from hypothesis import HealthCheck, given, settings, strategies as st
import numpy as np
import pytest

from planter_ros.cam import CamMechanism, CamTrack, plan_cam
from planter_ros.kinematics.five_bar import design_five_bar

MECH = CamMechanism.from_design(design_five_bar(0.045, 0.15, 0.05))
SPEED = 0.3
SPACINGS = (0.15, 0.25, 0.35, 0.5)
RULES = ('design_speed', 'zero_slip')


@pytest.fixture(scope='module')
def profiles():
    return {(rule, d): plan_cam(MECH, d, SPEED, rule=rule, top_speeds=False).profile
            for rule in RULES for d in SPACINGS}


def assert_no_jump(track):
    """At every join, the left segment's and the right segment's θ, θ′, θ″ agree."""
    for i, s in enumerate(track.joins):
        left = track.segment_values(i, s)
        right = track.segment_values(i + 1, s)
        assert right[0] == pytest.approx(left[0], abs=1e-9), (s, left, right)
        assert right[1] == pytest.approx(left[1], rel=1e-8, abs=1e-8), (s, left, right)
        assert right[2] == pytest.approx(left[2], rel=1e-6, abs=1e-5), (s, left, right)
        # and what the track itself gives either side of the join
        before, after = track.evaluate(s - 1e-9), track.evaluate(s + 1e-9)
        assert abs(after[0] - before[0]) <= 1e-6 and abs(after[1] - before[1]) <= 1e-4


def test_a_spacing_change_takes_effect_at_the_next_planting_instant(profiles):
    track = CamTrack(profiles[('design_speed', 0.15)])
    last_old = track.change(profiles[('design_speed', 0.5)], 0.31)
    assert last_old == pytest.approx(0.45)          # plants at 0, 0.15, 0.3, 0.45 | 0.95, ...
    plants = track.plants(0.0, 2.0)
    positions = [s for s, _ in plants]
    assert positions == pytest.approx([0.0, 0.15, 0.3, 0.45, 0.95, 1.45, 1.95])
    for k, (_, theta) in enumerate(plants):          # every plant at the bottom, θ = π + 2πk
        assert theta == pytest.approx(math.pi + 2 * math.pi * k, abs=1e-9)
    assert_no_jump(track)


def test_the_motion_a_drive_is_sent_is_the_cam_at_the_rows_speed(profiles):
    track = CamTrack(profiles[('zero_slip', 0.25)])
    theta, d1, d2 = track.evaluate(0.0123)
    assert track.motion(0.0123, 0.4) == pytest.approx((theta, 0.4 * d1, 0.16 * d2))
    # braking at 0.5 m/s²: α = v² θ″ + a θ′
    assert track.motion(0.0123, 0.4, -0.5)[2] == pytest.approx(0.16 * d2 - 0.5 * d1)


def test_the_same_rule_at_another_spacing_needs_no_planning_at_run_time(profiles):
    track = CamTrack(profiles[('zero_slip', 0.25)])
    track.change(profiles[('zero_slip', 0.5)], 0.1)
    assert len(track.joins) == 1                     # the old exit hands over directly
    assert_no_jump(track)


def test_a_change_of_rule_is_joined_by_a_planned_arc(profiles):
    track = CamTrack(profiles[('design_speed', 0.35)])
    track.change(profiles[('zero_slip', 0.15)], 0.2)
    assert len(track.joins) == 2                     # old exit → arc → new entry
    assert_no_jump(track)
    s = np.linspace(0.0, 2.0, 200_001)
    assert np.min(track.values(s, 1)) >= -1e-9       # nor does the transition turn back
    assert [p for p, _ in track.plants(0.0, 1.2)] == pytest.approx([0.0, 0.35, 0.5, 0.65, 0.8,
                                                                    0.95, 1.1])


def test_a_second_change_before_the_first_took_effect_replaces_it(profiles):
    track = CamTrack(profiles[('design_speed', 0.25)])
    assert track.change(profiles[('design_speed', 0.5)], 0.1) == pytest.approx(0.25)
    # asked again before the plant at 0.25: that plant is still the last of d = 0.25
    assert track.change(profiles[('zero_slip', 0.15)], 0.2) == pytest.approx(0.25)
    assert [p for p, _ in track.plants(0.0, 0.9)] == pytest.approx([0.0, 0.25, 0.4, 0.55, 0.7,
                                                                    0.85])
    # asked after it, before the new spacing's first plant: that one is the next
    assert track.change(profiles[('design_speed', 0.35)], 0.3) == pytest.approx(0.4)
    assert [p for p, _ in track.plants(0.0, 1.2)] == pytest.approx([0.0, 0.25, 0.4, 0.75, 1.1])
    assert_no_jump(track)


def expected_plants(changes, d0, until):
    """The planting instants a schedule of (s_now, d) changes should give, worked out without
    the cam: fixed plants, then a periodic run from an anchor."""
    fixed, anchor, spacing = [], 0.0, d0
    for s_now, d in changes:
        ahead = [p for p in fixed if p > s_now]
        if ahead:
            s_k = ahead[0]
        else:
            j = max(0, math.floor((s_now - anchor) / spacing) + 1)
            while anchor + j * spacing <= s_now:
                j += 1
            s_k = anchor + j * spacing
        run = [anchor + j * spacing for j in range(int((s_k - anchor) / spacing + 2))]
        fixed = [p for p in fixed + run if p <= s_k + 1e-12 and (p >= anchor or p in fixed)]
        anchor, spacing = s_k + d, d
    j, tail = 0, []
    while anchor + j * spacing <= until:
        tail.append(anchor + j * spacing)
        j += 1
    return sorted(set(round(p, 9) for p in fixed + tail if p <= until))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.floats(0.0, 0.6), st.sampled_from(RULES),
                          st.sampled_from(SPACINGS)), min_size=1, max_size=5),
       st.sampled_from(SPACINGS))
def test_any_sequence_of_changes_keeps_the_cam_smooth_and_the_plants_in_order(
        profiles, steps, d0):
    track = CamTrack(profiles[('design_speed', d0)])
    s_now, changes = 0.0, []
    for gap, rule, d in steps:
        s_now += gap
        track.change(profiles[(rule, d)], s_now)
        changes.append((s_now, d))
    assert_no_jump(track)
    until = s_now + 1.5
    got = [round(p, 9) for p, _ in track.plants(0.0, until)]
    assert got == pytest.approx(expected_plants(changes, d0, until), abs=1e-9)
    for k, (_, theta) in enumerate(track.plants(0.0, until)):
        assert theta == pytest.approx(math.pi + 2 * math.pi * k, abs=1e-8)
    s = np.linspace(0.0, until, 100_001)
    assert np.all(np.diff(track.values(s)) >= -1e-9)
