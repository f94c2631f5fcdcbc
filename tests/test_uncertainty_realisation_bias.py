"""The realised Hankel-MAP bands: the realisation-misfit bias term (stageid.subspace.uncertainty.realisation_bias) and
the propagation to the model's response (stageid.subspace.uncertainty.response_std)."""

from __future__ import annotations

import numpy as np
import pytest

from _subspace_systems import band_limited, random_stage, record
from stageid.subspace import HankelMAP
from stageid.subspace.uncertainty import (
    TangentProjection,
    model_jacobian,
    realised_response_uncertainty,
    response_std,
)
from stageid.subspace.uncertainty.realisation_bias import local_misfit_bias, misfit_noise


def test_misfit_noise_is_the_mean_squared_residual_of_the_projection():
    # r = K Re(F dG) - dG for a complex Gaussian dG with a given cov and pseudo-covariance,
    # against 200 000 draws
    rng = np.random.default_rng(3)
    N, r, P = 6, 2, 3
    J = rng.standard_normal((N, 1, 1, P)) + 1j * rng.standard_normal((N, 1, 1, P))
    proj = TangentProjection.from_jacobian(J, np.ones((N, 1, 1)))
    M = rng.standard_normal((2 * N, 2 * N))
    S = M @ M.T  # covariance of [Re dG; Im dG]
    draws = rng.multivariate_normal(np.zeros(2 * N), S, size=200_000)
    dG = draws[:, :N] + 1j * draws[:, N:]
    cov = dG.T @ np.conj(dG) / dG.shape[0]
    pseudo = dG.T @ dG / dG.shape[0]
    K = J.reshape(N, P) @ proj.basis
    phi = np.real(dG @ proj.functionals.T)  # (draws, r)
    resid = phi @ K.T - dG
    want = np.mean(np.abs(resid) ** 2, axis=0)
    phi_cov, phi_dG = proj.moments(cov, pseudo)
    got = misfit_noise(K, phi_cov, phi_dG, np.real(np.diag(cov)))
    # the same sample moments on both sides: equal to rounding
    np.testing.assert_allclose(got, want, rtol=1e-9)
    assert r <= proj.basis.shape[1] <= P


def test_local_bias_only_where_the_misfit_exceeds_its_noise():
    grid = np.linspace(1.0, 100.0, 24)
    G = np.ones((24, 1, 2)) * (1.0 + 0.5j)
    noise = np.full((24, 1, 2), 1e-2)
    misfit = noise * 1.3  # the first entry: 1.3x its noise, within the noise's scatter over 24 points
    misfit[:, 0, 1] = 20.0 * noise[:, 0, 1]  # the second: 20x
    b2 = local_misfit_bias(grid, misfit, noise, G, np.linspace(1.0, 100.0, 50))
    assert np.all(b2[:, 0, 0] == 0.0)
    np.testing.assert_allclose(b2[:, 0, 1], 19.0 * 1e-2 / 1.25, rtol=1e-12)


def test_a_correct_model_gets_no_bias_term_and_an_order_too_low_one_does():
    g = random_stage(8, m=1, q=2, modes=2)
    exp = record(g, band_limited(6000, 1, g.dt, 0), 0.02, 0, names=False)
    f = np.geomspace(2.0, 95.0, 60)
    right = HankelMAP(horizon=25, order=4).fit(exp)
    none = realised_response_uncertainty(right, f, bias="none").std
    np.testing.assert_array_equal(realised_response_uncertainty(right, f, bias="local").std, none)
    low = HankelMAP(horizon=25, order=2).fit(exp)  # one of the two resonances only
    err = np.abs(low.model.frequency_response(f) - g.frequency_response(f))
    s0 = realised_response_uncertainty(low, f, bias="none").std
    s1 = realised_response_uncertainty(low, f, bias="local").std
    assert np.all(s1 >= s0)
    # the order-2 model's error is its bias: the scatter alone covers little of it, the bias term most
    assert np.mean(err <= 1.73 * s0) < 0.5
    assert np.mean(err <= 1.73 * s1) > np.mean(err <= 1.73 * s0) + 0.3


@pytest.mark.parametrize("feedthrough", [True, False])
def test_response_std_is_the_jacobian_times_the_factor(feedthrough):
    # J dx formed without J equals the explicit Jacobian's product, with and without D
    rng = np.random.default_rng(2)
    n, m, q = 5, 2, 3
    A = 0.3 * rng.standard_normal((n, n))
    B, C, D = rng.standard_normal((n, m)), rng.standard_normal((q, n)), rng.standard_normal((q, m))
    P = n * n + n * m + q * n + (q * m if feedthrough else 0)
    factor = rng.standard_normal((P, 7))
    x = np.exp(2j * np.pi * np.linspace(0.01, 0.45, 300))  # more than one CHUNK of points
    _, J = model_jacobian(A, B, C, D, x, feedthrough)
    dG = J.reshape(-1, P) @ factor
    want = np.sqrt(np.sum(np.abs(dG) ** 2, axis=1)).reshape(x.size, q, m)
    np.testing.assert_allclose(response_std((A, B, C, D), factor, x, feedthrough), want, rtol=1e-12)
