"""Weight uncertainty of the PI models calibration on data with known weights."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.signal as ss

from stageid._errors import ModelError, ParameterError
from stageid.hysteresis import PIIdentifier, PIModel
from stageid.hysteresis.identify.weight_uncertainty import block_labels, correlation_length, plot_loop_band
from stageid.signals import decaying_triangle

U = decaying_triangle(1.0, 8, 1e-3, amplitude=10.0)  # symmetric: thresholds i R / n centred at 0
N_OPS = 8
W_TRUE = np.array([1.0, 0.4, 0.3, 0.2, 0.15, 0.1, 0.05, 0.05])
TRUE = PIModel(r=np.arange(N_OPS) * 10.0 / N_OPS, weights=W_TRUE)  # in the identified class exactly
Y0 = TRUE.simulate(U).reshape(-1)


def _fit(seed: int, ar: float = 0.0, method: str = "auto", model: str = "pi"):
    v = np.random.default_rng(seed).standard_normal(U.size)
    v = ss.lfilter([np.sqrt(1 - ar**2)], [1, -ar], v)  # unit variance, correlated when ar > 0
    y = Y0 + 0.01 * np.ptp(Y0) * v
    return PIIdentifier(model, n_operators=N_OPS, initial_state="zero", weight_uncertainty=method).fit((U, y))


@pytest.mark.parametrize(
    ("ar", "method"), [(0.0, "sandwich"), (0.9, "sandwich"), pytest.param(0.9, "bootstrap", marks=pytest.mark.slow)]
)
def test_weight_std_and_loop_band_are_calibrated(ar: float, method: str) -> None:
    """10 noise seeds (white, then strongly correlated): |w_hat - w| <= 1.96 std for ~95 % of the
    weights, and the loop's band covers the noise-free output as often."""
    hits, z2, band = [], [], []
    for seed in range(10 if method == "sandwich" else 6):  # the bootstrap refits 200 times per seed
        fit = _fit(seed, ar, method)
        assert fit.weight_uncertainty.method == method
        wu = fit.weight_uncertainty
        e = fit.model.weights - W_TRUE
        hits.append(np.abs(e) <= 1.96 * wu.std)
        z2.append(e**2 / wu.std**2)
        y, s = wu.output_band(fit.model, U)
        band.append(np.abs(y - Y0) <= 1.96 * s)
    # 48-80 weights: 95 % expected; 0.8 leaves room for the bootstrap's own scatter (measured 0.89-0.98)
    assert 0.8 <= np.mean(hits) <= 1.0, np.mean(hits)
    assert 0.8 <= np.mean(band) <= 1.0, np.mean(band)
    # E e^2 / std^2 = 1 when calibrated: a std 3x off moves it 9x (measured 0.9 white, 1.4 at ar = 0.9)
    assert 1 / 3 < np.mean(z2) < 3, np.mean(z2)


def test_blocks_follow_the_residual_memory() -> None:
    rng = np.random.default_rng(0)
    white = rng.standard_normal(4000)
    slow = ss.lfilter([1.0], [1, -0.95], white)
    assert correlation_length(white) == 1
    assert 10 <= correlation_length(slow) <= 40  # 1/e at lag -1/ln(0.95) ~ 20
    lab = block_labels(slow, [1000, 3000])
    assert lab.size == 4000 and np.all(np.diff(lab) >= 0)
    assert lab[999] != lab[1000]  # no block crosses a record's end
    assert lab.max() + 1 >= 40  # never fewer than MIN_BLOCKS blocks


def test_default_fit_has_none_and_the_bootstrap_agrees_with_the_sandwich() -> None:
    assert _fit(0, method="none").weight_uncertainty is None
    a, b = _fit(1, method="sandwich").weight_uncertainty, _fit(1, method="bootstrap").weight_uncertainty
    assert a.covariance.shape == (N_OPS, N_OPS) and a.parameter_covariance.shape == (N_OPS + 1, N_OPS + 1)
    # no bound is active here: the bootstrap reproduces the sandwich to its 200 draws' scatter (~10 %)
    assert np.allclose(b.std, a.std, rtol=0.3)
    assert _fit(1, method="auto").weight_uncertainty.method == "sandwich"
    with pytest.raises(ParameterError, match="weight_uncertainty"):
        PIIdentifier(weight_uncertainty="exact").fit((U, Y0))


def test_output_band_is_the_model_output_and_grows_with_the_covariance() -> None:
    fit = _fit(3, method="sandwich")
    y, s = fit.weight_uncertainty.output_band(fit.model, U)
    assert np.allclose(y, fit.model.simulate(U).reshape(-1))
    doubled = dataclasses.replace(
        fit.weight_uncertainty, parameter_covariance=4 * fit.weight_uncertainty.parameter_covariance
    )
    assert np.allclose(doubled.output_band(fit.model, U)[1], 2 * s)


@pytest.mark.slow
def test_modified_pi_has_a_band_and_a_figure() -> None:
    fit = _fit(2, method="auto", model="modified-pi")
    wu = fit.weight_uncertainty
    assert np.all(np.isfinite(wu.std)) and wu.method in ("sandwich", "bootstrap")
    fig = plot_loop_band(fit.model, wu, U, Y0 + 0.1)
    assert len(fig.axes) == 2
    with pytest.raises(ModelError, match="operators"):
        wu.output_band(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]), U)


def test_creep_weights_are_part_of_the_band() -> None:
    rng = np.random.default_rng(5)
    y = Y0 + 0.3 * ss.lfilter([0.01], [1, -0.99], U) + 0.01 * np.ptp(Y0) * rng.standard_normal(U.size)
    fit = PIIdentifier("pi", n_operators=N_OPS, creep=[0.5], sample_time=1e-3, weight_uncertainty="sandwich").fit(
        (U, y)
    )
    wu = fit.weight_uncertainty
    assert wu.parameter_covariance.shape == (N_OPS + 2, N_OPS + 2)  # weights, offset, one creep weight
    yb, s = wu.output_band(fit.model, U)
    assert np.allclose(yb, fit.model.simulate(U).reshape(-1))
    # the band against simulating models whose weights, offset and creep weight are drawn from it
    draws = np.random.default_rng(0).multivariate_normal(
        np.concatenate([fit.model.weights, [fit.model.output_offset], fit.model.creep.weights]),
        wu.parameter_covariance,
        size=400,
    )
    sims = [
        dataclasses.replace(
            fit.model,
            weights=d[:N_OPS],
            output_offset=float(d[N_OPS]),
            creep=dataclasses.replace(fit.model.creep, weights=d[N_OPS + 1 :]),
        ).simulate(U)[:, 0]
        for d in draws
    ]
    assert np.allclose(np.std(sims, axis=0), s, rtol=0.15)  # 400 draws: a std to ~4 %
