"""The faster regressor/Jacobian construction of closedloop.pem computes what the plain one did.

The preallocated regressors must equal the ``np.hstack``/``np.vstack`` of shifted copies they
replace (bit for bit, including the sign of the leading zeros), the Jacobian must be the
derivative of the residual, the Steiglitz-McBride start continued from a saved ``F`` must
equal the uninterrupted one, and the screened order selection must return exactly the model
``fit_pem`` gives for the selected order from the screen's state.
"""

import numpy as np
import pytest
import scipy.signal as ss

from stageid.closedloop import initial, order_selection, polynomial, regression
from stageid.closedloop.pem import fit_pem, jacobian, pem


def _reference_shifted(x, lags, start):
    n = x.size
    out = np.zeros((n, lags))
    for k in range(lags):
        s = start + k
        if s < n:
            out[s:, k] = x[: n - s]
    return out


def _records(seed=0, lengths=(400, 650, 530), noise=0.02):
    rng = np.random.default_rng(seed)
    us = [rng.standard_normal(n) for n in lengths]
    ys = [ss.lfilter([0, 0.3, 0.1], [1, -1.2, 0.5], u) + noise * rng.standard_normal(u.size) for u in us]
    return us, ys


@pytest.mark.parametrize("lags", [0, 1, 3, 12])
@pytest.mark.parametrize("start", [0, 1, 4, 11, 12, 30])
def test_shifted_and_regressor_equal_the_stacked_copies(lags, start):
    rng = np.random.default_rng(lags * 31 + start)
    a, b = rng.standard_normal(12), rng.standard_normal(12)
    c, d = rng.standard_normal(7), rng.standard_normal(7)
    assert np.array_equal(regression.shifted(a, lags, start), _reference_shifted(a, lags, start))
    got = regression.regressor(
        [[(a, lags, start, True), (b, 2, 1, False)], [(c, lags, start, True), (d, 2, 1, False)]], 19
    )
    want = np.vstack(
        [
            np.hstack([-_reference_shifted(a, lags, start), _reference_shifted(b, 2, 1)]),
            np.hstack([-_reference_shifted(c, lags, start), _reference_shifted(d, 2, 1)]),
        ]
    )
    assert got.shape == want.shape
    assert np.array_equal(got, want)
    assert np.array_equal(np.signbit(got), np.signbit(want))


@pytest.mark.parametrize(
    "structure,orders",
    [
        ("oe", {"nb": 2, "nf": 2}),
        ("bj", {"nb": 2, "nf": 2, "nc": 1, "nd": 2}),
        ("armax", {"na": 2, "nb": 2, "nc": 1}),
    ],
)
def test_jacobian_is_the_derivative_of_the_residual(structure, orders):
    us, ys = _records()
    full = polynomial.check_orders(structure, orders, 1)
    rng = np.random.default_rng(3)
    theta = 0.1 * rng.standard_normal(sum(full.values()))
    A, B, C, D, F = polynomial.unpack(theta, full)
    u, y = us[0], ys[0]
    J = jacobian(A, B, C, D, F, 1, full, u, y)
    parts = polynomial.residual_parts(A, B, C, D, F, 1, u, y)
    J_cached = jacobian(A, B, C, D, F, 1, full, u, y, parts=parts, out=np.full(J.shape, np.nan))
    assert np.array_equal(J, J_cached)
    h = 1e-6
    for k in range(theta.size):
        tp, tm = theta.copy(), theta.copy()
        tp[k] += h
        tm[k] -= h
        fd = (
            polynomial.residual(*polynomial.unpack(tp, full), 1, u, y)
            - polynomial.residual(*polynomial.unpack(tm, full), 1, u, y)
        ) / (2 * h)
        assert np.max(np.abs(J[:, k] - fd)) <= 1e-6 * max(1.0, np.max(np.abs(fd))), k


def test_steiglitz_mcbride_continued_from_a_saved_F_equals_the_full_run():
    us, ys = _records()
    segs = regression.records(us, ys)
    B8, F8 = initial.steiglitz_mcbride(segs, 3, 3, 1, n_iter=8)
    _, F6 = initial.steiglitz_mcbride(segs, 3, 3, 1, n_iter=6)
    B, F = initial.steiglitz_mcbride(segs, 3, 3, 1, n_iter=2, F0=F6)
    assert np.array_equal(B, B8) and np.array_equal(F, F8)
    # and the continuation is not a no-op: two more iterations move F away from F6 here
    assert not np.array_equal(F6, F8)


@pytest.mark.parametrize("structure", ["oe", "bj"])
def test_screened_selection_returns_the_pem_model_of_the_selected_order(structure):
    # the winner's PEM starts from the screen's estimate of its order (continued by its own passes)
    us, ys = _records(seed=4, noise=0.05)
    m, scores = order_selection.select_order(us, ys, structure, orders=[1, 2, 3, 4, 5])
    n = m.F.size - 1
    o = {"nb": n, "nf": n} if structure == "oe" else {"nb": n, "nf": n, "nc": 2, "nd": 2}
    screen, states = order_selection.screen_orders(regression.records(us, ys), [1, 2, 3, 4, 5], 1, "bic")
    assert n == min(screen, key=screen.get)
    ref = fit_pem(us, ys, structure, o, 1, 1.0, 200, None, states[n])
    assert list(scores) == [n]
    for name in "ABCDF":
        assert np.array_equal(getattr(m, name), getattr(ref, name)), name
    assert m.loss == ref.loss and m.n_iterations == ref.n_iterations


def test_pem_does_not_modify_the_callers_records():
    us, ys = _records()
    copies = [a.copy() for a in us + ys]
    order_selection.select_order(us, ys, "oe", orders=[1, 2, 3, 4])
    pem(us, ys, "bj", {"nb": 2, "nf": 2, "nc": 1, "nd": 1})
    assert all(np.array_equal(a, b) for a, b in zip(us + ys, copies))
