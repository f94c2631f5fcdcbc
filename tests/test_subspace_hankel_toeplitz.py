"""Hankel-Toeplitz regression (eq. 9): normal equations from lag correlations, model response."""

import numpy as np
import pytest

from _subspace_systems import random_stage, record
from stageid._errors import DataError
from stageid.subspace.map.posterior import batch_posterior
from stageid.subspace.statistics.correlations import lag_correlations
from stageid.subspace.statistics.hankel_toeplitz import (
    dense_regression,
    record_statistics,
    regressor_indices,
    window_statistics,
)
from stageid.subspace.statistics.theta_response import response_systems, theta_frequency_response


@pytest.mark.parametrize(
    "n, r, max_lag, block",
    [
        (1000, 3, 7, None),
        (777, 2, 40, 64),
        (300, 5, 130, None),
        (50, 1, 0, None),
        # several FFT batches (64 blocks each), the last one partial
        (20000, 8, 10, None),
    ],
)
def test_lag_correlations_match_direct_sums(n, r, max_lag, block):
    z = np.random.default_rng(n).standard_normal((n, r))
    R = lag_correlations(z, max_lag, block)
    direct = np.array([z[: n - c].T @ z[c:] for c in range(max_lag + 1)])
    # FFT rounding: relative 1e-12 of the largest correlation is far below any data precision
    np.testing.assert_allclose(R, direct, rtol=0, atol=1e-12 * np.abs(direct).max())


@pytest.mark.parametrize("horizon", [1, 2, 6])
@pytest.mark.parametrize("forgetting", [1.0, 0.97])
def test_window_statistics_equal_the_explicit_regression(horizon, forgetting):
    rng = np.random.default_rng(horizon)
    u = rng.standard_normal((400, 2))
    y = rng.standard_normal((400, 3)) + 5.0  # an offset must not matter
    s = window_statistics(u, y, horizon, forgetting=forgetting)
    X, Y = dense_regression(u, y, horizon)
    w = forgetting ** np.arange(X.shape[0])[::-1]
    XX, YX, YY = s.blocks()
    scale = np.abs((X * w[:, None]).T @ X).max()
    np.testing.assert_allclose(XX, (X * w[:, None]).T @ X, atol=1e-12 * scale)
    np.testing.assert_allclose(YX, (Y * w[:, None]).T @ X, atol=1e-12 * scale)
    np.testing.assert_allclose(YY, (Y * w[:, None]).T @ Y, atol=1e-12 * scale)
    assert s.count == X.shape[0]
    assert s.n_windows == pytest.approx(w.sum())


def test_regressor_layout_is_eq_9():
    # X = [u_p(k-p); y_p(k-p); u_p(k)], time ascending, channels fastest (eq. 3)
    u = np.arange(20.0)[:, None] * np.array([[1.0, 100.0]])
    y = np.arange(20.0)[:, None] * np.array([[1000.0]]) + 0.5
    X, Y = dense_regression(u, y, 2)
    k = 2  # first regression sample
    assert X[0].tolist() == [
        u[k - 2, 0],
        u[k - 2, 1],
        u[k - 1, 0],
        u[k - 1, 1],
        y[k - 2, 0],
        y[k - 1, 0],
        u[k, 0],
        u[k, 1],
        u[k + 1, 0],
        u[k + 1, 1],
    ]
    assert Y[0].tolist() == [y[k, 0], y[k + 1, 0]]
    xi, yi = regressor_indices(2, 2, 1)
    assert xi.size == 10 and yi.size == 2


def test_record_statistics_share_one_pass_and_skip_too_long_horizons():
    rng = np.random.default_rng(0)
    u, y = rng.standard_normal((60, 1)), rng.standard_normal((60, 1))
    stats = record_statistics(u, y, [3, 10, 40])
    assert sorted(stats) == [3, 10]
    np.testing.assert_allclose(stats[10].W, window_statistics(u, y, 10).W, atol=1e-10)
    with pytest.raises(DataError, match="needs records of more than"):
        window_statistics(u, y, 40)


