"""Uncertainty of models fitted to frequency-response data: from the data's std."""

import numpy as np
import pytest

from stageid._errors import DataError
from stageid.frf import FRDIdentification, FrequencyResponse
from stageid.models import StateSpaceModel
from test_uncertainty_hankel_map import assert_calibrated

SEEDS = range(16)  # 16 x 120 x 2 points; the study runs 20 seeds


def two_mode_plant(dt=0.002) -> StateSpaceModel:
    """1 input, 2 outputs, resonances at 12 and 47 Hz (3 and 2 % damping)."""
    A, B, C = np.zeros((4, 4)), np.zeros((4, 1)), np.zeros((2, 4))
    for i, (f, z, c) in enumerate([(12.0, 0.03, [1.0, 0.5]), (47.0, 0.02, [0.3, -0.8])]):
        w = 2 * np.pi * f
        A[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = [[0, 1], [-w * w, -2 * z * w]]
        B[2 * i + 1, 0] = w * w
        C[:, 2 * i] = c
    g = StateSpaceModel(A, B, C, np.zeros((2, 1)), None)
    return g if dt is None else g.c2d(dt)


def noisy_frf(g, f, seed, with_std=True):
    Gt = g.frequency_response(f)
    sd = 0.02 * np.abs(Gt).max() * (0.5 + np.random.default_rng(0).random(Gt.shape))
    rng = np.random.default_rng([seed, 7])
    noise = sd * (rng.standard_normal(Gt.shape) + 1j * rng.standard_normal(Gt.shape)) / np.sqrt(2)
    return FrequencyResponse(f, Gt + noise, sd if with_std else None)


@pytest.mark.parametrize("with_std", [True, False])
def test_fit_bands_are_calibrated(with_std):
    # with the data's std, and without it (noise from the weighted residual)
    g = two_mode_plant()
    f = np.linspace(1, 200, 300)
    fe = np.geomspace(1, 200, 120)
    Gt = g.frequency_response(fe)
    err, std = [], []
    for seed in SEEDS:
        res = FRDIdentification(order=4, sample_time=g.dt).fit(noisy_frf(g, f, seed, with_std))
        assert res.covariance.noise_source == ("std" if with_std else "residual")
        fr = res.response_uncertainty(fe)
        err.append(np.abs(fr.response - Gt))
        std.append(fr.std)
    assert_calibrated(np.concatenate(err), np.concatenate(std))  # measured 0.922 with std, 0.906 without


def test_continuous_fit_and_delay():
    g = two_mode_plant(None)
    f = np.linspace(1, 200, 300)
    res = FRDIdentification(order=4).fit(noisy_frf(g, f, 0))
    fe = np.geomspace(0.5, 1000, 50)  # a continuous model has no Nyquist limit
    fr = res.response_uncertainty(fe)
    np.testing.assert_allclose(fr.response, res.model.frequency_response(fe), rtol=1e-10)
    # calibrated in the band, pooled over seeds (one fit's errors are one smooth curve: its coverage
    # is 0.94-1.0 whatever the std's size); measured 0.922, rejecting a std 3x too small or too large
    fb = np.geomspace(1, 200, 120)
    err, std = [], []
    for seed in SEEDS:
        fr_s = FRDIdentification(order=4).fit(noisy_frf(g, f, seed)).response_uncertainty(fb)
        err.append(np.abs(fr_s.response - g.frequency_response(fb)))
        std.append(fr_s.std)
    assert_calibrated(np.concatenate(err), np.concatenate(std))
    # a discrete fit with an input delay: the delay states carry no uncertainty of their own
    gd = two_mode_plant()
    z = np.exp(2j * np.pi * f * gd.dt)
    data = noisy_frf(gd, f, 1)
    delayed = FrequencyResponse(f, data.response * (z**-2)[:, None, None], data.std)
    res_d = FRDIdentification(order=4, sample_time=gd.dt, delay=2).fit(delayed)
    fr_d = res_d.response_uncertainty(fe[fe <= 250])
    assert res_d.delay == 2 and np.all(fr_d.std > 0)


def test_grid_is_checked():
    g = two_mode_plant()
    res = FRDIdentification(order=4, sample_time=g.dt).fit(noisy_frf(g, np.linspace(1, 200, 300), 0))
    for bad in ([np.nan], [10.0, 300.0], [-1.0], []):
        with pytest.raises(DataError):
            res.response_uncertainty(bad)
