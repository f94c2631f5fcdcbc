"""Tests that kill surviving mutants of ``subspace/map_estimator.py`` and
``subspace/hankel_toeplitz.py`` (tests/MUTATION.md)."""

from __future__ import annotations

import numpy as np
import pytest

from stageid._errors import DataError
from stageid.subspace.map.posterior import LS_SINGULAR_PIVOT, Prior, map_prior, regressor_scales, singular_pivot
from stageid.subspace.statistics.hankel_toeplitz import WindowStatistics, window_statistics


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


def test_prior_from_a_covariance_vector_or_matrix() -> None:
    np.testing.assert_allclose(Prior.from_covariance(None, [4.0, 2.0], 0.01).precision, [0.0025, 0.005])
    cov = np.array([[4.0, 1.0], [1.0, 4.0]])
    np.testing.assert_allclose(Prior.from_covariance(None, cov, 0.01).precision, 0.01 * np.linalg.inv(cov))


def test_a_priors_mean_is_carried_into_the_fits_channel_scaling() -> None:
    # the fit divides inputs by su and outputs by sy; the prior mean theta must predict the
    # same scaled outputs from the scaled regressors: theta_s x_s = (theta x) / y_scale
    rng = np.random.default_rng(1)
    u, y = rng.standard_normal((60, 1)), rng.standard_normal((60, 2))
    stats = window_statistics(u, y, horizon=2)
    su, sy = np.array([3.0]), np.array([0.5, 20.0])
    xs, ys = regressor_scales(2, su, sy)
    theta = rng.standard_normal((ys.size, xs.size))
    prior = map_prior(stats, Prior(theta, np.ones(xs.size)), su, sy)
    x = rng.standard_normal(xs.size)
    np.testing.assert_allclose(prior.theta0 @ (x / xs), (theta @ x) / ys, rtol=1e-12)
    np.testing.assert_allclose(prior.precision, 1.0 / xs**2, rtol=1e-12)


def test_too_short_a_record_names_the_samples_it_needs() -> None:
    with pytest.raises(DataError, match="horizon 3 needs records of more than 6 samples; got 6"):
        window_statistics(np.ones((6, 1)), np.ones((6, 1)), horizon=3)
