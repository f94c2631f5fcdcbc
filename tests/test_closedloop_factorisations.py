"""The cheaper factorisations of the closed-loop fits compute what the plain routes did.

* :func:`~stageid.closedloop.reduced_lsq.reduced_least_squares` hands SciPy's ``trf`` (no bounds,
  ``x_scale="jac"``) the QR-reduced problem: the same iterates as the full problem, to rounding;
* :func:`~stageid.closedloop.regression.lstsq_qr` (one QR of ``[Phi | Y]``, gelsd's rank rule
  on ``R``) gives :func:`~stageid.closedloop.regression.lstsq`'s solution and rank decisions;
* the shared balancing / controllable parts of the cancellation and the reduction's canonical
  form (:func:`~stageid.models.conversions.tf2ss_siso` with the states of a zero numerator kept)
  give the very numbers of the routes they replace.
"""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.signal as ss
from scipy.optimize import least_squares

from stageid._errors import IdentificationError
from stageid.closedloop import cancellation, deduction, regression
from stageid.closedloop.reduced_lsq import qr_reduce, reduced_least_squares
from stageid.models import StateSpaceModel, TransferMatrix, minimal_realization
from stageid.models.conversions import tf2ss_siso


def _exp_problem(seed=0, m=300):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 4, m)
    y = 2.5 * np.exp(-1.3 * t) + 0.7 * np.sin(3.1 * t) + 0.01 * rng.standard_normal(m)

    def fun(x):
        return x[0] * np.exp(-x[1] * t) + x[2] * np.sin(x[3] * t) - y

    def jac(x):
        return np.column_stack(
            [np.exp(-x[1] * t), -x[0] * t * np.exp(-x[1] * t), np.sin(x[3] * t), x[2] * t * np.cos(x[3] * t)]
        )

    return fun, jac, np.array([1.0, 0.5, 0.2, 2.8])


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("max_nfev", [3, 7, 200])
def test_reduced_problem_follows_scipy_trf(seed, max_nfev):
    fun, jac, x0 = _exp_problem(seed)
    ref = least_squares(
        fun, x0, jac=jac, method="trf", x_scale="jac", max_nfev=max_nfev, ftol=1e-12, xtol=1e-12, gtol=1e-12
    )
    got = reduced_least_squares(fun, jac, x0, max_nfev, ftol=1e-12, xtol=1e-12, gtol=1e-12)
    assert got.nfev == ref.nfev and got.status == ref.status
    assert np.allclose(got.x, ref.x, rtol=1e-9, atol=1e-12)
    assert np.isclose(np.linalg.norm(got.fun), np.linalg.norm(ref.fun), rtol=1e-9)


def test_qr_reduction_keeps_what_the_iteration_uses():
    fun, jac, x0 = _exp_problem()
    J, f = jac(x0), fun(x0)
    J_r, f_r, _ = qr_reduce(J, f)
    assert J_r.shape == (5, 4) and f_r.shape == (5,) and not np.any(f_r[:4])
    np.testing.assert_allclose(J_r.T @ J_r, J.T @ J, rtol=1e-12)
    np.testing.assert_allclose(J_r.T @ f_r, J.T @ f, rtol=1e-10)
    np.testing.assert_allclose(np.linalg.norm(f_r), np.linalg.norm(f), rtol=1e-13)
    np.testing.assert_allclose(np.linalg.norm(J_r, axis=0), np.linalg.norm(J, axis=0), rtol=1e-13)


@pytest.mark.parametrize("seed", range(3))
def test_qr_reduction_gives_the_gauss_newton_decrement(seed):
    fun, jac, x0 = _exp_problem(seed)
    x0 = x0 + 0.3 * np.random.default_rng(seed).standard_normal(4)
    J, f = jac(x0), fun(x0)
    p = np.linalg.lstsq(J, -f, rcond=None)[0]
    expected = 1.0 - np.sum((J @ p + f) ** 2) / np.sum(f**2)
    assert 0.01 < expected < 1.0  # away from the optimum: a decrement worth checking
    np.testing.assert_allclose(qr_reduce(J, f)[2], expected, rtol=1e-10)


