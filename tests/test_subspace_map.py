"""MAP estimation (eq. 16-18): batch information form, recursion, flat prior = least squares."""

import numpy as np
import pytest

from stageid._errors import DataError
from stageid.subspace.map.posterior import Prior, batch_posterior, default_prior
from stageid.subspace.map.recursion import recursive_map, recursive_map_python
from stageid.subspace.statistics.hankel_toeplitz import dense_regression, window_statistics


def _data(seed, n=500, m=2, q=3):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, m))
    y = np.zeros((n, q))
    M = rng.standard_normal((m, q))
    for k in range(1, n):
        y[k] = 0.6 * y[k - 1] + u[k - 1] @ M
    return u, y + 0.05 * rng.standard_normal((n, q))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_flat_prior_map_equals_batch_least_squares(seed):
    u, y = _data(seed)
    p = 3
    post = batch_posterior(window_statistics(u, y, p), None)
    X, Y = dense_regression(u, y, p)
    theta_ls = np.linalg.lstsq(X, Y, rcond=None)[0].T
    # well-conditioned white data: both are the same unique LS solution to rounding
    np.testing.assert_allclose(post.theta, theta_ls, atol=1e-9 * np.abs(theta_ls).max())


def test_recursion_with_vague_prior_tends_to_least_squares():
    u, y = _data(5)
    p = 2
    d = 2 * p * 2 + p * 3
    theta, _ = recursive_map(u, y, p, np.zeros((p * 3, d)), 1e10 * np.eye(d))
    X, Y = dense_regression(u, y, p)
    theta_ls = np.linalg.lstsq(X, Y, rcond=None)[0].T
    # prior precision 1e-10 against data information ~1e2: relative difference ~1e-10
    np.testing.assert_allclose(theta, theta_ls, atol=1e-6 * np.abs(theta_ls).max())


@pytest.mark.parametrize("forgetting", [1.0, 0.99])
def test_recursion_equals_batch_posterior_and_python_reference(forgetting):
    u, y = _data(3, n=300)
    p = 2
    d = 2 * p * 2 + p * 3
    rng = np.random.default_rng(9)
    theta0 = 0.1 * rng.standard_normal((p * 3, d))
    P0 = 10.0 * np.eye(d)
    th_c, P_c = recursive_map(u, y, p, theta0, P0, forgetting, block=1)
    th_py, P_py = recursive_map_python(u, y, p, theta0, P0, forgetting)
    th_b, P_b = recursive_map(u, y, p, theta0, P0, forgetting, block=7)  # exact block form
    np.testing.assert_allclose(th_b, th_py, atol=1e-9)
    np.testing.assert_allclose(P_b, P_py, atol=1e-11)
    stats = window_statistics(u, y, p, forgetting=forgetting)
    # batch form: prior information discounted by lambda^N like the recursion's P_0 / lambda^N
    post = batch_posterior(stats, Prior(theta0, np.linalg.inv(P0) * forgetting**stats.count))
    np.testing.assert_allclose(th_c, th_py, atol=1e-10)
    np.testing.assert_allclose(P_c, P_py, atol=1e-12)
    np.testing.assert_allclose(th_c, post.theta, atol=1e-9)
    np.testing.assert_allclose(P_c, post.covariance, atol=1e-10 * np.abs(P_c).max())


def test_recursion_does_not_modify_its_inputs():
    u, y = _data(4, n=100)
    p = 2
    d = 14
    theta0 = np.zeros((6, d))
    P0 = np.eye(d)
    recursive_map(u, y, p, theta0, P0)
    assert not theta0.any() and np.array_equal(P0, np.eye(d))


def test_posterior_update_equals_fit_on_all_records():
    u, y = _data(6, n=800)
    p = 3
    s1 = window_statistics(u[:400], y[:400], p)
    s2 = window_statistics(u[400:], y[400:], p)
    prior = default_prior(s1, 1e-6)
    both = batch_posterior(s1 + s2, prior)
    step = batch_posterior(s1, prior).updated(s2)
    np.testing.assert_allclose(step.theta, both.theta, atol=1e-10)
    np.testing.assert_allclose(step.noise_cov, both.noise_cov, rtol=1e-8)


def test_posterior_std_shrinks_with_data():
    u, y = _data(7, n=2000)
    p = 2
    small = batch_posterior(window_statistics(u[:300], y[:300], p), None)
    large = batch_posterior(window_statistics(u, y, p), None)
    assert np.median(large.theta_std() / small.theta_std()) < 0.6  # ~ sqrt(300 / 2000) = 0.39


def test_bad_shapes_and_forgetting_are_rejected():
    u, y = _data(0, n=50)
    with pytest.raises(DataError, match="`theta` must have shape"):
        recursive_map(u, y, 2, np.zeros((3, 3)), np.eye(3))
    with pytest.raises(DataError, match="forgetting"):
        recursive_map(u, y, 2, np.zeros((6, 14)), np.eye(14), forgetting=1.5)


def _dense_prior(rng, d, scale):
    """A dense, well-conditioned prior covariance (eigenvalues in [scale / 10, scale])."""
    Q, _ = np.linalg.qr(rng.standard_normal((d, d)))
    return (Q * (scale * rng.uniform(0.1, 1.0, d))) @ Q.T


