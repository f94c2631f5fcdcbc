"""Weight uncertainty of the PI models (issue 20, point 4): calibration on data with known weights."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss

from stageid._errors import ModelError, ParameterError
from stageid.hysteresis import PIIdentifier, PIModel
from stageid.hysteresis.weight_uncertainty import block_labels, correlation_length, plot_loop_band
from stageid.signals import decaying_triangle

U = decaying_triangle(1.0, 8, 1e-3, amplitude=10.0)  # symmetric: thresholds i R / n centred at 0
N_OPS = 8
W_TRUE = np.array([1.0, 0.4, 0.3, 0.2, 0.15, 0.1, 0.05, 0.05])
TRUE = PIModel(r=np.arange(N_OPS) * 10.0 / N_OPS, weights=W_TRUE)  # in the identified class exactly
Y0 = TRUE.simulate(U).reshape(-1)


def _fit(seed: int, ar: float = 0.0, n_bootstrap: int = 100, model: str = "pi"):
    v = np.random.default_rng(seed).standard_normal(U.size)
    v = ss.lfilter([np.sqrt(1 - ar**2)], [1, -ar], v)  # unit variance, correlated when ar > 0
    y = Y0 + 0.01 * np.ptp(Y0) * v
    return PIIdentifier(model, n_operators=N_OPS, initial_state="zero", n_bootstrap=n_bootstrap).fit((U, y))


@pytest.mark.slow
@pytest.mark.parametrize("ar", [0.0, 0.9])
def test_weight_std_and_loop_band_are_calibrated(ar: float) -> None:
    """10 noise seeds (white, then strongly correlated): |w_hat - w| <= 1.96 std for ~95 % of the
    weights, and the loop's band covers the noise-free output as often."""
    hits, z2, band = [], [], []
    for seed in range(10):
        fit = _fit(seed, ar)
        wu = fit.weight_uncertainty
        e = fit.model.weights - W_TRUE
        hits.append(np.abs(e) <= 1.96 * wu.std)
        z2.append(e**2 / wu.std**2)
        y, s = wu.output_band(fit.model, U)
        band.append(np.abs(y - Y0) <= 1.96 * s)
    # 80 weights: 95 % expected; 0.8 leaves room for the bootstrap's own scatter (measured 0.89-0.98)
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


def test_default_fit_has_no_draws_and_draws_are_reproducible() -> None:
    assert _fit(0, n_bootstrap=0).weight_uncertainty is None
    a, b = _fit(1, n_bootstrap=20).weight_uncertainty, _fit(1, n_bootstrap=20).weight_uncertainty
    assert a.weights.shape == (20, N_OPS) and a.n_draws == 20
    assert np.array_equal(a.weights, b.weights)
    assert np.all(np.isfinite(a.std)) and a.covariance.shape == (N_OPS, N_OPS)
    with pytest.raises(ParameterError, match="n_bootstrap"):
        PIIdentifier(n_bootstrap=-1).fit((U, Y0))


@pytest.mark.slow
def test_modified_pi_draws_respect_the_invertibility_bound_and_plot() -> None:
    fit = _fit(2, n_bootstrap=30, model="modified-pi")
    wu = fit.weight_uncertainty
    eps = 0.02 * np.ptp(Y0) / np.ptp(U) * (1 - 1e-6)
    # every draw is refitted under the bound w0 + sum min(w_i, 0) >= eps
    assert np.all(wu.weights[:, 0] + np.minimum(wu.weights[:, 1:], 0).sum(axis=1) >= eps)
    fig = plot_loop_band(fit.model, wu, U, Y0 + 0.1)
    assert len(fig.axes) == 2
    with pytest.raises(ModelError, match="operators"):
        wu.output_band(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]), U)
