"""Held-out selection of the horizon: the completed split, the cheap training residual, the
nested (one-factorisation) scores and the rule."""

import numpy as np
import pytest

from _subspace_systems import band_limited, random_stage, record
from stageid.subspace.map.posterior import Prior, batch_posterior, default_prior, map_estimate
from stageid.subspace.selection import (
    central_statistics,
    held_out_segments,
    horizon_candidates,
    pooled_split,
    select_horizon,
    split_statistics,
)
from stageid.subspace.selection.nested_horizons import solve_lower, solve_lower_transposed
from stageid.subspace.statistics.hankel_toeplitz import hankel_toeplitz_statistics, row_residuals, window_statistics
from stageid.subspace.statistics.window_covariance import window_lags


def _records(n, seed=3):
    g = random_stage(seed, m=2, q=2)
    exp = record(g, np.random.default_rng(seed).standard_normal((n, 2)), 0.01, seed, names=False)
    return g, [(exp.u, exp.y), (exp.u[: n // 2 + 7], exp.y[: n // 2 + 7])]


@pytest.mark.parametrize("n", [1200, 5000, 20000])
def test_pooled_split_equals_the_whole_records_statistics(n):
    # the held-out split lacks the windows across segment boundaries and the range tails of the
    # smaller horizons; pooled_split adds exactly those, so every candidate's statistics equal
    # one pass over the whole records (to rounding: 1e-12 of the largest entry).  None (a second
    # pass) only where the missing windows of neighbouring ranges overlap: ranges < 4 p samples
    _, recs = _records(n)
    cands = horizon_candidates(2, 2, [u.shape[0] for u, _ in recs])
    train, val = split_statistics(recs, cands, 1.0, 0.25)
    for p in cands:
        whole = hankel_toeplitz_statistics(recs, p)
        pooled = pooled_split(train, val, p, recs, 0.25)
        shortest = min(b - a for u, _ in recs for a, b in sum(held_out_segments(u.shape[0], 0.25), []))
        if pooled is None:
            assert shortest < 4 * p
            continue
        assert pooled.count == whole.count and pooled.n_windows == whole.n_windows
        np.testing.assert_allclose(pooled.W, whole.W, rtol=0, atol=1e-12 * np.abs(whole.W).max())
        np.testing.assert_array_equal(pooled.input_power, whole.input_power)


@pytest.mark.parametrize("n", [5000, 20000])
@pytest.mark.parametrize("n_records", [1, 2])
def test_split_from_the_whole_records_lags_equals_the_split_by_segments(n, n_records, monkeypatch):
    # with the whole records' lag correlations, the training segments' are the whole less the
    # held-out segments' and the products straddling the range boundaries: the same statistics
    # as one pass per group of ranges (to rounding), for every candidate, and no such pass made
    import stageid.subspace.selection.split as split

    _, recs = _records(n)
    recs = recs[:n_records]
    cands = horizon_candidates(2, 2, [u.shape[0] for u, _ in recs])
    want = split_statistics(recs, cands, 1.0, 0.25)
    whole = window_lags(recs, max(cands))

    def no_pass(*args, **kwargs):
        raise AssertionError("a pass over the segments")

    monkeypatch.setattr(split, "segments_statistics", no_pass)
    got = split_statistics(recs, cands, 1.0, 0.25, whole)
    for g, w in zip(got, want):
        assert sorted(g) == sorted(w) == sorted(cands)
        for p in cands:
            assert g[p].count == w[p].count and g[p].n_windows == w[p].n_windows and g[p].horizon == p
            np.testing.assert_allclose(g[p].W, w[p].W, rtol=0, atol=1e-12 * np.abs(w[p].W).max())
    # and the whole records' statistics from the same lags, every candidate
    for p in cands:
        pooled = pooled_split(*got, p, recs, 0.25, whole)
        ref = hankel_toeplitz_statistics(recs, p)
        assert pooled.count == ref.count and pooled.n_windows == ref.n_windows
        np.testing.assert_allclose(pooled.W, ref.W, rtol=0, atol=1e-12 * np.abs(ref.W).max())
        np.testing.assert_array_equal(pooled.input_power, ref.input_power)


def test_split_keeps_the_pass_by_segments_where_the_whole_lags_do_not_serve():
    # forgetting, ranges too short for the largest candidate, or lags of a smaller horizon than
    # it: the statistics by segments (the same numbers bit for bit), whatever lags are given
    _, recs = _records(1200)
    recs = recs[:1]  # 7 segments of 171-172 samples
    for forgetting, cands, top in ((0.99, [8, 12], 12), (1.0, [8, 12, 90], 90), (1.0, [8, 12, 16], 12)):
        got = split_statistics(recs, cands, forgetting, 0.25, window_lags(recs, top))
        want = split_statistics(recs, cands, forgetting, 0.25)
        for g, w in zip(got, want):
            assert sorted(g) == sorted(w)
            for p in w:
                np.testing.assert_array_equal(g[p].W, w[p].W)


@pytest.mark.parametrize("strength", [1e-5, 1e-2])
def test_posterior_residual_identity_equals_the_explicit_residual(strength):
    # batch_posterior's residual by the MAP identity (diagonal prior around zero) against the
    # explicit O(p q d^2) form, which a prior with an explicit zero mean takes
    _, recs = _records(6000)
    stats = hankel_toeplitz_statistics(recs, 12)
    prior = default_prior(stats, strength)
    fast = batch_posterior(stats, prior)
    explicit = batch_posterior(stats, Prior(np.zeros_like(fast.theta), prior.precision))
    np.testing.assert_array_equal(fast.theta, explicit.theta)
    rows = row_residuals(fast.theta, stats)
    np.testing.assert_allclose(np.diag(explicit.residual), rows, rtol=1e-10)
    # residual ~1e-4 of the output energy: the identity keeps it to ~1e-7
    np.testing.assert_allclose(fast.residual, explicit.residual, rtol=0, atol=1e-6 * rows.max())


def _split(seed=24, n=20000):
    g = random_stage(seed)
    exp = record(g, band_limited(n, 2, g.dt, seed), 0.01, seed, names=False)
    recs = [(exp.u / exp.u.std(axis=0), exp.y / exp.y.std(axis=0))]
    cands = horizon_candidates(2, 2, [n])
    return recs, cands, *split_statistics(recs, cands, 1.0, 0.25)


def test_central_statistics_are_the_shifted_windows_of_the_smaller_horizon():
    # horizon p from the top P: the windows of the top shifted by P - p, i.e. the horizon-p
    # windows of the record without its first and last P - p samples (the windows the horizon
    # scores use, predicting from the same point)
    _, recs = _records(3000)
    u, y = recs[0]
    top = window_statistics(u, y, 20, with_spectrum=False)
    s = central_statistics(top, 8)
    want = window_statistics(u[12:-12], y[12:-12], 8, with_spectrum=False)
    assert s.count == want.count
    np.testing.assert_allclose(s.W, want.W, rtol=0, atol=1e-12 * np.abs(want.W).max())


def test_blocked_triangular_solves():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((300, 300))
    L = np.linalg.cholesky(X @ X.T + 300 * np.eye(300))
    B = rng.standard_normal((300, 7))
    inverses = [np.linalg.inv(L[a : a + 64, a : a + 64]) for a in range(0, 300 - 63, 64)]
    for inv in (None, inverses):
        for d in (300, 200, 64, 50):  # leading blocks of the factor, as the candidates use them
            want, want_t = np.linalg.solve(L[:d, :d], B[:d]), np.linalg.solve(L[:d, :d].T, B[:d])
            got = solve_lower(L[:d, :d], B[:d], block=64, inverses=inv)
            got_t = solve_lower_transposed(L[:d, :d], B[:d], block=64, inverses=inv)
            np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12 * np.abs(want).max())
            np.testing.assert_allclose(got_t, want_t, rtol=1e-10, atol=1e-12 * np.abs(want_t).max())


def test_nested_scores_equal_candidate_by_candidate_solves():
    # the default prior takes the one-factorisation path; the same prior given with an explicit
    # zero mean is solved candidate by candidate (map_estimate): the scores must agree
    recs, cands, train, val = _split()
    chosen, table = select_horizon(train, val, cands, default_prior)
    slow_prior = lambda s: Prior(np.zeros((s.horizon * 2, s.horizon * 6)), default_prior(s).precision)  # noqa: E731
    chosen_slow, slow = select_horizon(train, val, cands, slow_prior)
    assert table.values == slow.values == tuple(cands)
    np.testing.assert_allclose(table.errors, slow.errors, rtol=1e-8)
    assert chosen == chosen_slow == min(zip(table.errors, table.values))[1]


def test_horizon_rule_scores_the_first_block_rows_of_every_candidate():
    # the error of candidate p: held-out residual of y(k) .. y(k + p_min - 1) under the MAP
    # estimate from the training windows, outputs weighted by the top's training noise
    recs, cands, train, val = _split()
    chosen, table = select_horizon(train, val, cands, default_prior)
    lead, top, q = cands[0], cands[-1], 2
    # one Gram matrix per split here: the candidates use the central windows of the largest
    assert all(train[p].count == train[top].count for p in cands)
    train = {p: central_statistics(train[top], p) for p in cands}
    val = {p: central_statistics(val[top], p) for p in cands}
    rows = lead * q
    t_top = map_estimate(*train[top].blocks()[:2], default_prior(train[top]))[0]
    noise = row_residuals(t_top, train[top])[:rows].reshape(lead, q).mean(axis=0) / (
        train[top].n_windows - t_top.shape[1]
    )
    ms = np.diag(train[top].blocks()[2])[:rows].reshape(lead, q).mean(axis=0) / train[top].n_windows
    w2 = (1.0 / np.maximum(np.sqrt(noise), 1e-3 * np.sqrt(ms))) ** 2
    for p, err in zip(table.values, table.errors):
        theta = map_estimate(*train[p].blocks()[:2], default_prior(train[p]))[0]
        res = row_residuals(theta, val[p])[:rows].reshape(lead, q).sum(axis=0)
        energy = np.diag(val[p].blocks()[2])[:rows].reshape(lead, q).sum(axis=0)
        np.testing.assert_allclose(err, np.sum(w2 * res) / np.sum(w2 * energy), rtol=1e-8)
    assert chosen == table.values[int(np.argmin(table.errors))]
