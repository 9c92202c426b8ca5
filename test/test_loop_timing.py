"""Control-loop period statistics (the gaps between a row's command frames) and their
diagnostics: what says whether the loop keeps the drive's RPDO deadline."""
import math

import numpy as np
import pytest

from planter_ros import diagnostics
from planter_ros.control import sync_status
from planter_ros.control.loop_timing import PeriodStats


def test_gaps_between_events_max_mean_and_tail_to_one_bin():
    stats = PeriodStats()
    rng = np.random.default_rng(1)
    gaps = rng.uniform(0.010, 0.020, 5000)
    gaps[[100, 2000, 4000]] = [0.047, 0.061, 0.188]         # three late frames
    now = 100.0
    stats.event(now)
    for gap in gaps:
        now += gap
        stats.event(now)
    assert stats.gaps == gaps.size
    assert stats.max_gap == pytest.approx(0.188)
    assert stats.mean == pytest.approx(gaps.mean())
    for q in (0.5, 0.99, 0.999):
        assert abs(stats.quantile(q) - np.quantile(gaps, q, method='inverted_cdf')) <= 1e-4
    assert stats.quantile(1.0) == pytest.approx(0.188)


def test_a_pause_on_purpose_is_no_gap_and_gaps_beyond_the_span_keep_their_max():
    stats = PeriodStats()
    stats.event(0.0)
    stats.event(0.02)
    stats.restart()                     # shut down on purpose
    stats.event(50.0)
    stats.event(52.5)                   # a real 2.5 s stall, beyond the histogram's span
    assert stats.gaps == 2 and stats.max_gap == pytest.approx(2.5)
    assert stats.quantile(0.999) == pytest.approx(2.5)
    assert math.isnan(PeriodStats().quantile(0.5)) and PeriodStats().summary()['max'] is None


def test_merged_rows_give_the_machines_figures():
    a, b = PeriodStats(), PeriodStats()
    for g in (0.01, 0.02):
        a.add(g)
    b.add(0.09)
    merged = PeriodStats().merge(a).merge(b)
    assert merged.gaps == 3 and merged.max_gap == pytest.approx(0.09)
    assert merged.summary()['mean'] == pytest.approx(0.04)


def loop_with(max_gap):
    stats = PeriodStats()
    for g in [0.015] * 2000 + [max_gap]:
        stats.add(g)
    return stats


def test_diagnostics_warn_once_half_the_deadline_is_used_and_error_once_missed():
    ok = sync_status.loop_report([('', loop_with(0.03))], 0.2)
    assert ok.level == diagnostics.OK
    values = dict(ok.values)
    assert values['command gap max'] == '30.0 ms' and values['command gap p99.9'] == '15.1 ms'
    assert values['drive command deadline'] == '200 ms'
    warn = sync_status.loop_report([('left', loop_with(0.03)), ('right', loop_with(0.12))], 0.2)
    assert warn.level == diagnostics.WARN and 'right command gap max' in dict(warn.values)
    late = sync_status.loop_report([('left', loop_with(0.25))], 0.2)
    assert late.level == diagnostics.ERROR and late.message.startswith('deadline missed')


def test_a_histogram_sent_elsewhere_gives_the_same_figures():
    stats = PeriodStats()
    for g in (0.012, 0.018, 0.02, 0.047, 1.7):
        stats.add(g)
    again = PeriodStats.from_histogram(stats.histogram())
    assert again.summary() == stats.summary()
