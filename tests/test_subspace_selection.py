"""Held-out selection of the horizon: the completed split, the cheap training residual, the search rule."""

import numpy as np
import pytest

from _subspace_systems import band_limited, random_stage, record
from stageid.subspace.hankel_toeplitz import hankel_toeplitz_statistics, row_residuals
from stageid.subspace.map_estimator import Prior, default_prior, map_estimate
from stageid.subspace.selection import (
    HORIZON_GAIN,
    held_out_segments,
    horizon_candidates,
    pooled_split,
    select_horizon,
    split_statistics,
    training_noise,
)


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


@pytest.mark.parametrize("strength", [1e-5, 1e-2])
def test_training_noise_identity_equals_the_explicit_residual(strength):
    _, recs = _records(6000)
    stats = hankel_toeplitz_statistics(recs, 12)
    prior = default_prior(stats, strength)
    theta = map_estimate(*stats.blocks()[:2], prior)[0]
    fast = training_noise(theta, prior, stats)
    # the explicit O(p q d^2) residual; the flat prior (None) takes that route itself
    explicit = training_noise(theta, Prior(np.zeros_like(theta), prior.precision), stats)
    rows = row_residuals(theta, stats).reshape(12, 2).mean(axis=0) / (stats.n_windows - theta.shape[1])
    np.testing.assert_allclose(explicit[0], rows, rtol=1e-12)
    np.testing.assert_allclose(fast[0], explicit[0], rtol=1e-6)  # residual ~1e-4 of the output energy
    np.testing.assert_array_equal(fast[1], explicit[1])


def test_horizon_search_rule():
    g = random_stage(24)
    exp = record(g, band_limited(20000, 2, g.dt, 24), 0.01, 24, names=False)
    recs = [(exp.u / exp.u.std(axis=0), exp.y / exp.y.std(axis=0))]
    cands = horizon_candidates(2, 2, [20000])
    train, val = split_statistics(recs, cands, 1.0, 0.25)
    chosen, table = select_horizon(train, val, cands, default_prior)
    errors = dict(zip(table.values, table.errors))
    # every candidate up to half the largest is scored, then the search goes on while the error falls by 0.1 %
    assert [p for p in cands if 2 * p <= max(cands)] == [p for p in table.values if 2 * p <= max(cands)]
    scored = list(table.values)
    for k, p in enumerate(scored):
        if 2 * p > max(cands) and p != scored[-1]:
            assert errors[p] < min(errors[q] for q in scored[:k]) * (1 - HORIZON_GAIN)
    if scored[-1] != max(cands):
        last = scored[-1]
        assert not errors[last] < min(errors[q] for q in scored[:-1]) * (1 - HORIZON_GAIN)
    assert chosen == min(errors, key=errors.get)
