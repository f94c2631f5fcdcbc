"""The threshold search's fast weight fits: the same operator rows, normal equations and bounded
solutions as the operator-matrix path and scipy's BVLS."""

import numpy as np
import pytest

from stageid.hysteresis import kernels
from stageid.hysteresis.identify.weights import WeightProblem, bounded_gram_lsq, bounded_gram_lsq_bvls


def _record(seed, n=3000):
    rng = np.random.default_rng(seed)
    u = np.cumsum(rng.standard_normal(n)) * 8.0
    u[rng.random(n) < 0.3] = np.nan  # standing stretches: repeat the previous sample
    for k in range(1, n):
        if np.isnan(u[k]):
            u[k] = u[k - 1]
    u[0] = 0.0 if np.isnan(u[0]) else u[0]
    return u, np.tanh(u / 50.0) + 0.01 * rng.standard_normal(n)


def _cp_thresholds(R, n, c, a, b):
    """``r, rc, ra, rb`` of ``n`` operators over the half range ``R`` with constant ratios."""
    r = np.linspace(0.0, R, n + 1)[:n]
    return r, c * r, a * r, b * a * r


@pytest.mark.parametrize("stride", [1, 3])
@pytest.mark.parametrize("q", [0.0, 0.15, -0.3])
def test_cp_rows_are_the_bank_rows(stride, q):
    u, _ = _record(0)
    R = float(np.ptp(u)) / 2
    r = np.linspace(0.0, R, 9)[:8]
    rc, ra = 0.4 * r, 1.3 * r
    rb = 0.7 * ra
    z0 = np.zeros(8)
    x = u - 3.0
    if q:
        t = np.abs(x) / R
        x = x + q * R * np.where(t <= 1.0, t * t, 2.0 * t - 1.0)
    Z, _ = kernels.cp_bank(np.ascontiguousarray(x), r, rc, ra, rb, z0)
    rows, s, low, high = kernels.cp_rows(u, 3.0, q, R, r, rc, ra, rb, z0, stride)
    # skipping standing samples is exact (the operators are idempotent); the warp inside the
    # kernel may contract to fused multiply-adds: a few ulps of the input
    np.testing.assert_allclose(rows, Z[::stride], rtol=0, atol=1e-12 * R)
    np.testing.assert_allclose(s, rows.sum(axis=0), rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(low, rows.min(axis=0))
    np.testing.assert_array_equal(high, rows.max(axis=0))


@pytest.mark.parametrize("stride", [1, 3])
@pytest.mark.parametrize("q", [0.0, 0.15, -0.3])
def test_cp_gram_is_the_normal_equations_of_the_cp_rows(stride, q):
    u, y = _record(3)
    # twelve operators, thresholds ratios 0.5 / 1.2 / 0.6, centre -1, the warp q, from rest
    args = (-1.0, q, float(np.ptp(u)) / 2, *_cp_thresholds(float(np.ptp(u)) / 2, 12, 0.5, 1.2, 0.6), np.zeros(12))
    Z, s, low, high = kernels.cp_rows(u, *args, stride)
    yb = y[::stride]
    G, g, s2, rows, ysum, low2, high2 = kernels.cp_gram(u, yb, *args, stride)
    assert rows == Z.shape[0]
    # sums over a few thousand rows in another order than BLAS: rounding only
    np.testing.assert_allclose(G, Z.T @ Z, rtol=1e-12, atol=1e-12 * np.abs(Z.T @ Z).max())
    np.testing.assert_array_equal(G, G.T)
    np.testing.assert_allclose(g, Z.T @ yb, rtol=1e-12, atol=1e-12 * np.abs(Z.T @ yb).max())
    np.testing.assert_allclose(s2, s, rtol=1e-12, atol=1e-9)
    assert ysum == pytest.approx(float(yb.sum()), rel=1e-12, abs=1e-9)
    np.testing.assert_array_equal(low2, low)
    np.testing.assert_array_equal(high2, high)


@pytest.mark.parametrize("classical", [True, False])
def test_gram_blocks_equal_the_operator_matrix_path(classical):
    recs = [_record(1), _record(2, 2000)]
    u_all = np.concatenate([u for u, _ in recs])
    R = float(np.ptp(u_all)) / 2
    r = np.linspace(0.0, R, 11)[:10]
    prob = WeightProblem(recs, r, 1e-3, 2, "modified-pi", 1e-6, R)
    theta = np.array([0.6, 0.2, 1.3, -0.1, 0.5, 0.1, 2.0, 0.1])
    kinds = ["zero", "ascending"]
    blocks = prob.matrix(theta, kinds, classical)
    idx = prob._live(blocks)
    G1, _, g1, yy1 = prob._normal_equations([b[:, idx] for b in blocks], idx.size, classical)
    stats, motion = prob.gram_blocks(theta, kinds, classical)
    idx2 = prob._live(motion=motion)
    np.testing.assert_array_equal(idx, idx2)
    live = [(G[np.ix_(idx, idx)], g[idx], s[idx], n, ys) for G, g, s, n, ys in stats]
    G2, _, g2, yy2 = prob._assemble(live, idx.size, classical)
    # BLAS sums in another order: rounding of sums over a few thousand rows
    np.testing.assert_allclose(G2, G1, rtol=1e-12, atol=1e-12 * np.abs(G1).max())
    np.testing.assert_allclose(g2, g1, rtol=1e-12, atol=1e-12 * np.abs(g1).max())
    assert yy1 == yy2


@pytest.mark.parametrize("seed", range(6))
def test_nnls_on_the_reduced_factor_is_the_bvls_optimum(seed):
    rng = np.random.default_rng(seed)
    k, J = 12 + seed, seed % 3
    A = rng.standard_normal((300, k + J)) * rng.uniform(0.1, 10.0, k + J)
    b = A @ rng.standard_normal(k + J) + rng.standard_normal(300)
    G, g = A.T @ A, A.T @ b
    lb = np.r_[rng.uniform(-0.5, 0.5, k), np.full(J, -np.inf)]
    v1, v2 = bounded_gram_lsq(G, g, lb), bounded_gram_lsq_bvls(G, g, lb)
    assert np.all(v1[:k] >= lb[:k] - 1e-12)
    assert np.any(np.isclose(v1[:k], lb[:k], atol=1e-9))  # some bounds are active: a real test
    # one strictly convex problem: the same minimiser, to the solvers' tolerances
    np.testing.assert_allclose(v1, v2, rtol=1e-6, atol=1e-8 * np.abs(v2).max())


def test_the_weight_fit_reads_the_rows_outputs_the_problem_holds():
    # the bootstrap of the weight uncertainty refits with new outputs written into ``y``
    recs = [_record(4), _record(5, 2000)]
    R = float(np.ptp(np.concatenate([u for u, _ in recs]))) / 2
    r = np.linspace(0.0, R, 9)[:8]
    theta = np.array([0.6, 0.2, 1.3, -0.1, 0.5, 0.1, 2.0, 0.1])
    prob = WeightProblem(recs, r, 1e-3, 2, "modified-pi", 1e-6, R)
    prob.y = 2.0 * prob.y + 1.0
    rewritten = WeightProblem([(u, 2.0 * y + 1.0) for u, y in recs], r, 1e-3, 2, "modified-pi", 1e-6, R)
    for a, b in zip(prob.solve(theta, ["zero", "zero"], False), rewritten.solve(theta, ["zero", "zero"], False)):
        np.testing.assert_array_equal(a, b)
