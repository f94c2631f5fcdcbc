"""Closed-loop uncertainty: PEM parameter covariance and its propagation to the plant."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.signal as ss

from stageid._errors import DataError, IdentificationError, ParameterError
from stageid.closedloop import ClosedLoopIdentification, deduce_response, pem, reduce_entry, unstable_plant_poles
from stageid.closedloop.cancellation import z_to_s
from stageid.closedloop.covariance import model_orders, pem_covariance, transfer_gradient
from stageid.closedloop.polynomial import pack, unpack
from stageid.closedloop.uncertainty import (
    SIGNIFICANCE,
    deduced_variance,
    deduction_sensitivity,
    plant_uncertainty,
    significant_share,
    unstable_pole_sensitivity,
)
from stageid.models import TransferMatrix
from stageid.models.frequency_response import FrequencyResponse

sys.path.insert(0, str(Path(__file__).parent))
from test_closedloop_estimator import G_SISO, _siso_controller, _siso_experiment  # noqa: E402


def _oe_draws(n_seeds: int, colour: list[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Parameters of an OE fit over seeds, and the mean predicted variances (white, sandwich)."""
    thetas, white, sandwich = [], [], []
    for seed in range(n_seeds):
        rng = np.random.default_rng(seed)
        u = rng.standard_normal(3000)
        y = ss.lfilter([0, 0.3, 0.1], [1, -1.2, 0.5], u) + 0.3 * ss.lfilter(colour, [1.0], rng.standard_normal(3000))
        m = pem(u, y, "oe", {"nb": 2, "nf": 2})
        thetas.append(pack(m.A, m.B, m.C, m.D, m.F))
        white.append(np.diag(pem_covariance(m, [u], [y], "white")))
        sandwich.append(np.diag(pem_covariance(m, [u], [y], "sandwich")))
    return np.array(thetas), np.mean(white, axis=0), np.mean(sandwich, axis=0)


def test_pem_covariance_matches_the_scatter_over_seeds() -> None:
    # coloured (high-pass) noise, as an output-error fit in closed loop sees it
    thetas, white, sandwich = _oe_draws(60, [1.0, -0.9])
    ratio = np.sqrt(sandwich) / thetas.std(axis=0)
    # 60 seeds estimate a std to about +-10 %; the lag window adds up to ~20 % (measured 1.07-1.24)
    assert np.all((ratio > 0.75) & (ratio < 1.4)), ratio
    # the white formula is visibly off on coloured noise (measured up to 2x): the sandwich matters
    assert np.max(np.sqrt(white) / thetas.std(axis=0)) > 1.5


def test_white_and_sandwich_agree_on_white_noise() -> None:
    thetas, white, sandwich = _oe_draws(40, [1.0])
    assert np.allclose(np.sqrt(sandwich), np.sqrt(white), rtol=0.1)  # the lag window only adds scatter
    ratio = np.sqrt(white) / thetas.std(axis=0)
    assert np.all((ratio > 0.75) & (ratio < 1.3)), ratio


def test_transfer_gradient_matches_finite_differences() -> None:
    rng = np.random.default_rng(3)
    u = rng.standard_normal(2000)
    y = ss.lfilter([0, 0.3, 0.1], [1, -1.2, 0.5], u) + 0.01 * rng.standard_normal(2000)
    m = pem(u, y, "armax", {"na": 2, "nb": 2, "nc": 1})
    f = np.array([10.0, 100.0, 400.0])
    m = type(m)(m.A, m.B, m.C, m.D, m.F, m.nk, 1e-3, m.structure)
    g = transfer_gradient(m, f)
    theta = pack(m.A, m.B, m.C, m.D, m.F)
    h = 1e-7
    for k in range(theta.size):
        t = theta.copy()
        t[k] += h
        A = np.concatenate([[1.0], t[:2]])
        B = t[2:4]
        C = np.concatenate([[1.0], t[4:5]])
        mk = type(m)(A, B, C, m.D, m.F, m.nk, 1e-3, m.structure)
        fd = (mk.frequency_response(f) - m.frequency_response(f)) / h
        assert np.allclose(g[:, k], fd, rtol=1e-5, atol=1e-6)


def test_response_uncertainty_is_a_frequency_response_of_the_plant() -> None:
    res = ClosedLoopIdentification(_siso_controller(), order_range=range(2, 9)).fit(_siso_experiment(0, 60.0))
    f = np.geomspace(10.0, 500.0, 50)
    fr = res.response_uncertainty(f)
    assert isinstance(fr, FrequencyResponse)
    assert fr.inputs == res.plant.inputs and fr.outputs == res.plant.outputs
    assert np.allclose(fr.response, res.plant.frequency_response(f))
    assert fr.std.shape == (50, 1, 1) and np.all(fr.std > 0)
    # at 60 dB the relative std sits well below the paper's 1 % band error and above rounding
    rel = fr.std[:, 0, 0] / np.abs(fr.response[:, 0, 0])
    assert np.all((rel > 1e-7) & (rel < 0.01))


