"""The eq. 9 covariance under overlapping windows (stageid.subspace.statistics.window_covariance)."""

from __future__ import annotations

import numpy as np
import pytest

from _subspace_systems import band_limited, random_stage, record
from stageid.subspace import HankelMAP
from stageid.subspace.statistics.hankel_toeplitz import dense_regression, regressor_indices
from stageid.subspace.statistics.window_covariance import (
    WindowFilter,
    lag_spectrum,
    lag_sum,
    overlap_response_covariance,
    self_lag_products,
    window_lags,
)
from stageid.subspace.uncertainty import column_solve, weighted_parts


def _explicit_lag_products(recs, p, h, lags):
    """``sum_t s_t conj(s_(t+l))^T`` and ``sum_t s_t s_(t+l)^T`` over the whole windows, by hand."""
    out_c = np.zeros((lags.size, h.shape[1], h.shape[1]), dtype=complex)
    out_p = np.zeros_like(out_c)
    for u, y in recs:
        z = np.hstack([u, y])
        K = z.shape[0] - 2 * p + 1
        s = np.stack([z[t : t + 2 * p].reshape(-1) for t in range(K)]) @ h
        for i, lag in enumerate(lags):
            out_c[i] += s[: K - lag].T @ np.conj(s[lag:])
            out_p[i] += s[: K - lag].T @ s[lag:]
    return out_c, out_p


@pytest.mark.parametrize("p", [3, 4])
def test_self_lag_products_equal_the_sums_over_whole_windows(p):
    # lags 0..2p-1 on 4p DFT points: every pair of whole windows, none with a window outside a
    # record (two records, a drifting output: large end corrections at both ends)
    rng = np.random.default_rng(p)
    r = 3
    recs = [(rng.standard_normal((n, 1)), np.cumsum(rng.standard_normal((n, 2)), axis=0) * 0.3 + 5) for n in (200, 333)]
    stats = window_lags(recs, p)
    n = 8 * p
    h = rng.standard_normal((2 * p * r, 4)) + 1j * rng.standard_normal((2 * p * r, 4))
    got_c, got_p = self_lag_products(WindowFilter(h, np.arange(2 * p * r), p, r, n), lag_spectrum(stats.lags, n), stats)
    want_c, want_p = _explicit_lag_products(recs, p, h, np.arange(2 * p))
    np.testing.assert_allclose(got_c, want_c, rtol=0, atol=1e-12 * np.abs(want_c).max())
    np.testing.assert_allclose(got_p, want_p, rtol=0, atol=1e-12 * np.abs(want_p).max())


def test_self_lag_products_in_several_blocks_equal_the_sums_over_whole_windows(monkeypatch):
    # blocks of a few rows (each transform written into its rows of the lags-last store): the
    # same sums as one block and as by hand
    import stageid.subspace.statistics.window_covariance as wc

    rng = np.random.default_rng(7)
    p, r = 3, 3
    recs = [(rng.standard_normal((n, 2)), rng.standard_normal((n, 1)) + 2) for n in (150, 97)]
    stats = window_lags(recs, p)
    n = 8 * p
    h = rng.standard_normal((2 * p * r, 11)) + 1j * rng.standard_normal((2 * p * r, 11))
    S = lag_spectrum(stats.lags, n)
    one_c, one_p = self_lag_products(WindowFilter(h, np.arange(2 * p * r), p, r, n), S, stats)
    monkeypatch.setattr(wc, "BLOCK_ENTRIES", 4 * p * 22 * 3)  # 3 rows per block: 4 blocks, the last short
    got_c, got_p = self_lag_products(WindowFilter(h, np.arange(2 * p * r), p, r, n), S, stats)
    want_c, want_p = _explicit_lag_products(recs, p, h, np.arange(2 * p))
    assert got_c.shape == got_p.shape == (2 * p, 11, 11)
    np.testing.assert_allclose(got_c, want_c, rtol=0, atol=1e-12 * np.abs(want_c).max())
    np.testing.assert_allclose(got_p, want_p, rtol=0, atol=1e-12 * np.abs(want_p).max())
    np.testing.assert_allclose(got_c, one_c, rtol=0, atol=1e-13 * np.abs(want_c).max())


def _explicit_lag_sum(B, A, nz, q, m):
    L = B.shape[0]
    w = np.r_[0.5, np.ones(L - 1)]
    Bk, Ak = B.reshape(L, nz, q, nz, q), A.reshape(L, nz, m, nz, m)
    want = np.zeros((nz, q, m, nz, q, m), dtype=complex)
    for c in range(L):
        for k in range(nz):
            for kk in range(nz):
                want[k, :, :, kk] += w[c] * np.einsum("ix,jy->ijxy", Bk[c, k, :, kk], Ak[c, k, :, kk])
    return want.reshape(nz * q * m, -1)