def test_model_response_equals_truth_on_exact_data():
    # noise-free white inputs: the regression is exact, so is the response of eq. 9
    g = random_stage(3, m=2, q=2, modes=2)
    u = np.random.default_rng(1).standard_normal((3000, 2))
    exp = record(g, u, 0.0, 0)
    p = 12
    post = batch_posterior(window_statistics(exp.u, exp.y, p), None)
    f = np.linspace(0.5, 240, 60)
    G = theta_frequency_response(post.theta, p, 2, 2, f, g.dt)
    Gt = g.frequency_response(f)
    # lightly damped poles (|z| ~ 0.997): A^p is not small, yet the model is exact up to rounding
    np.testing.assert_allclose(G, Gt, atol=1e-6 * np.abs(Gt).max())


@pytest.mark.parametrize("p, m, q", [(1, 1, 1), (2, 1, 3), (5, 2, 1), (7, 3, 2), (50, 3, 3)])
def test_model_response_equals_the_least_squares_solution_of_the_block_rows(p, m, q):
    # reference: the normal equations of the (n_freqs, p q, q) block-row systems formed directly;
    # the response is evaluated from their Laurent coefficients (other summation order: rounding)
    rng = np.random.default_rng(p + 10 * m + 100 * q)
    theta = 0.3 * rng.standard_normal((p * q, 2 * p * m + p * q)) / p
    f = np.concatenate([[0.0, 250.0], rng.uniform(0, 250, 40)])
    lhs, rhs, _, _ = response_systems(theta, p, m, q, f, 0.002)
    lh = np.conj(lhs).transpose(0, 2, 1)
    expected = np.linalg.solve(lh @ lhs, lh @ rhs)
    G = theta_frequency_response(theta, p, m, q, f, 0.002)
    assert G.shape == (f.size, q, m)
    np.testing.assert_allclose(G, expected, rtol=0, atol=1e-13 * np.abs(expected).max())
    assert theta_frequency_response(theta, p, m, q, f[:0], 0.002).shape == (0, q, m)


def test_window_gram_from_lags_equals_reference():
    from stageid.subspace.statistics.correlations import window_gram, window_gram_python

    z = np.random.default_rng(2).standard_normal((90, 3))
    R = lag_correlations(z, 9)
    np.testing.assert_allclose(window_gram(z, R, 5), window_gram_python(z, R, 5), atol=1e-11)


