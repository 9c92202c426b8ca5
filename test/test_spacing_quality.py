"""ISO 7256-1 / Kachman & Smith spacing-quality indices, computed by hand on crafted spacings."""
import math

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest

from planter_ros.prediction import (
    SpacingQuality, spacing_quality, spacing_quality_by_row)

D = 0.2


def cv(values):
    """Sample standard deviation over mean, by hand."""
    mean = sum(values) / len(values)
    var = sum((v - mean) ** 2 for v in values) / (len(values) - 1)
    return math.sqrt(var) / mean


def test_no_multiples_no_misses():
    x = [0.19, 0.2, 0.21, 0.2]
    q = spacing_quality(x, D)
    assert q['spacings'] == 4
    assert q['multiple_index'] == 0.0 and q['miss_index'] == 0.0
    assert q['quality_of_feed_index'] == 1.0
    assert q['precision'] == pytest.approx(cv(x), rel=1e-12)


def test_multiples_only():
    # two plants where one belongs: 0.05 and 0.1 (= 0.5 d exactly counts as a multiple)
    x = [0.2, 0.05, 0.1, 0.2, 0.22]
    q = spacing_quality(x, D)
    assert q['multiple_index'] == pytest.approx(2 / 5)
    assert q['miss_index'] == 0.0
    assert q['quality_of_feed_index'] == pytest.approx(3 / 5)
    assert q['precision'] == pytest.approx(cv([0.2, 0.2, 0.22]), rel=1e-12)


def test_misses_only():
    # a missing plant: 0.4; 0.3 (= 1.5 d exactly) is still a single
    x = [0.2, 0.4, 0.3, 0.18]
    q = spacing_quality(x, D)
    assert q['multiple_index'] == 0.0
    assert q['miss_index'] == pytest.approx(1 / 4)
    assert q['quality_of_feed_index'] == pytest.approx(3 / 4)
    assert q['precision'] == pytest.approx(cv([0.2, 0.3, 0.18]), rel=1e-12)


# Exact boundaries (ISO 7256-1; Kachman and Smith 1995): a multiple is x <= 0.5 d, a miss
# x > 1.5 d. With d = 0.25 m and spacings that are binary fractions every x/d is exact, so the
# comparison meets 0.5 and 1.5 exactly (0.1 / 0.2 is not 0.5 in floating point, 0.3 / 0.2 is
# 1.4999...: such a test cannot tell <= from <).
Q = 0.25


@pytest.mark.parametrize('batch', [1, 3])
def test_exactly_half_the_design_spacing_is_a_multiple_and_the_next_float_a_single(batch):
    half = 0.125
    assert half / Q == 0.5
    x = [half, np.nextafter(half, 1.0), 0.25]
    running = SpacingQuality()
    for i in range(0, len(x), batch):
        running.add(x[i:i + batch], Q)
    q = running.result()
    assert (q['multiple_index'], q['miss_index'], q['spacings']) == (1 / 3, 0.0, 3)
    assert q['quality_of_feed_index'] == 2 / 3


@pytest.mark.parametrize('batch', [1, 3])
def test_exactly_one_and_a_half_design_spacings_is_a_single_and_the_next_float_a_miss(batch):
    one_and_a_half = 0.375
    assert one_and_a_half / Q == 1.5
    x = [one_and_a_half, np.nextafter(one_and_a_half, 1.0), 0.125 + 0.0625]
    running = SpacingQuality()
    for i in range(0, len(x), batch):
        running.add(x[i:i + batch], Q)
    q = running.result()
    assert (q['multiple_index'], q['miss_index'], q['spacings']) == (0.0, 1 / 3, 3)
    # the singles are 1.5 d and 0.75 d: mean 1.125 d, sample deviation 0.75 / sqrt(2) d
    assert q['precision'] == pytest.approx(cv([1.5, 0.75]), rel=1e-15)


def test_two_singles_are_enough_for_a_precision_and_one_is_not():
    assert spacing_quality([0.1875, 0.3125], Q)['precision'] == pytest.approx(
        cv([0.75, 1.25]), rel=1e-15)
    assert spacing_quality([0.1875, 0.5], Q)['precision'] is None


def test_multiples_and_misses_and_nan_spacings_left_out():
    x = [math.nan, 0.2, 0.05, 0.61, 0.2, math.nan, 0.21, 0.09, 0.19, 0.45]
    q = spacing_quality(x, D)
    assert q['spacings'] == 8
    assert q['multiple_index'] == pytest.approx(2 / 8)
    assert q['miss_index'] == pytest.approx(2 / 8)
    assert q['quality_of_feed_index'] == pytest.approx(4 / 8)
    assert q['precision'] == pytest.approx(cv([0.2, 0.2, 0.21, 0.19]), rel=1e-12)


def test_undefined_values_are_none():
    assert spacing_quality([], D) == {'multiple_index': None, 'miss_index': None,
                                      'quality_of_feed_index': None, 'precision': None,
                                      'spacings': 0}
    assert spacing_quality([math.nan, math.nan], D)['spacings'] == 0
    one = spacing_quality([0.2, 0.05, 0.9], D)          # a single single: no precision
    assert one['quality_of_feed_index'] == pytest.approx(1 / 3) and one['precision'] is None


def test_each_spacing_is_judged_against_its_own_design_spacing():
    # a design change from d = 0.2 to 0.3: 0.3 is a single there, 0.12 a multiple
    q = spacing_quality([0.2, 0.21, 0.3, 0.12], [0.2, 0.2, 0.3, 0.3])
    assert q['multiple_index'] == pytest.approx(1 / 4) and q['miss_index'] == 0.0
    assert q['precision'] == pytest.approx(cv([1.0, 1.05, 1.0]), rel=1e-12)


def test_per_row_and_the_machine():
    spacing = [0.2, 0.05, 0.2, 0.45, 0.2, 0.21]
    row = [0, 0, 1, 1, 1, 2]
    rows, machine = spacing_quality_by_row(spacing, D, row, rows=[0, 1, 2, 3])
    assert rows[0]['multiple_index'] == 0.5 and rows[1]['miss_index'] == pytest.approx(1 / 3)
    assert rows[2]['quality_of_feed_index'] == 1.0 and rows[2]['precision'] is None
    assert rows[3]['spacings'] == 0 and rows[3]['quality_of_feed_index'] is None
    assert machine == spacing_quality(spacing, D)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(st.floats(0.0, 1.0), st.just(math.nan)), max_size=60),
       st.integers(1, 7))
def test_running_counts_equal_the_whole_run(spacing, batch):
    """The live monitor adds plants a few at a time; replay judges the whole run at once."""
    running = SpacingQuality()
    for i in range(0, len(spacing), batch):
        running.add(spacing[i:i + batch], D)
    live, whole = running.result(), spacing_quality(spacing, D)
    assert live['spacings'] == whole['spacings']
    for key in ('multiple_index', 'miss_index', 'quality_of_feed_index', 'precision'):
        if whole[key] is None:
            assert live[key] is None
        else:
            assert live[key] == pytest.approx(whole[key], rel=1e-9, abs=1e-12)
    finite = np.asarray(spacing)[np.isfinite(spacing)]
    if finite.size:
        assert whole['multiple_index'] + whole['miss_index'] + \
            whole['quality_of_feed_index'] == pytest.approx(1.0)
