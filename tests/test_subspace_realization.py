"""Reconstruction of the system matrices: eq. 10-15 and the frequency-domain realisation."""

import numpy as np
import pytest

from _subspace_systems import random_stage, record
from stageid._errors import IdentificationError
from stageid.models import StateSpaceModel
from stageid.subspace.map.posterior import batch_posterior
from stageid.subspace.realisation.era import (
    era,
    hankel_h0,
    hankel_hi,
    hankel_matrices,
    markov_from_theta,
)
from stageid.subspace.realisation.frequency_domain import balanced_start, balanced_truncation, frequency_realization
from stageid.subspace.realisation.refinement import refine_frequency_fit
from stageid.subspace.statistics.hankel_toeplitz import window_statistics


def _exact_theta(g, p, n=2500, seed=0):
    u = np.random.default_rng(seed).standard_normal((n, g.n_inputs))
    exp = record(g, u, 0.0, seed)
    return batch_posterior(window_statistics(exp.u, exp.y, p), None).theta


def test_markov_parameters_from_eq_10_to_12_match_the_system():
    # a well damped system (|pole| <= 0.9) so that Phi is a deadbeat-like observer for p = 6
    rng = np.random.default_rng(2)
    A = np.diag([0.9, -0.5, 0.3]) + 0.05 * rng.standard_normal((3, 3))
    g = StateSpaceModel(A, rng.standard_normal((3, 2)), rng.standard_normal((2, 3)), np.zeros((2, 2)), dt=0.01)
    p = 6
    theta = _exact_theta(g, p)
    Y = markov_from_theta(theta, p, 2, 2, 4 * p)
    np.testing.assert_allclose(Y, g.markov_parameters(4 * p), atol=1e-8)
    # H0 = C_p B_p: block (i, j) = Y_(p + i - j) (B_p ordered A^(p-1) B ... B, eq. 4)
    H0 = hankel_h0(theta, p, 2, 2)
    Yt = g.markov_parameters(3 * p)
    for i in range(p):
        for j in range(p):
            np.testing.assert_allclose(H0[2 * i : 2 * i + 2, 2 * j : 2 * j + 2], Yt[p + i - j], atol=1e-8)
    H2 = hankel_hi(theta, p, 2, 2, 2)
    np.testing.assert_allclose(H2[:2, :2], g.markov_parameters(3 * p + 1)[3 * p], atol=1e-8)


def test_lemma_1_recovers_poles_and_response_from_exact_markov_parameters():
    g = random_stage(0, m=2, q=3, modes=3)
    Y = g.markov_parameters(80)
    A, B, C, D, s = era(Y, g.n_states, n1=20, n2=20)
    est = StateSpaceModel(A, B, C, D, g.dt)
    np.testing.assert_allclose(np.sort_complex(est.poles()), np.sort_complex(g.poles()), atol=1e-8)
    f = np.linspace(1, 200, 50)
    np.testing.assert_allclose(
        est.frequency_response(f), g.frequency_response(f), atol=1e-8 * np.abs(g.frequency_response(f)).max()
    )
    H0, H1 = hankel_matrices(Y, 3, 2)
    assert H0.shape == (9, 8) and np.allclose(H1[:3, :2], Y[2])
    with pytest.raises(IdentificationError, match="Lemma 1 needs"):
        era(Y, 100, n1=3, n2=3)


@pytest.mark.parametrize("f_high", [100.0, 250.0])
def test_frequency_realization_is_exact_on_a_partial_band(f_high):
    g = random_stage(1, m=2, q=2, modes=3)
    f = np.linspace(1.0, f_high, 300)
    G = g.frequency_response(f)
    A, B, C, D, _ = frequency_realization(G, f, g.dt, g.n_states, feedthrough=False)
    est = StateSpaceModel(A, B, C, D, g.dt)
    np.testing.assert_allclose(np.sort_complex(est.poles()), np.sort_complex(g.poles()), atol=1e-7)
    ff = np.linspace(1.0, f_high, 977)
    scale = np.abs(g.frequency_response(ff)).max()
    np.testing.assert_allclose(est.frequency_response(ff), g.frequency_response(ff), atol=1e-7 * scale)


