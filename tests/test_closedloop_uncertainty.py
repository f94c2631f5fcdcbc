"""Closed-loop uncertainty (issue 20): PEM parameter covariance and its propagation to the plant."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.signal as ss

from stageid._errors import DataError, IdentificationError, ParameterError
from stageid.closedloop import ClosedLoopIdentification, pem
from stageid.closedloop.covariance import pem_covariance, transfer_gradient
from stageid.closedloop.polynomial import pack
from stageid.frf.frd import FrequencyResponse

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


@pytest.mark.slow
def test_siso_bands_are_calibrated_over_seeds() -> None:
    """20 noise seeds of an unstable SISO loop: the 1.73-std band covers 85-99 % (issue 20, point 3)."""
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