@pytest.mark.parametrize("seed", range(3))
def test_decrement_stop_ends_where_little_is_left_to_gain(seed):
    fun, jac, x0 = _exp_problem(seed)
    full = reduced_least_squares(fun, jac, x0, 200)
    tol = 1e-4
    got = reduced_least_squares(fun, jac, x0, 200, decrement_tol=tol)
    assert got.status == 1 and got.nfev < full.nfev
    loss, loss_full = np.sum(fun(got.x) ** 2), np.sum(fun(full.x) ** 2)
    assert np.isclose(np.linalg.norm(got.fun), np.sqrt(loss), rtol=1e-12)
    assert loss_full <= loss <= loss_full * (1 + 10 * tol)
    # and where it stopped, the linearised problem offers less than the tolerance
    assert qr_reduce(jac(got.x), fun(got.x))[2] < tol


@pytest.mark.parametrize("x0", [(-1.2, 1.0), (-3.0, -2.0), (2.5, -1.0)])
@pytest.mark.parametrize("max_nfev", [5, 200])
def test_reduced_problem_follows_scipy_trf_through_rejected_steps(x0, max_nfev):
    # Rosenbrock from far away: steps are rejected, the radius shrinks and grows, alpha > 0
    # (six residuals: more than n + 1, so the QR route, not the square fallback, is taken)
    def fun(x):
        return np.array(
            [10 * (x[1] - x[0] ** 2), 1 - x[0], 0.1 * x[0] * x[1], 0.2 * (x[0] + x[1] - 1), 0.3, 0.1 * x[1]]
        )

    def jac(x):
        return np.array([[-20 * x[0], 10.0], [-1.0, 0.0], [0.1 * x[1], 0.1 * x[0]], [0.2, 0.2], [0.0, 0.0], [0.0, 0.1]])

    x0 = np.array(x0)
    ref = least_squares(fun, x0, jac=jac, method="trf", x_scale="jac", max_nfev=max_nfev, ftol=1e-12, xtol=1e-12)
    got = reduced_least_squares(fun, jac, x0, max_nfev, ftol=1e-12, xtol=1e-12, gtol=1e-8)
    assert got.nfev == ref.nfev and got.status == ref.status
    assert np.allclose(got.x, ref.x, rtol=1e-9, atol=1e-12)


def test_reduced_problem_refuses_a_non_finite_start():
    fun, jac, x0 = _exp_problem()
    with pytest.raises(ValueError, match="not finite"):
        reduced_least_squares(lambda x: fun(x) * np.nan, jac, x0, 10)


def _lstsq_qr(Phi, Y, strict=True):
    W = np.asfortranarray(np.column_stack([Phi, Y]))
    return regression.lstsq_qr(W, "test", strict=strict)


@pytest.mark.parametrize("seed", range(4))
def test_lstsq_qr_equals_lstsq_on_well_and_ill_conditioned_regressors(seed):
    rng = np.random.default_rng(seed)
    m, k = 2000, 12
    Phi = rng.standard_normal((m, k)) * 10.0 ** rng.uniform(-2, 2, k)
    Y = Phi @ rng.standard_normal(k) + 1e-3 * rng.standard_normal(m)
    assert np.allclose(_lstsq_qr(Phi, Y), regression.lstsq(Phi, Y, "test"), rtol=1e-10, atol=0)
    # columns over 12 decades: each coefficient to the rounding its column's share of Y allows,
    # the fitted values to rounding
    Phi = Phi * 10.0 ** rng.uniform(-4, 4, k)
    a, b = _lstsq_qr(Phi, Y), regression.lstsq(Phi, Y, "test")
    assert np.allclose(Phi @ a, Phi @ b, rtol=0, atol=1e-12 * np.abs(Y).max())
    col = np.linalg.norm(Phi, axis=0)
    assert np.all(np.abs(a - b) * col <= 1e-11 * np.linalg.norm(Y))
    # a column that repeats another up to 1e-14: both routes cut the same rank and agree on the
    # minimum-norm solution
    Phi[:, 3] = Phi[:, 1] * (1 + 1e-14 * rng.standard_normal(m))
    a, b = _lstsq_qr(Phi, Y, strict=False), regression.lstsq(Phi, Y, "test", strict=False)
    assert np.allclose(Phi @ a, Phi @ b, rtol=1e-9, atol=1e-9 * np.abs(Y).max())
    assert np.allclose(a, b, rtol=1e-6, atol=1e-9 * np.abs(b).max())
    for solve in (_lstsq_qr, lambda P, y: regression.lstsq(P, y, "test")):
        with pytest.raises(IdentificationError, match="rank deficient"):
            solve(Phi, Y)
    Phi[:, 5] = 0.0
    for solve in (_lstsq_qr, lambda P, y: regression.lstsq(P, y, "test")):
        with pytest.raises(IdentificationError, match="identically zero"):
            solve(Phi, Y)