def test_refinement_never_increases_the_cost_and_recovers_a_perturbed_model():
    g = random_stage(4, m=1, q=2, modes=2)
    f = np.linspace(1.0, 100.0, 200)
    zs = np.exp(2j * np.pi * f * g.dt)
    G = g.frequency_response(f)
    rng = np.random.default_rng(0)
    A0 = g.A + 1e-3 * rng.standard_normal(g.A.shape)
    B0 = g.B * (1 + 0.05 * rng.standard_normal(g.B.shape))
    A, B, C, D, info = refine_frequency_fit(A0, B0, g.C, g.D, G, zs, feedthrough=False)
    assert info["cost"] <= info["cost0"]
    est = StateSpaceModel(A, B, C, D, g.dt)
    # from a start ~5 % off, the output-error fit lands on the truth (noise-free data)
    assert np.abs(est.frequency_response(f) - G).max() < 1e-4 * np.abs(G).max()


@pytest.mark.parametrize(
    "feedthrough, n, q, m",
    [
        (True, 4, 3, 2),
        (False, 4, 3, 2),
        (False, 1, 3, 2),
        (True, 1, 1, 1),
        (True, 2, 1, 3),
        (False, 15, 3, 3),
        (True, 7, 2, 1),
    ],
)
def test_structured_normal_equations_equal_the_explicit_jacobian(feedthrough, n, q, m):
    from stageid.subspace.realisation.refinement import _normal_equations

    nz = 40
    rng = np.random.default_rng(1)
    a = rng.standard_normal((nz, q, n)) + 1j * rng.standard_normal((nz, q, n))
    b = rng.standard_normal((nz, n, m)) + 1j * rng.standard_normal((nz, n, m))
    e = rng.standard_normal((nz, q, m)) + 1j * rng.standard_normal((nz, q, m))
    w = rng.random(nz)
    JA = np.einsum("zqi,zjm->zqmij", a, b).reshape(nz, q, m, n * n)
    JB = np.einsum("zqi,jm->zqmij", a, np.eye(m)).reshape(nz, q, m, n * m)
    JC = np.einsum("qi,zjm->zqmij", np.eye(q), b).reshape(nz, q, m, q * n)
    JD = np.broadcast_to(np.einsum("qi,mj->qmij", np.eye(q), np.eye(m)).reshape(1, q, m, q * m), (nz, q, m, q * m))
    J = np.concatenate([JA, JB, JC] + ([JD] if feedthrough else []), axis=3) * np.sqrt(w)[:, None, None, None]
    J = J.reshape(nz * q * m, -1)
    r = (e * np.sqrt(w)[:, None, None]).reshape(-1)
    M, g = _normal_equations(a, b, e, w, feedthrough)
    np.testing.assert_allclose(M, (J.conj().T @ J).real, atol=1e-12 * np.abs(M).max())
    np.testing.assert_allclose(g, (J.conj().T @ r).real, atol=1e-12 * np.abs(g).max())


def test_discrete_gramian_solves_the_stein_equation():
    from stageid.subspace.realisation.frequency_domain import _discrete_gramian

    rng = np.random.default_rng(3)
    A = rng.standard_normal((6, 6))
    A *= 0.995 / np.max(np.abs(np.linalg.eigvals(A)))  # slow: ~13 doublings
    Q = rng.standard_normal((6, 2))
    Q = Q @ Q.T
    X = _discrete_gramian(A, Q)
    # against the Kronecker form (I - A (x) A) vec(X) = vec(Q)
    direct = np.linalg.solve(np.eye(36) - np.kron(A, A), Q.ravel()).reshape(6, 6)
    np.testing.assert_allclose(X, direct, rtol=0, atol=1e-9 * np.abs(direct).max())
    assert _discrete_gramian(np.diag([1.01, 0.5]), np.eye(2)) is None