@pytest.mark.parametrize("q, m", [(1, 1), (2, 1), (1, 3), (2, 2)])
def test_lag_sum_of_lags_last_views_leaves_them_alone(q, m):
    # the layout self_lag_products returns (views of a lags-last store, half its lags): one input
    # or output makes lag_sum's regrouping a view too, which must not be scaled in place
    rng = np.random.default_rng(q + 3 * m)
    L, nz = 4, 3
    store_b = rng.standard_normal((nz * q, nz * q, 2 * L)) + 1j * rng.standard_normal((nz * q, nz * q, 2 * L))
    store_a = rng.standard_normal((nz * m, nz * m, 2 * L)) + 1j * rng.standard_normal((nz * m, nz * m, 2 * L))
    B, A = store_b.transpose(2, 0, 1)[:L], store_a.transpose(2, 0, 1)[:L]
    A0, B0 = A.copy(), B.copy()
    got = lag_sum(B, A, nz, q, m)
    np.testing.assert_allclose(got, _explicit_lag_sum(B0, A0, nz, q, m), rtol=1e-13, atol=1e-13)
    np.testing.assert_array_equal(A, A0)
    np.testing.assert_array_equal(B, B0)


def test_lag_sum_is_the_sum_over_lags_of_the_kronecker_products():
    rng = np.random.default_rng(1)
    L, nz, q, m = 5, 3, 2, 3
    B = rng.standard_normal((L, nz * q, nz * q)) + 1j * rng.standard_normal((L, nz * q, nz * q))
    A = rng.standard_normal((L, nz * m, nz * m)) + 1j * rng.standard_normal((L, nz * m, nz * m))
    want = _explicit_lag_sum(B, A, nz, q, m)
    A0 = A.copy()
    np.testing.assert_allclose(lag_sum(B, A, nz, q, m), want, rtol=1e-13, atol=1e-13)
    np.testing.assert_array_equal(A, A0)  # the caller's array is not modified


def test_column_solve_applies_the_posterior_covariance():
    g = random_stage(8, m=1, q=2, modes=2)
    res = HankelMAP(horizon=10, order=4).fit(record(g, band_limited(3000, 1, g.dt, 0), 0.02, 0, names=False))
    post = res.channels[0].scaled_posterior
    V = np.random.default_rng(0).standard_normal((post.information.shape[0], 5))
    col_cov = weighted_parts(post)[0].column_cov
    want = col_cov / post.horizon @ V
    np.testing.assert_allclose(column_solve(post)(V), want, rtol=1e-8, atol=1e-10 * np.abs(want).max())


def test_column_solve_of_a_complex_right_hand_side():
    # real and imaginary parts solved as one real system: the same as the complex product
    g = random_stage(8, m=1, q=2, modes=2)
    res = HankelMAP(horizon=10, order=4).fit(record(g, band_limited(3000, 1, g.dt, 0), 0.02, 0, names=False))
    post = res.channels[0].scaled_posterior
    rng = np.random.default_rng(1)
    V = rng.standard_normal((post.information.shape[0], 5)) + 1j * rng.standard_normal((post.information.shape[0], 5))
    col_cov = weighted_parts(post)[0].column_cov
    want = col_cov / post.horizon @ V
    got = column_solve(post)(V)
    assert np.iscomplexobj(got)
    np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-10 * np.abs(want).max())


def test_short_records_keep_no_lag_statistics():
    u, y = np.zeros((30, 1)), np.zeros((30, 1))
    assert window_lags([(u, y)], 4) is None  # 30 < 8 p
    assert window_lags([(u, y)], 3) is not None


