"""Prediction-error identification (eq. 12-14): ARX, ARMAX, OE, BJ on systems with known truth."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss

from stageid._errors import DataError, IdentificationError
from stageid.closedloop import arx, pem, select_order
from stageid.closedloop.order_selection import continuation_orders

B_TRUE = np.array([0.0, 0.3, 0.1])  # q^-1 (0.3 + 0.1 q^-1): delay 1
F_TRUE = np.array([1.0, -1.2, 0.5])


def _data(n: int, seed: int, noise: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = ss.lfilter(B_TRUE, F_TRUE, u)
    if noise is not None:
        y = y + noise
    return u, y


def test_arx_is_exact_without_noise() -> None:
    u, y = _data(400, 0)
    m = arx(u, y, na=2, nb=2, nk=1)
    np.testing.assert_allclose(m.A, F_TRUE, atol=1e-10)  # noise-free: exact to rounding
    np.testing.assert_allclose(m.B, B_TRUE[1:], atol=1e-10)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_oe_is_consistent_where_arx_is_biased(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    n = 4000
    u, y0 = _data(n, seed)
    e = 0.3 * np.std(y0) * rng.standard_normal(n)  # white output noise, 10 dB SNR
    y = y0 + e
    m_oe = pem(u, y, "oe", {"nb": 2, "nf": 2}, nk=1)
    m_arx = arx(u, y, 2, 2, 1)
    # OE is consistent for white output noise: poles within a few percent of the truth
    assert np.max(np.abs(np.sort(np.roots(m_oe.F)) - np.sort(np.roots(F_TRUE)))) < 0.03
    # ARX is not: the equation error is coloured, so its pole estimate is clearly further off
    assert np.max(np.abs(np.sort(np.roots(m_arx.A)) - np.sort(np.roots(F_TRUE)))) > 0.05


def test_armax_recovers_noise_model() -> None:
    rng = np.random.default_rng(7)
    n = 6000
    u = rng.standard_normal(n)
    e = 0.1 * rng.standard_normal(n)
    A = np.array([1.0, -1.2, 0.5])
    C = np.array([1.0, 0.6])
    y = ss.lfilter([0.0, 0.3, 0.1], A, u) + ss.lfilter(C, A, e)
    m = pem(u, y, "armax", {"na": 2, "nb": 2, "nc": 1})
    np.testing.assert_allclose(m.A, A, atol=0.02)  # ~5 sigma of the estimate at N = 6000
    np.testing.assert_allclose(m.C, C, atol=0.05)
    assert abs(m.loss - 0.01) / 0.01 < 0.1  # loss ~ innovation variance


def test_bj_separates_plant_and_noise_dynamics() -> None:
    rng = np.random.default_rng(8)
    n = 6000
    u = rng.standard_normal(n)
    e = 0.05 * rng.standard_normal(n)
    y = ss.lfilter(B_TRUE, F_TRUE, u) + ss.lfilter([1.0, 0.5], [1.0, -0.9], e)
    m = pem(u, y, "bj", {"nb": 2, "nf": 2, "nc": 1, "nd": 1})
    np.testing.assert_allclose(m.F, F_TRUE, atol=0.02)
    np.testing.assert_allclose(m.D, [1.0, -0.9], atol=0.03)
    np.testing.assert_allclose(m.C, [1.0, 0.5], atol=0.05)


def test_predictor_polynomials_are_kept_stable() -> None:
    rng = np.random.default_rng(9)
    u, y = _data(2000, 9, 0.05 * rng.standard_normal(2000))
    m = pem(u, y, "bj", {"nb": 2, "nf": 2, "nc": 2, "nd": 2})
    assert np.all(np.abs(np.roots(m.C)) < 1.0) and np.all(np.abs(np.roots(m.F)) < 1.0)


def test_several_records_are_fitted_jointly() -> None:
    u1, y1 = _data(800, 11)
    u2, y2 = _data(800, 12)
    m = pem([u1, u2], [y1, y2], "oe", {"nb": 2, "nf": 2})
    np.testing.assert_allclose(m.F, F_TRUE, atol=1e-6)  # noise-free: converges to the truth


def test_select_order_finds_the_true_order() -> None:
    rng = np.random.default_rng(13)
    u, y = _data(3000, 13, 1e-3 * rng.standard_normal(3000))
    m, scores = select_order(u, y, "oe", orders=range(1, 7))
    assert m.F.size - 1 == 2 and scores


def test_select_order_optimises_the_screens_winner_and_climbs_to_the_largest() -> None:
    rng = np.random.default_rng(13)
    u, y = _data(3000, 13, 1e-3 * rng.standard_normal(3000))
    m, scores = select_order(u, y, "oe", orders=range(1, 9), refine_largest=True)
    winner = m.F.size - 1
    # from the lower of the winner and four below the largest, every second order up to the largest
    assert set(scores) == {winner, *continuation_orders(min(winner, 4), range(1, 9))} and 8 in scores
    assert m.F.size - 1 == 2  # the criterion after the optimisation still picks the true order


def test_transfer_and_frequency_response_agree() -> None:
    u, y = _data(500, 14)
    m = pem(u, y, "oe", {"nb": 2, "nf": 2})
    f = np.array([0.01, 0.1, 0.3])
    np.testing.assert_allclose(m.transfer().frequency_response(f)[:, 0, 0], m.frequency_response(f), rtol=1e-10)


def test_bad_arguments_raise_stageid_errors() -> None:
    u, y = _data(200, 15)
    with pytest.raises(IdentificationError, match="structure"):
        pem(u, y, "nope", {"nb": 1})
    with pytest.raises(IdentificationError, match="not free"):
        pem(u, y, "oe", {"nb": 2, "na": 2})
    with pytest.raises(DataError, match="same length"):
        pem(u, y[:-1], "oe", {"nb": 2, "nf": 2})
    with pytest.raises(DataError, match="samples"):
        pem(u[:20], y[:20], "oe", {"nb": 4, "nf": 4})
    with pytest.raises(IdentificationError, match="zero"):
        arx(np.zeros(200), y, 2, 2)


@pytest.mark.parametrize("pair", [(0, 1), (1, 0)])
def test_decrement_stop_gives_up_less_than_the_statistical_excess(monkeypatch, pair) -> None:
    """The 2x2 test plant's coupling pairs at the screen's order (order 15-16, cond(J) ~ 1e13):
    the default stop saves evaluations and costs less loss than an estimate's own excess d / N."""
    import importlib

    from _closedloop_plant2x2 import chirp_experiments  # tests/ is on sys.path (see conftest.py)

    pem_module = importlib.import_module("stageid.closedloop.pem")
    j, i = pair  # reference j, output i
    exp = chirp_experiments((10, 11))[j]
    r, y = exp.u[:, j], exp.y[:, i]
    stopped, _ = select_order(r, y, "oe", range(2, 17), 1, exp.dt)
    monkeypatch.setattr(pem_module, "STOP_FRACTION", 0.0)
    full, _ = select_order(r, y, "oe", range(2, 17), 1, exp.dt)
    assert stopped.F.size == full.F.size >= 15  # the same screen's choice
    excess = stopped.loss / full.loss - 1.0
    assert -1e-9 < excess < stopped.n_parameters / stopped.n_samples
    assert stopped.converged and stopped.n_iterations < 0.75 * full.n_iterations