def test_balanced_truncation_keeps_the_error_within_twice_the_discarded_hankel_values():
    g = random_stage(5, m=2, q=2, modes=4)  # 8 states, lightly damped
    f = np.linspace(0.0, 250.0, 2001)
    G = g.frequency_response(f)
    full = balanced_truncation(g.A, g.B, g.C, g.n_states)
    assert full is not None
    Af, Bf, Cf, hsv = full
    # all states kept: the same system in balanced coordinates
    np.testing.assert_allclose(
        StateSpaceModel(Af, Bf, Cf, g.D, g.dt).frequency_response(f), G, atol=1e-8 * np.abs(G).max()
    )
    for r in (2, 4, 6):
        Ar, Br, Cr, _ = balanced_truncation(g.A, g.B, g.C, r)
        Gr = StateSpaceModel(Ar, Br, Cr, g.D, g.dt).frequency_response(f)
        worst = np.max(np.linalg.norm(Gr - G, ord=2, axis=(1, 2)))  # largest singular value per frequency
        assert worst <= 2.0 * hsv[r:].sum() * (1 + 1e-6)
        assert np.max(np.abs(np.linalg.eigvals(Ar))) < 1.0
    assert balanced_truncation(np.diag([1.2, 0.3]), np.ones((2, 1)), np.ones((1, 2)), 1) is None


def test_balanced_start_recovers_an_exact_response():
    g = random_stage(6, m=2, q=2, modes=3)
    f = np.linspace(0.0, 250.0, 200)
    G = g.frequency_response(f)
    start = balanced_start(G, f, g.dt, g.n_states, feedthrough=False)
    assert start is not None
    est = StateSpaceModel(*start, g.dt)
    np.testing.assert_allclose(np.sort_complex(est.poles()), np.sort_complex(g.poles()), atol=1e-6)
    np.testing.assert_allclose(est.frequency_response(f), G, atol=1e-6 * np.abs(G).max())
    # too few frequencies for twice the order: no start
    assert balanced_start(G[:8], f[:8], g.dt, g.n_states, feedthrough=False) is None


def test_observability_basis_spans_the_lq_subspace():
    from stageid.subspace.realisation.frequency_domain import _observability_basis

    rng = np.random.default_rng(7)
    nf, q, m, r = 40, 2, 3, 5
    zs = np.exp(1j * np.linspace(0.05, 3.0, nf))
    G = rng.standard_normal((nf, q, m)) + 1j * rng.standard_normal((nf, q, m))
    Us, s = _observability_basis(G, zs, r)
    # reference: LQ factorisation of the stacked real data [U; Y] (McKelvey et al. 1996)
    powers = zs[None, :] ** np.arange(r)[:, None]
    Y = (powers[:, :, None, None] * G[None]).transpose(0, 2, 1, 3).reshape(r * q, nf * m)
    U = np.einsum("rk,ij->rikj", powers, np.eye(m)).reshape(r * m, nf * m)
    big = np.vstack([np.hstack([U.real, U.imag]), np.hstack([Y.real, Y.imag])])
    L = np.linalg.qr(big.T, mode="r").T
    U2, s2, _ = np.linalg.svd(L[r * m :, r * m :], full_matrices=False)
    np.testing.assert_allclose(s, s2, rtol=1e-10, atol=1e-12 * s2[0])
    for k in range(r * q):  # the same singular vectors up to sign
        assert abs(abs(Us[:, k] @ U2[:, k]) - 1.0) < 1e-8


def test_balanced_start_gives_none_when_the_truncation_fails(monkeypatch):
    from stageid.subspace.realisation import frequency_domain

    g = random_stage(6, m=2, q=2, modes=3)
    f = np.linspace(0.0, 250.0, 200)

    def broken(*args, **kwargs):
        raise np.linalg.LinAlgError("SVD did not converge")

    monkeypatch.setattr(frequency_domain, "balanced_truncation", broken)
    assert balanced_start(g.frequency_response(f), f, g.dt, g.n_states, feedthrough=False) is None


def _random_realisation(rng, n, m, q, nz):
    A = rng.standard_normal((n, n))
    A *= 0.95 / np.max(np.abs(np.linalg.eigvals(A)))
    B, C, D = rng.standard_normal((n, m)), rng.standard_normal((q, n)), rng.standard_normal((q, m))
    zs = np.exp(1j * np.sort(rng.uniform(0.0, np.pi, nz)))
    return A, B, C, D, zs