def test_response_uncertainty_refuses_bad_grids_and_missing_covariance() -> None:
    exp = _siso_experiment(1, 60.0)
    res = ClosedLoopIdentification(_siso_controller(), order_range=range(2, 6)).fit(exp)
    for bad in ([], [0.0, 10.0], [10.0, 5.0], [np.nan]):
        with pytest.raises(DataError, match="freqs_hz"):
            res.response_uncertainty(bad)
    none = ClosedLoopIdentification(_siso_controller(), order_range=range(2, 6), covariance="none").fit(exp)
    assert none.covariance is None
    with pytest.raises(IdentificationError, match="covariance"):
        none.response_uncertainty([10.0])
    with pytest.raises(ParameterError, match="covariance"):
        ClosedLoopIdentification(_siso_controller(), covariance="bootstrap").fit(exp)


@pytest.mark.study
@pytest.mark.slow
def test_siso_bands_are_calibrated_over_seeds() -> None:
    """20 noise seeds of an unstable SISO loop: the 1.73-std band covers 85-99 %.

    Measured 97.9 %, mean E|err|^2/std^2 0.56; counting the misfit's whole excess over its noise
    expectation as bias (no significance quantile) covered 100 % with 0.42.
    """
    f = np.geomspace(20.0, 300.0, 60)
    Gt = G_SISO.frequency_response(f)[:, 0, 0]
    hits, z2 = [], []
    for seed in range(20):
        res = ClosedLoopIdentification(_siso_controller(), order_range=range(2, 9)).fit(_siso_experiment(seed, 60.0))
        fr = res.response_uncertainty(f)
        e, s = np.abs(fr.response[:, 0, 0] - Gt), fr.std[:, 0, 0]
        hits.append(e <= 1.73 * s)
        z2.append(e**2 / s**2)
    coverage = np.mean(hits)
    assert 0.85 <= coverage <= 0.99, coverage
    # E|err|^2 / std^2 is 1 when calibrated: a std 3x off moves it by 9x
    assert 1 / 3 < np.mean(z2) < 3, np.mean(z2)


def test_noise_alone_passes_the_significance_quantile_at_its_rate() -> None:
    """The misfit under the noise alone is ``sum_k lambda_k chi2_1``: its excess counts as bias
    only as often as the quantile says (Satterthwaite's approximation of the quantile)."""
    lam = np.array([3.0, 1.0, 0.5, 0.1])  # few effective degrees of freedom (2.4), as on the SISO loop
    rng = np.random.default_rng(5)
    misfit = (lam * rng.standard_normal((20000, lam.size)) ** 2).sum(axis=1)
    share = significant_share(misfit, np.full(misfit.shape, lam.sum()), np.full(misfit.shape, np.sum(lam**2)))
    assert np.all((share >= 0) & (share <= 1))
    # the chance excess is common and large: 35 % of the draws exceed the mean, 20 % by half of it
    assert np.mean(misfit - lam.sum() > 0.5 * lam.sum()) > 0.15
    assert abs(np.mean(share > 0) - (1 - SIGNIFICANCE)) < 0.015  # measured 0.046
    # a bias far beyond the noise keeps (nearly) all of its excess; none below the mean
    big = significant_share(np.array([1000.0, 2.0]), np.array([4.6, 4.6]), np.array([11.26, 11.26]))
    assert big[0] > 0.98 and big[1] == 0.0


@pytest.fixture(scope="module")
def siso_result():
    return ClosedLoopIdentification(_siso_controller(), order_range=range(2, 9)).fit(_siso_experiment(0, 60.0))


def _with_parameters(model, theta):
    A, B, C, D, F = unpack(theta, model_orders(model))
    return dataclasses.replace(model, A=A, B=B, C=C, D=D, F=F)


def test_unstable_pole_sensitivity_matches_finite_differences(siso_result) -> None:
    res = siso_result
    m = res.pem_models[(0, 0)]
    theta = pack(m.A, m.B, m.C, m.D, m.F)
    sens = unstable_pole_sensitivity(res)
    k = int(np.argmin(np.abs(res.unstable_poles - 50.0)))

    def pole(t):
        num, den = _with_parameters(m, t).plant_polynomials()
        T = TransferMatrix([[num]], [[den]], m.dt, res.closed_loop.inputs, res.closed_loop.outputs)
        s = z_to_s(unstable_plant_poles(T, res.controller), m.dt)
        return s[np.argmin(np.abs(s - res.unstable_poles[k]))].real

    d = np.random.default_rng(0).standard_normal(theta.size) * 1e-10 * np.abs(theta).max()
    fd = (pole(theta + d) - pole(theta - d)) / 2
    # the pole is very sensitive to single coefficients (1e-9 already leaves the linear range)
    assert np.isclose(sens[k][(0, 0)] @ d, fd, rtol=0.05)