# the last two form M = H^T H in two bands of block rows (36 + 14 and 51 + 29)
@pytest.mark.parametrize(
    ("horizon", "r", "n_segments"), [(1, 1, 1), (2, 3, 4), (7, 2, 3), (12, 5, 6), (25, 6, 3), (40, 4, 2)]
)
def test_gram_from_lags_equals_the_explicit_window_sum_over_segments(horizon, r, n_segments):
    # the diagonal-view recursion against sum_k w(k) w(k)^T formed window by window, both
    # triangles; segments from one window (L samples) upwards
    from stageid.subspace.statistics.correlations import gram_from_lags

    rng = np.random.default_rng([horizon, r, n_segments])
    L = 2 * horizon
    segments = [rng.standard_normal((L + int(k), r)) for k in rng.integers(0, 5 * L, n_segments)]
    R = sum(lag_correlations(s, L - 1) for s in segments)
    heads = np.stack([s[:L] for s in segments])
    tails = np.stack([s[-L:] for s in segments])
    W = gram_from_lags(R, heads, tails)
    windows = np.concatenate([np.stack([s[k : k + L].ravel() for k in range(len(s) - L + 1)]) for s in segments])
    expected = windows.T @ windows
    # sums of a few hundred unit-variance products: rounding ~1e-13 of the largest entry
    np.testing.assert_allclose(W, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("horizon", [1, 4, 9])
def test_segments_statistics_equal_the_sum_over_ranges_and_the_dense_regression(horizon):
    from stageid.subspace.statistics.hankel_toeplitz import dense_regression, segments_statistics, window_statistics

    rng = np.random.default_rng(horizon)
    u, y = rng.standard_normal((700, 2)), rng.standard_normal((700, 3))
    # adjacent, separated and minimal-length ranges (2 p + 1 samples: two windows)
    ranges = [(0, 120), (120, 121 + 2 * horizon), (300, 430), (431, 700)]
    s = segments_statistics(u, y, ranges, horizon)
    total = None
    XX = YX = 0.0
    for a, b in ranges:
        w = window_statistics(u[a:b], y[a:b], horizon)
        total = w if total is None else total + w
        X, Y = dense_regression(u[a:b], y[a:b], horizon)
        XX, YX = XX + X.T @ X, YX + Y.T @ X
    assert s.count == total.count == sum(b - a - 2 * horizon + 1 for a, b in ranges)
    np.testing.assert_allclose(s.W, total.W, atol=1e-10 * np.abs(total.W).max())
    np.testing.assert_allclose(s.blocks()[0], XX, atol=1e-10 * np.abs(XX).max())
    np.testing.assert_allclose(s.blocks()[1], YX, atol=1e-10 * np.abs(YX).max())


def test_segments_statistics_reject_short_ranges():
    from stageid.subspace.statistics.hankel_toeplitz import segments_statistics

    u, y = np.zeros((100, 1)), np.zeros((100, 1))
    with pytest.raises(DataError, match="more than 10 samples; got 10"):
        segments_statistics(u, y, [(0, 50), (60, 70)], 5)
    with pytest.raises(DataError, match="at least one"):
        segments_statistics(u, y, [], 5)


@pytest.mark.parametrize(("M", "r", "n_joints"), [(1, 1, 1), (5, 2, 3), (40, 3, 2), (119, 6, 4)])
def test_straddling_lags_equal_the_products_across_each_joint(M, r, n_joints):
    # the pairs (t, t + c) with t before the joint and t + c after it, for c = 0 .. M, by hand
    from stageid.subspace.statistics.correlations import straddling_lags

    rng = np.random.default_rng([M, r, n_joints])
    z = rng.standard_normal((n_joints, 2 * M, r))
    got = straddling_lags(z[:, :M], z[:, M:])
    want = np.zeros((M + 1, r, r))
    for s in z:
        for c in range(1, M + 1):
            want[c] += s[M - c : M].T @ s[M : M + c]
    assert got.shape == (M + 1, r, r)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())


def test_gram_from_lags_takes_column_major_end_samples():
    # records read column by column (CSV) give Fortran-ordered samples; their spectra follow
    # that layout, which the real-and-imaginary view of the FFT products must not assume away
    from stageid.subspace.statistics.correlations import gram_from_lags

    rng = np.random.default_rng(7)
    z = np.asfortranarray(rng.standard_normal((90, 3)))
    R = lag_correlations(z, 9)
    want = gram_from_lags(R, np.ascontiguousarray(z[None, :10]), np.ascontiguousarray(z[None, -10:]))
    got = gram_from_lags(R, np.asfortranarray(z[None, :10]), np.asfortranarray(z[None, -10:]))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * np.abs(want).max())


@pytest.mark.parametrize("block", [1, 3, 8, 64])
def test_record_rows_fill_the_frames_with_the_joined_ranges(block):
    # ranges joined by zero gaps, written frame after frame into the data halves of FFT frames:
    # pieces starting and ending inside a frame, spanning several, gaps, and rows past the end
    from stageid.subspace.statistics.correlations import RecordRows

    rng = np.random.default_rng(block)
    u, y = rng.standard_normal((200, 2)), rng.standard_normal((200, 1))
    ranges, gap = [(3, 40), (41, 42), (90, 200)], 5
    joined = np.vstack(
        [np.vstack([np.hstack([u[a:b], y[a:b]]), np.zeros((gap, 3))]) for a, b in ranges[:-1]]
        + [np.hstack([u[90:], y[90:]])]
    )
    src = RecordRows([u, y], ranges, gap=gap)
    assert src.n == joined.shape[0]
    padded = np.vstack([joined, np.zeros((4 * block + 100, 3))])
    for lo in (0, 1, block, 37, src.n - 2):
        frames = np.full((5, 2 * block, 3), np.nan)  # rows not written would stay NaN
        src.fill(frames[:, :block], lo)
        np.testing.assert_array_equal(frames[:, :block].reshape(-1, 3), padded[lo : lo + 5 * block])
        assert np.isnan(frames[:, block:]).all()
