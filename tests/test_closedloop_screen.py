"""The order screen of session 10: one QR per pass for all orders, then one own pass per order.

* :func:`~stageid.closedloop.regression.prefix_lstsq` gives, for every leading column block,
  :func:`~stageid.closedloop.regression.lstsq`'s solution of that block alone;
* :func:`~stageid.closedloop.initial.steiglitz_mcbride_orders` is Steiglitz-McBride of the largest
  order, and each smaller order the least squares of its own regressor on the same pre-filtered
  data;
* the screen's orders give a 2x2 plant as accurate as the issue asks (diagonal < 1 %, coupling
  < 5 % of the peak, unstable poles < 1 %) on a record where the screen with six common passes
  and two own passes per order did not (1.65 % diagonal, 4.0 % pole error; the common passes
  alone, without the own pass, pick order 5 for the order-2 system of
  ``test_closedloop_pem.test_select_order_finds_the_true_order``);
* :func:`~stageid.models.minimal.controllable_basis` and the shared poles of the cancellation
  give the subspaces and roots of the reference formulas.
"""

import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.signal as ss

from stageid.closedloop import ClosedLoopIdentification, cancellation, initial, regression
from stageid.models import StateSpaceModel
from stageid.models.minimal import controllable_basis

sys.path.insert(0, str(Path(__file__).parent))
import _closedloop_plant2x2 as p2  # noqa: E402


def _graded(seed, m=400, k=13):
    """Columns over twelve decades, one nearly repeating another (rank decisions matter)."""
    rng = np.random.default_rng(seed)
    W = rng.standard_normal((m, k + 1)) * 10.0 ** rng.uniform(-6, 6, k + 1)
    W[:, 5] = W[:, 2] * (1 + 1e-14) + 1e-16 * np.abs(W[:, 2]).max() * rng.standard_normal(m)
    return np.asfortranarray(W)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_prefix_lstsq_is_the_least_squares_of_each_leading_block(seed):
    W = _graded(seed)
    sizes = [1, 2, 4, 5, 6, 9, 13]
    want = {k: regression.lstsq(W[:, :k].copy(), W[:, -1].copy(), "test", strict=False) for k in sizes}
    got = regression.prefix_lstsq(W.copy(order="F"), sizes, "test")
    assert sorted(got) == sizes
    for k in sizes:
        # the fitted values are what a rank-deficient block determines
        fit_w, fit_g = W[:, :k] @ want[k], W[:, :k] @ got[k]
        assert np.linalg.norm(fit_g - fit_w) <= 1e-9 * np.linalg.norm(W[:, -1]), k
        if k < 6:  # full rank: the solution itself
            np.testing.assert_allclose(got[k], want[k], rtol=1e-8, err_msg=str(k))


def test_prefix_lstsq_short_records_and_zero_columns():
    rng = np.random.default_rng(7)
    W = np.asfortranarray(rng.standard_normal((9, 7)))
    W[:, 4] = 0.0
    got = regression.prefix_lstsq(W.copy(order="F"), [2, 3, 5, 6], "test")
    assert sorted(got) == [2, 3]  # blocks holding the zero column are left out
    for k in (2, 3):
        assert np.array_equal(got[k], regression.lstsq(W[:, :k].copy(), W[:, -1].copy(), "test", strict=False))


def _records(seed=0, lengths=(1500, 1200), noise=0.02):
    rng = np.random.default_rng(seed)
    us = [rng.standard_normal(n) for n in lengths]
    ys = [ss.lfilter([0, 0.3, 0.1, -0.05], [1, -1.5, 0.9, -0.2], u) + noise * rng.standard_normal(u.size) for u in us]
    return regression.records(us, ys)


