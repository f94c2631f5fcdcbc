"""The stage dynamics' column filter (``kernels/filters.py``) against ``scipy.signal.lfilter``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from stageid.hysteresis.stage.dynamics import unit_gain_filter

CASES = [
    ([1.0], [1.0]),
    ([0.7], [1.0]),
    ([0.2, 0.3], [1.0, -0.5]),
    ([0.0, 0.1, 0.05], [1.0, -0.9, 0.05]),
    ([0.5], [1.0, -0.5]),  # numerator shorter: lfilter pads it
    ([0.1, 0.2, 0.3, 0.1], [1.0, -0.3]),  # denominator shorter
    ([2.0, 0.4], [2.0, -1.0]),  # a[0] != 1: normalised
    ([0.3, -0.2, 0.4, 0.1, 0.05], [1.0, -1.2, 0.6, -0.1, 0.02]),
]


@pytest.mark.parametrize("b, a", CASES)
@pytest.mark.parametrize("shape", [(1, 3), (2, 1), (997, 7)])
def test_filter_equals_lfilter_to_the_bit(b, a, shape):
    # same operations in the same order as lfilter's transposed direct form II: equal bits,
    # so the stage fits and simulations are unchanged by the compiled filter
    rng = np.random.default_rng(sum(shape) + len(b))
    c = rng.standard_normal(shape).cumsum(axis=0) + 3.0
    before = c.copy()
    expected = c[:1] + lfilter(b, a, c - c[:1], axis=0)
    got = unit_gain_filter(np.array(b), np.array(a), c)
    assert np.array_equal(got, expected)
    assert np.array_equal(c, before)  # caller data untouched


def test_filter_takes_any_memory_layout_and_empty_records():
    rng = np.random.default_rng(5)
    c = np.asfortranarray(rng.standard_normal((500, 6)).cumsum(axis=0))
    b, a = np.array([0.0, 0.4, 0.1]), np.array([1.0, -0.6, 0.1])
    assert np.array_equal(unit_gain_filter(b, a, c), c[:1] + lfilter(b, a, c - c[:1], axis=0))
    assert np.array_equal(unit_gain_filter(b, a, c[::3]), c[:1] + lfilter(b, a, c[::3] - c[:1], axis=0))
    assert unit_gain_filter(b, a, np.zeros((0, 4))).shape == (0, 4)