def test_deduced_variance_matches_sampling_the_covariance(siso_result) -> None:
    """Steps 1-2 (delta method through eq. 18) against draws of the parameters pushed through eq. 18."""
    res = siso_result
    m = res.pem_models[(0, 0)]
    C = res.covariance.covariances[(0, 0)]
    theta = pack(m.A, m.B, m.C, m.D, m.F)
    f = np.geomspace(20.0, 300.0, 15)
    M = res.controller.frequency_response(f)
    G0 = deduce_response(m.frequency_response(f)[:, None, None], M)
    rng = np.random.default_rng(1)
    draws = rng.multivariate_normal(theta, C, size=400, method="eigh")
    G = np.array([deduce_response(_with_parameters(m, t).frequency_response(f)[:, None, None], M) for t in draws])
    mc = np.sqrt(np.mean(np.abs(G - G0) ** 2, axis=0))[:, 0, 0]
    delta = np.sqrt(deduced_variance(res, f))[:, 0, 0]
    assert np.allclose(delta, mc, rtol=0.15)  # 400 draws: the std to ~4 %, plus the linearisation


def test_reduction_projection_matches_refitting_draws(siso_result) -> None:
    """Step 3 (implicit-function projection) against refitting the reduced entry to perturbed responses."""
    res = siso_result
    red = res.reduced[(0, 0)]
    fb = res.covariance.band_freqs
    f = np.geomspace(20.0, 300.0, 15)
    L, R, g, P = deduction_sensitivity(res, fb)
    C = res.covariance.covariances[(0, 0)]
    H = (L[:, 0, 0] * R[:, 0, 0])[:, None] * g[(0, 0)]  # dP / dtheta over the band
    rng = np.random.default_rng(2)
    dth = rng.multivariate_normal(np.zeros(C.shape[0]), C, size=60, method="eigh")
    ref = reduce_entry(P[:, 0, 0], fb, res.dt, 0, 2, red.unstable_poles, stable_free=red.unstable_poles.size > 0)
    s = 2j * np.pi * f

    def response(e):
        return np.polyval(e.num, s) / np.polyval(e.den, s)

    base = response(ref)
    moved = [
        response(reduce_entry(P[:, 0, 0] + H @ d, fb, res.dt, 0, 2, red.unstable_poles, stable_free=False)) for d in dth
    ]
    mc = np.sqrt(np.mean(np.abs(np.array(moved) - base) ** 2, axis=0))
    delta = plant_uncertainty(res, f, bias="none").std[:, 0, 0]
    assert np.allclose(delta, mc, rtol=0.35)  # 60 refits: the std to ~10 %


def test_bias_rules_and_other_structures(siso_result) -> None:
    # every comparison with atol=0: the stds are 1e-11-4e-8, below allclose's default atol of 1e-8
    f = np.geomspace(20.0, 300.0, 20)
    # the loop's pair at its own order (4, the default range's choice) leaves the reduction a
    # misfit within its noise: no rule adds to the std
    local = plant_uncertainty(siso_result, f, "local").std
    np.testing.assert_array_equal(local, plant_uncertainty(siso_result, f, "none").std)
    np.testing.assert_array_equal(siso_result.response_uncertainty(f).std, local)  # "local" is the default
    # orders 5-8 only, output error alone: the spare poles leave the reduction a misfit that passes
    # the significance quantile, and the rules add to the std where it sits ("local" up to 1.44x);
    # with the outputs' noise model (the default) the misfit stays below it: no rule adds (ratio 1.0)
    over = ClosedLoopIdentification(_siso_controller(), order_range=range(5, 9), noise_model="none").fit(
        _siso_experiment(0, 60.0)
    )
    none, flat, inflate, local_over = (plant_uncertainty(over, f, b).std for b in ("none", "flat", "inflate", "local"))
    assert all(np.all(std >= none) for std in (flat, inflate, local_over))  # the misfit only adds
    assert np.max(local_over / none) > 1.3
    with pytest.raises(IdentificationError, match="bias"):
        plant_uncertainty(siso_result, f, "huge")
    exp = _siso_experiment(0, 60.0)
    full = ClosedLoopIdentification(
        _siso_controller(), order_range=range(3, 8), structure="full", continuous=False
    ).fit(_siso_experiment(6))  # the setting test_closedloop_estimator's full-structure test uses
    fr = full.response_uncertainty(f)  # the cancelled deduction: eq. 18's variance
    np.testing.assert_allclose(fr.std**2, deduced_variance(full, f), rtol=1e-12, atol=0)
    assert np.all(fr.std > 0)
    disc = ClosedLoopIdentification(_siso_controller(), order_range=range(2, 9), continuous=False).fit(exp)
    frd = disc.response_uncertainty(f)
    np.testing.assert_allclose(frd.response, disc.plant.frequency_response(f), rtol=1e-12, atol=0)
    # the same data and parameters: the discrete model's band is the continuous one's to the
    # hold's effect (0.6 % at 300 Hz with dt = 0.2 ms)
    np.testing.assert_allclose(frd.std, local, rtol=0.02, atol=0)