def test_eq9_response_std_matches_its_scatter_over_noise_seeds():
    # one input and noise record held, 40 noise seeds: the scatter of the eq. 9 response is what
    # the overlap covariance predicts (the p P allowance was ~1.4x off in std on this stage)
    g = random_stage(8, m=1, q=2, modes=2)
    u = band_limited(4000, 1, g.dt, 0)
    f = np.linspace(5, 90, 8)
    G9, pred = [], []
    for seed in range(40):
        res = HankelMAP(horizon=15, order=4).fit(record(g, u, 0.02, seed, names=False))
        ch = res.channels[0]
        post = ch.scaled_posterior
        p, m, q = post.horizon, post.n_inputs, post.n_outputs
        spread, w = weighted_parts(post)
        theta_w, col_cov = spread.theta, spread.column_cov
        stats = ch.window_lags.weighted(np.concatenate([np.ones(m), w]))
        G, cov, _ = overlap_response_covariance(theta_w, col_cov / p, stats, post.n_windows, p, m, q, f, g.dt)
        G9.append(G.reshape(-1) / np.repeat(w, m)[None, :].repeat(f.size, 0).reshape(-1))
        pred.append(np.sqrt(np.real(np.diag(cov))) / np.repeat(w, m)[None, :].repeat(f.size, 0).reshape(-1))
    scatter = np.std(np.array(G9), axis=0) * np.sqrt(40 / 39)
    ratio = scatter / np.median(np.array(pred), axis=0)
    # 40 seeds estimate a std to ~11 %; a std sqrt(p) or p^-1/2 off would be 3.9x off
    assert 0.75 < np.median(ratio) < 1.3, np.median(ratio)
    assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio


@pytest.mark.parametrize("horizon", [5, 12])
def test_lag_statistics_hold_the_fit_gram(horizon):
    # the kept lag statistics rebuild the fit's own eq. 9 Gram exactly (end corrections included)
    g = random_stage(8, m=1, q=2, modes=2)
    exp = record(g, band_limited(600, 1, g.dt, 1), 0.02, 1, names=False)
    res = HankelMAP(horizon=horizon, order=4, detrend=False).fit(exp)
    ch = res.channels[0]
    su, sy = ch.scales
    X, Y = dense_regression(exp.u / su, exp.y / sy, horizon)
    stats = ch.window_lags
    n = 8 * horizon
    d = X.shape[1]
    ones = np.eye(d)
    # the lag products of the unit regressor filters are X^T X (lag 0) and X(t)^T X(t+1)
    pos, _ = regressor_indices(horizon, 1, 2)
    f = WindowFilter(ones, pos, horizon, 3, n)
    got, _ = self_lag_products(f, lag_spectrum(stats.lags, n), stats)
    np.testing.assert_allclose(got[0].real, X.T @ X, rtol=0, atol=1e-10 * np.abs(X.T @ X).max())
    np.testing.assert_allclose(got[1].real, X[:-1].T @ X[1:], rtol=0, atol=1e-10 * np.abs(X.T @ X).max())


def test_lags_of_a_larger_horizon_serve_the_smaller_ones():
    # one pass at the largest candidate: its lags cut to a smaller horizon are that horizon's
    # (to rounding: the FFT blocks differ), and rebuild the whole records' eq. 9 statistics
    from stageid.subspace.statistics.hankel_toeplitz import hankel_toeplitz_statistics

    g = random_stage(5, m=2, q=2)
    recs = [(e.u, e.y) for e in (record(g, band_limited(n, 2, g.dt, n), 0.01, n, names=False) for n in (900, 640))]
    top = window_lags(recs, 20)
    assert top.horizon == 20 and top.lengths == (900, 640)
    for p in (20, 13, 8, 1):
        got, want = top.at(p), window_lags(recs, p)
        assert got.horizon == p and got.lengths == want.lengths
        np.testing.assert_allclose(got.lags, want.lags, rtol=0, atol=1e-12 * np.abs(want.lags).max())
        np.testing.assert_array_equal(got.heads, want.heads)
        np.testing.assert_array_equal(got.tails, want.tails)
        s, ref = top.statistics(p, 2), hankel_toeplitz_statistics(recs, p)
        assert (s.count, s.n_windows, s.horizon, s.n_inputs, s.n_outputs) == (ref.count, ref.n_windows, p, 2, 2)
        np.testing.assert_allclose(s.W, ref.W, rtol=0, atol=1e-12 * np.abs(ref.W).max())


def test_a_chosen_horizon_keeps_its_own_lag_statistics():
    # the fit takes the lags once at its largest candidate; what it keeps is the chosen horizon's
    g = random_stage(8, m=1, q=2, modes=2)
    exp = record(g, band_limited(4000, 1, g.dt, 1), 0.02, 1, names=False)
    res = HankelMAP(order=4, detrend=False).fit(exp)
    ch = res.channels[0]
    su, sy = ch.scales
    want = window_lags([(exp.u / su, exp.y / sy)], ch.horizon)
    assert ch.window_lags.horizon == ch.horizon < max(res.channels[0].horizon_table.values)
    np.testing.assert_allclose(ch.window_lags.lags, want.lags, rtol=0, atol=1e-12 * np.abs(want.lags).max())
    np.testing.assert_allclose(ch.window_lags.heads, want.heads, rtol=1e-14)
