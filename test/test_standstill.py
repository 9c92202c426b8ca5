"""Standstill is standstill (issue 32, item 4): a ground-speed sensor's noise at rest does not
turn the planting mechanism. The GNSS velocity (a magnitude, noisy at rest) goes through the
ground-speed node's adapters as the node applies them (sensing.ground_speed_sources), then
the phase-locked sync law drives a simulated drive (sim.closed_loop.simulate)."""
import math

import numpy as np
import pytest

from planter_ros.control.phase_lock import PhaseLock, PhaseLockConfig
from planter_ros.sensing.ground_speed_sources import (GroundSpeedSourceConfig, PulseSpeed,
                                                      SpeedSample, Standstill, gnss_speed)
from planter_ros.sim.closed_loop import LoopTiming, SpeedSensor, simulate

D = 0.15                     # the tomato cam scene's spacing: the most turns per metre
NOISE = 0.02                 # m/s per axis: a GNSS receiver's velocity at rest


def turned_at_rest(seed, threshold, seconds=60.0, rate=10.0):
    """Mechanism angle (rad) turned in `seconds` at rest, the GNSS velocity `NOISE` per axis
    at `rate` Hz, through Standstill(threshold) (0: none) as the ground-speed node applies it,
    into the phase-locked sync law."""
    rng = np.random.default_rng(seed)
    rule = Standstill(threshold)

    def sensor(t, v):
        east, north = v + rng.normal(0.0, NOISE), rng.normal(0.0, NOISE)
        return rule.apply(gnss_speed(t, east, north)).speed

    law = PhaseLock(PhaseLockConfig())
    law.set_design(D, 1, 0.0)
    sim = simulate(law, lambda t: 0.0, seconds, sensor=SpeedSensor(read=sensor),
                   timing=LoopTiming(dt=0.002, sample_period=1.0 / rate))
    return float(sim.angle[-1] - sim.angle[0])


@pytest.mark.parametrize('seed', [1, 2, 3])
def test_sixty_seconds_at_rest_with_gnss_noise_turn_the_mechanism_less_than_a_degree(seed):
    default = GroundSpeedSourceConfig().standstill_speed
    assert abs(turned_at_rest(seed, default)) < math.radians(1.0)


def test_without_the_standstill_rule_the_noise_plants_into_one_spot():
    # the issue measured 46 rad in 60 s (7.4 planting cycles into one spot); here about 63
    assert turned_at_rest(1, 0.0) > 5 * 2 * math.pi


def test_standstill_holds_each_source_until_twice_the_threshold_and_keeps_the_direction():
    rule = Standstill(0.05)
    readings = [('gnss', 0.04), ('gnss', 0.07), ('gnss', 0.099), ('gnss', 0.1), ('gnss', 0.06),
                ('gnss', 0.049), ('gnss', 0.08), ('isobus_ground', -0.12),
                ('isobus_ground', -0.07), ('isobus_ground', -0.03), ('isobus_ground', -0.07)]
    got = [rule.apply(SpeedSample(i * 0.1, v, source)).speed
           for i, (source, v) in enumerate(readings)]
    #          rest  band  band  moves  on    rest  band  reverse  on     rest  band
    assert got == [0.0, 0.0, 0.0, 0.1, 0.06, 0.0, 0.0, -0.12, -0.07, 0.0, 0.0]
    assert rule.standing == ['gnss', 'isobus_ground']
    # off: every reading as it is
    assert Standstill(0.0).apply(SpeedSample(0.0, 0.01, 'gnss')).speed == 0.01


def test_a_start_from_rest_loses_only_the_distance_up_to_twice_the_threshold():
    rule = Standstill(0.05)
    t = np.arange(0.0, 3.0, 0.01)
    v = 0.5 * t                              # a tractor starting at 0.5 m/s²
    used = np.array([rule.apply(SpeedSample(a, b, 'gnss')).speed for a, b in zip(t, v)])
    lost = np.trapezoid(v - used, t)
    assert lost == pytest.approx(0.1 ** 2 / (2 * 0.5), abs=1e-3)     # v²/2a = 1 cm


def test_no_infinite_speed_sample_from_huge_readings():
    assert gnss_speed(0.0, 1.7e308, 1.7e308) is None
    assert gnss_speed(0.0, 3.0, 4.0).speed == 5.0
    with pytest.raises(ValueError):
        PulseSpeed(1e-300)
    fast = PulseSpeed(0.01)
    fast.update(0.0, 0)
    assert fast.update(5e-324, 2 ** 31) is None          # an infinite speed: no sample


def test_a_pulse_scale_no_sensor_has_is_refused_in_one_line():
    from planter_ros.config import ConfigError
    with pytest.raises(ConfigError) as caught:
        GroundSpeedSourceConfig(sources=['pulses'], pulses_per_metre=1e-300)
    assert 'pulses_per_metre = 1e-300 is out of range' in str(caught.value)
    assert '\n' not in str(caught.value)