@pytest.mark.parametrize("forgetting", [1.0, 0.99])
@pytest.mark.parametrize("extra", [0, 1, 2, 3, 5, 8, 30])
@pytest.mark.parametrize("m, q", [(1, 2), (0, 2), (1, 1)])
def test_grouped_recursion_equals_reference_for_every_record_length(forgetting, extra, m, q):
    # recursive_map runs the first d windows one at a time, then groups of four with delayed
    # updates, then the last (< 4) one at a time: lengths around every switch point
    # (m = 0: output-only data, x holds past outputs only; q = 1: odd d = 9 and p q = 3, which
    # the grouped kernel pads to an even number of rows)
    p = 3
    d = 2 * p * m + p * q
    rng = np.random.default_rng(extra)
    n_windows = d + 2 * 4 + extra if extra < 30 else 40 * d
    u, y = _data(11 + extra, n=n_windows + 2 * p - 1, m=m, q=q)
    y = y + 0.3 * rng.standard_normal(y.shape)  # both outputs well excited
    theta0 = 0.1 * rng.standard_normal((p * q, d))
    P0 = _dense_prior(rng, d, 5.0)
    th_c, P_c = recursive_map(u, y, p, theta0, P0, forgetting)
    th_py, P_py = recursive_map_python(u, y, p, theta0, P0, forgetting)
    # the same arithmetic in another order: rounding only (relative 1e-12 leaves 1e3 eps of room;
    # the textbook P update amplifies rounding by up to forgetting^-n, 0.99^-480 ~ 1e2, so long
    # records with strong forgetting would test the reference's drift, not this kernel)
    np.testing.assert_allclose(th_c, th_py, rtol=0, atol=1e-12 * np.abs(th_py).max())
    np.testing.assert_allclose(P_c, P_py, rtol=0, atol=1e-12 * np.abs(P_py).max())


@pytest.mark.parametrize("forgetting", [1.0, 0.97])
def test_delayed_update_kernel_from_the_prior_equals_reference(forgetting):
    # the four-window delayed-update kernel on its own (no one-window warm-up), from a dense prior
    from stageid.subspace.map import kernels as mk

    p, m, q = 2, 2, 3
    d = 2 * p * m + p * q
    rows = p * q
    rng = np.random.default_rng(21)
    u, y = _data(22, n=4 * 25 + 2 * p - 1, m=m, q=q)  # 100 windows: 25 groups, no remainder
    theta0 = rng.standard_normal((rows, d))
    P0 = _dense_prior(rng, d, 2.0)
    dp = -(-d // 4) * 4
    th = mk.aligned_zeros((rows, dp))
    th[:, :d] = theta0
    Pw = mk.aligned_zeros((d, dp))
    Pw[:, :d] = P0
    work = [mk.aligned_zeros((mk.DELAY, dp)) if k in (0, 2, 4, 6, 8) else np.zeros((mk.DELAY, rows)) for k in range(10)]
    done = mk.delayed_kernel()(u.ravel(), y.ravel(), u.shape[0], p, m, q, th, Pw, forgetting, *work)
    assert done == 100
    th_py, P_py = recursive_map_python(u, y, p, theta0, P0, forgetting)
    assert not th[:, d:].any() and not Pw[:, d:].any()  # the padding stays zero
    # rounding only (relative 1e-12)
    np.testing.assert_allclose(th[:, :d], th_py, rtol=0, atol=1e-12 * np.abs(th_py).max())
    np.testing.assert_allclose(Pw[:, :d], P_py, rtol=0, atol=1e-12 * np.abs(P_py).max())


def test_vector_intrinsics_match_numpy():
    # the 4-wide operations the delayed-update kernel is written in (stageid.simd)
    numba = pytest.importorskip("numba")
    from stageid.runtime.simd import vbcast, vfma, vfnma, vload, vmul, vstore, vsum, vzero

    @numba.njit
    def kernel(a, b, c, out):
        acc = vzero()
        for t in range(0, a.shape[0], 4):
            v = vfnma(vbcast(2.0), vload(b, t), vfma(vload(a, t), vload(b, t), vload(c, t)))
            vstore(out, t, vmul(v, vbcast(0.5)))
            acc = vfma(vload(a, t), vload(b, t), acc)
        return vsum(acc)

    rng = np.random.default_rng(3)
    a, b, c = (rng.standard_normal(12) for _ in range(3))
    out = np.zeros(12)
    dot = kernel(a, b, c, out)
    # fused multiply-adds round once where numpy rounds twice: a few ulps
    np.testing.assert_allclose(out, 0.5 * (a * b + c - 2.0 * b), rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(dot, a @ b, rtol=1e-14)


def _register_sums(a, out):
    # the shape of the delayed-update kernel's loops: a register list indexed by a written-out loop
    acc = [0.0 for j in range(DELAY_FOR_TEST)]
    for t in range(a.shape[1]):
        for j in range(DELAY_FOR_TEST):
            acc[j] = acc[j] + a[j, t] * (j + 1)
    for j in range(DELAY_FOR_TEST):
        out[j] = acc[j]


DELAY_FOR_TEST = 3


def test_written_out_loops_compute_what_the_rolled_source_does():
    from stageid.runtime.unroll import written_out

    a = np.arange(12.0).reshape(3, 4)
    rolled, unrolled = np.zeros(3), np.zeros(3)
    _register_sums(a, rolled)
    fn = written_out(_register_sums, {"DELAY_FOR_TEST": DELAY_FOR_TEST})
    fn(a, unrolled)
    np.testing.assert_array_equal(unrolled, rolled)
    np.testing.assert_array_equal(rolled, a.sum(axis=1) * [1, 2, 3])
    # the constant-count loops are gone, the run-time loop over t stays; acc[j] became acc_0..acc_2
    code = fn.__code__
    assert {"acc_0", "acc_1", "acc_2"} <= set(code.co_varnames) and "acc" not in code.co_varnames
    assert code.co_filename == __file__  # tracebacks and numba's cache point at the source as written
