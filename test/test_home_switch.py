"""The simulated drive's bottom switch (simdrive.switch): ideal by default (exactly the comparator
the drive always had), else with a hysteresis (edges at different angles crossed forwards and
backwards), a delay and a seeded jitter between the switch and the drive's input. Pure: no bus,
no thread; the commissioning run against it is in test_commission."""
import math

import pytest

from planter_ros.simdrive.mechanism import Mechanism, wrap_angle
from planter_ros.simdrive.spec import SimSpec
from planter_ros.simdrive.switch import HomeSwitch

W, H = 0.25, 0.0625             # rad, binary fractions: the edges below are exact


def sweep(switch, start, stop, step, t0=0.0, dt=0.001):
    """Move from `start` to `stop` rad in `step`s of `dt` s; [(t, input)] at each step."""
    seen = []
    n = round((stop - start) / step)
    for k in range(n + 1):
        t = t0 + k * dt
        switch.sense(start + k * step, t)
        seen.append((t, switch.read(t)))
    return seen


def test_the_default_switch_is_the_ideal_comparator_the_drive_always_had():
    spec = SimSpec(mechanical_offset=0.3, gear_ratio=3.0)
    mechanism = Mechanism(spec)
    assert mechanism.switch.ideal
    per_turn = spec.counts_per_motor_rev * spec.gear_ratio
    for counts in range(-int(per_turn), int(per_turn), 7):
        old = abs(wrap_angle(mechanism.angle(counts))) <= 0.5 * spec.home_switch_width
        assert mechanism.switch_active(counts) == old
    # its edges: active at exactly half the width, not just beyond (2^-51 rad: the wrap to
    # [-pi, pi) rounds at pi + 0.125, where one ulp is 2^-51)
    switch = HomeSwitch(W)
    assert switch.ideal_active(0.125) and switch.ideal_active(-0.125)
    assert not switch.ideal_active(0.125 + 2.0 ** -51)
    assert not switch.ideal_active(-0.125 - 2.0 ** -51)


def test_hysteresis_puts_each_edge_at_two_angles_symmetric_about_the_nominal_edge():
    step = 2.0 ** -12
    forward = HomeSwitch(W, hysteresis=H)
    sweep(forward, -0.5, 0.5, step)
    backward = HomeSwitch(W, hysteresis=H)
    sweep(backward, 0.5, -0.5, -step)
    (_, on_fwd, s1), (_, off_fwd, s2) = forward.edges
    (_, on_back, s3), (_, off_back, s4) = backward.edges
    assert (s1, s2, s3, s4) == (True, False, True, False)
    tol = step
    assert on_fwd == pytest.approx(-W / 2 + H / 2, abs=tol)       # inside the lower edge
    assert off_fwd == pytest.approx(W / 2 + H / 2, abs=tol)       # outside the upper edge
    assert on_back == pytest.approx(W / 2 - H / 2, abs=tol)
    assert off_back == pytest.approx(-W / 2 - H / 2, abs=tol)
    # each nominal edge is the middle of its two crossings; the four edges' middle the bottom
    assert 0.5 * (on_fwd + off_back) == pytest.approx(-W / 2, abs=tol)
    assert 0.5 * (off_fwd + on_back) == pytest.approx(W / 2, abs=tol)
    assert (on_fwd + off_back + off_fwd + on_back) / 4 == pytest.approx(0.0, abs=tol)
    # a single direction misses the bottom by half the hysteresis
    assert 0.5 * (on_fwd + off_fwd) == pytest.approx(H / 2, abs=tol)


def test_the_input_shows_a_change_after_the_delay_plus_a_seeded_jitter():
    delay, jitter = 0.125, 0.03125
    runs = []
    for seed in (3, 3, 4):
        switch = HomeSwitch(W, delay=delay, jitter=jitter, seed=seed)
        seen = sweep(switch, -0.5, 0.5, 2.0 ** -10, t0=100.0)
        changes = [t for (t, now), (_, before) in zip(seen[1:], seen) if now != before]
        assert len(changes) == 2 == len(switch.edges)
        lags = [shown - edge[0] for shown, edge in zip(changes, switch.edges)]
        # shown on the first 1 ms step at or after edge + delay + [0, jitter)
        assert all(delay <= lag < delay + jitter + 0.001 for lag in lags), lags
        runs.append(lags)
    assert runs[0] == runs[1] and runs[0] != runs[2]        # seeded: the same seed, the same


@pytest.mark.parametrize('options, message', [
    ({'home_switch_hysteresis': W}, 'home_switch_hysteresis = 0.25 is out of range: allowed '
                                    '0 <= hysteresis < home_switch_width (0.25 rad)'),
    ({'home_switch_hysteresis': -2.0 ** -20}, 'home_switch_hysteresis'),
    ({'home_switch_delay': -0.001}, 'home_switch_delay = -0.001 is out of range'),
    ({'home_switch_jitter': math.inf}, 'home_switch_jitter = inf is out of range'),
    ({'home_switch_width': 0.0}, 'home_switch_width = 0.0 is out of range'),
])
def test_a_switch_the_model_cannot_be_is_refused_in_one_line(options, message):
    options.setdefault('home_switch_width', W)
    with pytest.raises(ValueError) as refused:
        SimSpec(**options)
    assert message in str(refused.value) and '\n' not in str(refused.value)


def test_hysteresis_just_below_the_width_is_a_switch():
    """The limit: a hysteresis of the whole width leaves no angle where the switch turns on."""
    spec = SimSpec(home_switch_width=W, home_switch_hysteresis=math.nextafter(W, 0.0))
    switch = Mechanism(spec).switch
    sweep(switch, -0.5, 0.5, 2.0 ** -20 * 1024)
    assert [state for _, _, state in switch.edges] == [True, False]