def test_lstsq_qr_on_short_records_takes_the_plain_route():
    rng = np.random.default_rng(5)
    Phi, Y = rng.standard_normal((9, 6)), rng.standard_normal(9)
    assert np.array_equal(_lstsq_qr(Phi, Y), regression.lstsq(Phi, Y, "test"))


@pytest.mark.filterwarnings("ignore::scipy.signal.BadCoefficients")  # the tiny-leading-coefficient cases
def test_zoh_realisation_equals_scipy_tf2ss_zero_numerator_included():
    rng = np.random.default_rng(0)
    for k in range(600):
        nd = int(rng.integers(2, 6))
        nn = int(rng.integers(1, nd + 1))
        den = rng.standard_normal(nd) * 10 ** rng.uniform(-3, 6, nd)
        num = rng.standard_normal(nn) * 10 ** rng.uniform(-3, 6, nn)
        if k % 5 == 0:
            num[0] = 0.0
        if k % 7 == 0:
            num[:] = 0.0  # scipy keeps the denominator's states with C = 0
        for x, y in zip(ss.tf2ss(num, den), tf2ss_siso(num, den, keep_states=True), strict=True):
            assert x.shape == y.shape and np.array_equal(x, y)


def _plant(seed=3, n=24, p=2):
    rng = np.random.default_rng(seed)
    A = np.diag(rng.uniform(0.5, 0.97, n)) + 0.02 * rng.standard_normal((n, n))
    B, C = rng.standard_normal((n, p)), rng.standard_normal((p, n))
    B[:4, 1] = 0.0  # input 2 leaves some states uncontrollable
    return StateSpaceModel(A, B, C, np.zeros((p, p)), 1e-3)


def test_shared_entry_realisations_equal_the_entry_by_entry_minimal_realisation():
    plant = _plant()
    split = cancellation.PlantEntries(plant, None)
    A, T = sla.matrix_balance(plant.A, permute=False, separate=False)
    t = T.diagonal()
    for i in range(2):
        for j in range(2):
            b, c = plant.B[:, [j]] / t[:, None], plant.C[[i]] * t[None, :]
            nb, nc = np.linalg.norm(b), np.linalg.norm(c)
            g = StateSpaceModel(A, b / nb, c / nc, plant.D[[i]][:, [j]] / (nb * nc), plant.dt)
            want = minimal_realization(g, 1e-8 * max(1.0, np.linalg.norm(g.A, 2)))
            got = split.minimal(i, j)
            for name in "ABCD":
                assert np.array_equal(getattr(got, name), getattr(want, name)), (i, j, name)


def test_wide_response_is_eq18_and_falls_back_where_it_is_singular():
    f = np.geomspace(1.0, 200.0, 40)
    T = TransferMatrix([[[0.2, 0.1]]], [[[1.0, -0.6, 0.1]]], 1e-3)
    M = TransferMatrix([[[2.0, -1.0]]], [[[1.0, -0.2]]], 1e-3)
    G_full = deduction.deduce_plant(T, M)
    got = deduction.wide_response(T, M, None, G_full)(f)
    assert np.array_equal(got, deduction.plant_response(T, M, None, f))
    # a controller zero on the unit circle at 100 Hz makes eq. 18 singular there
    zc = np.exp(2j * np.pi * 100.0 * 1e-3)
    Mz = TransferMatrix([[np.real(np.poly([zc, np.conj(zc)]))]], [[np.array([1.0, 0.0, 0.0])]], 1e-3)
    fz = np.array([50.0, 100.0, 150.0])
    with pytest.raises(IdentificationError):
        deduction.plant_response(T, Mz, None, fz)
    Gz = deduction.deduce_plant(T, Mz)
    assert np.array_equal(deduction.wide_response(T, Mz, None, Gz)(fz), Gz.frequency_response(fz))