@pytest.mark.parametrize("nk", [1, 2])
def test_order_scan_is_steiglitz_mcbride_of_the_largest_order_and_least_squares_below(nk):
    segs = _records()
    orders = [1, 2, 3, 5]
    got = initial.steiglitz_mcbride_orders(segs, orders, nk, 4)
    assert sorted(got) == orders
    B5, F5 = initial.steiglitz_mcbride(segs, 5, 5, nk, n_iter=4)
    np.testing.assert_allclose(got[5][1], F5, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(got[5][0], B5, rtol=1e-8, atol=1e-10)
    # the smaller orders: their own regressor, pre-filtered by the largest order's F of pass 3
    _, F_pre = initial.steiglitz_mcbride(segs, 5, 5, nk, n_iter=3)
    for n in (1, 2, 3):
        rows, rhs = [], []
        for uu, yy in segs:
            yf, uf = ss.lfilter([1.0], F_pre, yy), ss.lfilter([1.0], F_pre, uu)
            rows.append(np.hstack([-regression.shifted(yf, n, 1), regression.shifted(uf, n, nk)]))
            rhs.append(yf)
        th = regression.lstsq(np.vstack(rows), np.concatenate(rhs), "ref", strict=False)
        np.testing.assert_allclose(got[n][0], th[n:], rtol=1e-8, atol=1e-10, err_msg=str(n))
        F_ref = initial.stabilize(np.concatenate([[1.0], th[:n]]))
        np.testing.assert_allclose(got[n][1], F_ref, rtol=1e-8, atol=1e-10, err_msg=str(n))


def _accuracy_2x2(seed, snr_db):
    exps = p2.chirp_experiments((seed, seed + 1), snr_db)
    res = ClosedLoopIdentification(p2.controller(), band=(20.0, 300.0)).fit(exps)
    f = np.geomspace(20.0, 300.0, 300)
    Gt, Gh = p2.plant().frequency_response(f), res.plant.frequency_response(f)
    rel = np.max(np.abs(Gh - Gt) / np.abs(Gt), axis=0)
    peak = np.max(np.abs(Gh - Gt), axis=0) / np.max(np.abs(Gt), axis=0)
    rhp = np.sort(np.asarray(res.plant_unstable_poles).real)
    pole = max(np.min(np.abs(rhp - a)) / a for a in p2.UNSTABLE)
    return np.diag(rel), max(peak[0, 1], peak[1, 0]), pole


def test_the_screens_orders_give_an_accurate_2x2_plant():
    diag, coupling, pole = _accuracy_2x2(80, 70.0)
    assert np.all(diag < 0.01), diag
    assert coupling < 0.05, coupling
    assert pole < 0.01, pole


def _reference_basis(A, B, tol):
    """The staircase as it was: one SVD and one ``hstack`` per block."""
    n = A.shape[0]
    Q, V = np.zeros((n, 0)), B
    while Q.shape[1] < n:
        for _ in range(2):
            V = V - Q @ (Q.T @ V)
        U, s, _ = np.linalg.svd(V, full_matrices=False)
        r = int(np.sum(s > tol))
        if r == 0:
            break
        Q = np.hstack([Q, U[:, :r]])
        V = A @ U[:, :r]
    return Q


@pytest.mark.parametrize("m", [1, 2])
@pytest.mark.parametrize("seed", range(6))
def test_controllable_basis_spans_the_reference_subspace(seed, m):
    rng = np.random.default_rng(seed)
    n, k = 14, 4 + seed  # the last k states are not reached from B
    A = rng.standard_normal((n, n)) / np.sqrt(n)
    A[n - k :, : n - k] = 0.0  # the reached block is invariant
    w = n - k - 1  # reached, but only weakly: the rank threshold decides it
    A[w, :w] = 0.0
    A[w, 0] = 1e-3
    B = np.zeros((n, m))
    B[:w] = rng.standard_normal((w, m))
    T = np.linalg.qr(rng.standard_normal((n, n)))[0]  # hide the structure
    A, B = T @ A @ T.T, T @ B
    want = _reference_basis(A, B / np.linalg.norm(B, 2), 1e-9)
    got = controllable_basis(A, B / np.linalg.norm(B, 2), 1e-9)
    assert got.shape == want.shape == (n, n - k)
    np.testing.assert_allclose(got.T @ got, np.eye(n - k), atol=1e-12)
    assert np.linalg.norm(got @ got.T - want @ want.T, 2) < 1e-9


def _plant_with_unobservable_entry(seed=3, n=16, p=2):
    rng = np.random.default_rng(seed)
    # upper triangular: state k is driven only by the states after it
    A = np.diag(np.linspace(0.2, 0.9, n)) + 0.05 * np.triu(rng.standard_normal((n, n)), 1)
    B, C = rng.standard_normal((n, p)), rng.standard_normal((p, n))
    B[n - 3 :, 1] = 0.0  # input 2 does not reach the last three states
    C[1, :3] = 0.0  # output 2 does not see the first three
    return StateSpaceModel(A, B, C, np.zeros((p, p)), 1e-3)


def _matched(got, want):
    """Largest distance from a root to the nearest root of the other set (both ways)."""
    d = np.abs(got[:, None] - want[None, :])
    return max(d.min(axis=1).max(), d.min(axis=0).max())


def test_shared_poles_are_the_minimal_realisations_poles_and_zeros():
    plant = _plant_with_unobservable_entry()
    split = cancellation.PlantEntries(plant, None)
    sizes = []
    for i in range(2):
        for j in range(2):
            g = split.minimal(i, j)
            sizes.append(g.n_states)
            got_p, got_z = split.poles_zeros(i, j)
            want_p, want_z = np.linalg.eigvals(g.A), g.zeros(minimal=False)
            assert got_p.size == want_p.size and got_z.size == want_z.size, (i, j)
            assert _matched(got_p, want_p) < 1e-9 and _matched(got_z, want_z) < 1e-7, (i, j)
    assert sizes == [16, 13, 13, 10]  # both routes of poles_zeros are taken
