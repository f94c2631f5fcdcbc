"""Uncertainty of the realised Hankel-MAP model: calibration, cross-method agreement, API."""

import numpy as np
import pytest

from _subspace_systems import band_limited, random_stage, record
from stageid._errors import DataError
from stageid.frf import FrequencyResponse
from stageid.plants import piezo_stage as ps
from stageid.subspace import HankelMAP
from stageid.subspace.uncertainty import realised_response_uncertainty

# For a circular complex Gaussian error with E|dG|^2 = std^2, P(|dG| <= k std) = 1 - exp(-k^2):
# k = 1.73 covers 95 %.  The window is a factor 3 either way: a std 3x too small covers ~28 %, 3x too large
# ~100 %, and each test also checks that its own data would reject those (the test can fail).
K95 = 1.73
WINDOW = (0.90, 0.98)
SEEDS = range(20)


def coverage(errors: np.ndarray, std: np.ndarray, factor: float = 1.0) -> float:
    return float(np.mean(errors <= K95 * factor * std))


def assert_calibrated(errors: np.ndarray, std: np.ndarray) -> float:
    c = coverage(errors, std)
    assert WINDOW[0] <= c <= WINDOW[1], c
    # the same errors would reject a std 3x too small or 3x too large
    assert coverage(errors, std, 1 / 3) < WINDOW[0] and coverage(errors, std, 3) > WINDOW[1]
    return c


def test_p558_realised_model_bands_are_calibrated():
    # the acceptance case: all inputs band-limited 1-100 Hz, 1 % output noise, order 15 (horizon
    # fixed at what "auto" picks here, to spare the selection); studies/uncertainty has 20 seeds
    # with the horizon chosen and per-entry figures (Z -> z is the weak entry)
    g = ps.model()
    f = np.geomspace(1.5, 98, 60)
    Gt = g.frequency_response(f)
    err, std = [], []
    for seed in SEEDS:
        exp = record(g, band_limited(20000, 3, g.dt, seed) * np.array([10.0, 100.0, 100.0]), 0.01, seed)
        fr = HankelMAP(horizon=50, order=15).fit(exp).response_uncertainty(f)
        assert np.all(fr.std > 0)
        err.append(np.abs(fr.response - Gt))
        std.append(fr.std)
    assert_calibrated(np.concatenate(err), np.concatenate(std))  # measured 0.912 (0.924 with the former p P covariance)


def test_realised_model_bands_are_calibrated_on_an_unseen_stage():
    # with the covariance under overlapping windows (window_covariance); the p P allowance it
    # replaced covered 99.3 % here (bands ~1.4x too wide), so this was a strict xfail
    g = random_stage(8, m=1, q=2, modes=2)
    f = np.geomspace(2, 98, 60)
    Gt = g.frequency_response(f)
    err, std = [], []
    for seed in SEEDS:
        exp = record(g, band_limited(6000, 1, g.dt, seed), 0.02, seed, names=False)
        fr = HankelMAP(horizon=25, order=4).fit(exp).response_uncertainty(f)
        err.append(np.abs(fr.response - Gt))
        std.append(fr.std)
    assert_calibrated(np.concatenate(err), np.concatenate(std))  # measured 0.95 (studies: 94.9-95.0 %)


def test_per_channel_fit_stacks_the_channels_own_uncertainty():
    # eq. 19-22: column j of the stacked model's std is that of input j's own single-input fit
    exps = [ps.EXPERIMENTS[k](0) for k in ("chirp-z", "chirp-rx", "chirp-ry")]
    f = np.geomspace(1.5, 95, 30)
    stacked = HankelMAP(horizon=16, order=[7, 4, 4], per_channel=True).fit(exps).response_uncertainty(f)
    for j, (exp, order) in enumerate(zip(exps, (7, 4, 4))):
        alone = HankelMAP(horizon=16, order=order).fit(exp.select(inputs=[exp.input_names[j]]))
        fr = alone.response_uncertainty(f)
        np.testing.assert_allclose(stacked.std[:, :, j], fr.std[:, :, 0], rtol=1e-6)
        np.testing.assert_allclose(stacked.response[:, :, j], fr.response[:, :, 0], rtol=1e-6)


def test_delta_method_agrees_with_realising_posterior_draws():
    # the first-order map against realising draws of the same (matrix-normal, p P) posterior
    g = random_stage(8, m=1, q=2, modes=2)
    exp = record(g, band_limited(6000, 1, g.dt, 3), 0.02, 3, names=False)
    res = HankelMAP(horizon=25, order=4).fit(exp)
    f = np.geomspace(2, 98, 40)
    delta = realised_response_uncertainty(res, f, method="delta", overlap="inflate")
    draws = res.response_uncertainty(f, method="sampling", n_samples=60, seed=1)
    ratio = delta.std / draws.std
    # 60 draws estimate a std to ~9 %; the first-order map misses the realisation's curvature
    assert 0.8 < np.median(ratio) < 1.25, np.median(ratio)
    assert np.all((ratio > 0.4) & (ratio < 2.5))


def test_result_is_a_frequency_response_of_the_model():
    g = random_stage(8, m=1, q=2, modes=2)
    exp = record(g, band_limited(4000, 1, g.dt, 0), 0.02, 0)
    res = HankelMAP(horizon=20, order=4).fit(exp)
    f = np.geomspace(1, 250, 30)  # up to Nyquist, outside the excited band too
    fr = res.response_uncertainty(f)
    assert isinstance(fr, FrequencyResponse)
    np.testing.assert_allclose(fr.response, res.model.frequency_response(f), rtol=1e-12)
    assert fr.inputs == res.model.inputs and fr.outputs == res.model.outputs
    assert fr.std.shape == (30, 2, 1) and np.all(np.isfinite(fr.std))
    for bad in ([np.nan], [10.0, 300.0], [[1.0, 2.0]], [-1.0, 2.0]):
        with pytest.raises(DataError):
            res.response_uncertainty(bad)
    with pytest.raises(DataError, match="method"):
        res.response_uncertainty(f, method="bootstrap")
    with pytest.raises(DataError, match="overlap"):
        realised_response_uncertainty(res, f, overlap="hac")
    with pytest.raises(DataError, match="bias"):
        realised_response_uncertainty(res, f, bias="flat")


def test_markov_route_uses_posterior_draws():
    g = random_stage(5, m=1, q=2, modes=2)
    u = np.random.default_rng(0).standard_normal((6000, 1))
    exp = record(g, u, 0.02, 0, names=False)
    res = HankelMAP(horizon=20, order=4, realization="markov").fit(exp)
    f = np.geomspace(2, 98, 20)
    fr = res.response_uncertainty(f, n_samples=30)
    assert np.all(fr.std > 0) and np.all(np.isfinite(fr.std))
    # the truth lies within a few std almost everywhere (a loose check: 30 draws, one record)
    z = np.abs(fr.response - g.frequency_response(f)) / fr.std
    assert np.mean(z <= 3.0) > 0.9, np.mean(z <= 3.0)