@pytest.mark.parametrize("n, m, q", [(1, 1, 1), (4, 2, 3), (15, 3, 3), (30, 3, 3), (6, 1, 2)])
def test_model_response_and_resolvent_rows_equal_direct_solves(n, m, q):
    # reference: (zI - A)^-1 by a linear solve at every z (the product forms use A's eigenvectors)
    from stageid.subspace.realisation.frequency_domain import _resolvent_rows
    from stageid.subspace.realisation.refinement import fit_cost, model_response

    rng = np.random.default_rng(n + 10 * m + 100 * q)
    A, B, C, D, zs = _random_realisation(rng, n, m, q, 50)
    R = np.stack([np.linalg.inv(z * np.eye(n) - A) for z in zs])
    eig, G, CR, RB = model_response((A, B, C, D), zs)
    np.testing.assert_allclose(eig[0], np.linalg.eig(A)[0], rtol=0, atol=0)
    for got, expected in ((G, C @ R @ B + D), (CR, C @ R), (RB, R @ B), (_resolvent_rows(A, C, zs), C @ R)):
        assert got.shape == expected.shape and got.flags.c_contiguous
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-11 * np.abs(expected).max())
    target = C @ R @ B + D + 0.01 * rng.standard_normal((zs.size, q, m))
    assert fit_cost((A, B, C, D), target, zs) == pytest.approx(np.sum(np.abs(C @ R @ B + D - target) ** 2), rel=1e-10)


def test_refinement_from_a_given_start_response_is_the_same_refinement():
    from stageid.subspace.realisation.refinement import fit_cost, model_response

    rng = np.random.default_rng(4)
    A, B, C, D, zs = _random_realisation(rng, 5, 2, 2, 60)
    target = np.stack([C @ np.linalg.solve(z * np.eye(5) - A, B) + D for z in zs])
    start = (A + 0.02 * rng.standard_normal((5, 5)), B, C, D)
    response = model_response(start, zs)
    assert fit_cost(start, target, zs, response) == fit_cost(start, target, zs)
    plain = refine_frequency_fit(*start, target, zs, max_iter=4)
    shared = refine_frequency_fit(*start, target, zs, max_iter=4, response=response)
    for x, y in zip(plain[:4], shared[:4]):
        np.testing.assert_array_equal(x, y)
    assert plain[4] == shared[4] and plain[4]["cost"] < plain[4]["cost0"]
    assert model_response((np.full((2, 2), np.nan), B[:2], C[:, :2], D), zs) is None
    assert fit_cost((np.full((2, 2), np.nan), B[:2], C[:, :2], D), target, zs) == float("inf")


@pytest.mark.parametrize("feedthrough, weighted", [(False, False), (True, False), (True, True)])
def test_fit_input_matrices_equal_the_least_squares_solution(feedthrough, weighted):
    # reference: lstsq on the stacked real and imaginary parts of C (zI - A)^-1 [B] + [D] = G
    from stageid.subspace.realisation.frequency_domain import fit_input_matrices

    rng = np.random.default_rng(11)
    n, m, q, nz = 6, 2, 3, 40
    A, B, C, D, zs = _random_realisation(rng, n, m, q, nz)
    G = rng.standard_normal((nz, q, m)) + 1j * rng.standard_normal((nz, q, m))
    w = rng.uniform(0.2, 2.0, nz) if weighted else np.ones(nz)
    # the second case: a decoupled state that C does not see, so the problem is rank deficient
    A2, C2 = A.copy(), C.copy()
    A2[-1, :], A2[:, -1], A2[-1, -1], C2[:, -1] = 0.0, 0.0, 0.5, 0.0

    def reference(A, C):
        R = np.stack([C @ np.linalg.inv(z * np.eye(n) - A) for z in zs])
        M = np.concatenate([R] + ([np.broadcast_to(np.eye(q), (nz, q, q))] if feedthrough else []), axis=2)
        M = M.reshape(nz * q, -1) * np.repeat(np.sqrt(w), q)[:, None]
        rhs = G.reshape(nz * q, m) * np.repeat(np.sqrt(w), q)[:, None]
        return np.linalg.lstsq(np.vstack([M.real, M.imag]), np.vstack([rhs.real, rhs.imag]), rcond=None)[0]

    for Ax, Cx in ((A, C), (A2, C2)):
        Bf, Df = fit_input_matrices(Ax, Cx, G, zs, feedthrough, w if weighted else None)
        expected = reference(Ax, Cx)
        scale = np.abs(expected).max()
        np.testing.assert_allclose(Bf, expected[:n], rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(Df, expected[n:] if feedthrough else 0.0, rtol=0, atol=1e-10 * scale)
