"""Tests that kill surviving mutants of ``subspace/map_estimator.py`` and
``subspace/hankel_toeplitz.py`` (tests/MUTATION.md)."""

from __future__ import annotations

import numpy as np

from stageid.subspace.hankel_toeplitz import WindowStatistics, window_statistics
from stageid.subspace.map_estimator import LS_SINGULAR_PIVOT, singular_pivot


def test_singular_pivot_tells_a_rich_regressor_from_a_collinear_one() -> None:
    rng = np.random.default_rng(0)
    u = rng.standard_normal((400, 1))
    y = np.convolve(u[:, 0], [0.0, 0.5, 0.3])[:400, None] + 0.1 * rng.standard_normal((400, 1))
    assert singular_pivot(window_statistics(u, y, horizon=3)) is None  # white input, noisy output: well posed
    # an output that is the input delayed by one sample: past outputs repeat past inputs exactly
    y_copy = np.r_[[[0.0]], u[:-1]]
    pivot = singular_pivot(window_statistics(u, y_copy, horizon=3))
    assert pivot is not None and pivot < LS_SINGULAR_PIVOT


def test_adding_window_statistics_sums_the_input_spectra_of_equal_grids() -> None:
    def stats(power):
        return WindowStatistics(np.eye(6), 10.0, 1, 1, 1, power, np.array([0.0, 0.25]), 1)

    a, b = stats(np.array([1.0, 2.0])), stats(np.array([0.5, 4.0]))
    np.testing.assert_array_equal((a + b).input_power, [1.5, 6.0])
    assert (a + b).n_windows == 20.0 and (a + b).count == 2
    np.testing.assert_array_equal((stats(None) + b).input_power, [0.5, 4.0])
