"""Identification: exact recovery where the model class contains the truth, constraints, offsets."""

import numpy as np
import pytest

from stageid import IdentificationError
from stageid.hysteresis import ModifiedPIModel, PIIdentifier, PIModel, align_record
from stageid.signals import decaying_triangle


def _input():
    return decaying_triangle(1.0, 8, 2e-3, amplitude=400.0)


def test_recovers_classical_pi_exactly():
    u = _input()
    r = np.arange(8) * 50.0  # the grid PIIdentifier uses for +-400 V and 8 operators
    true = PIModel(r=r, weights=[0.01, 0.004, 0.003, -0.001, 0.002, 0.001, 0.0015, 0.0005])
    fit = PIIdentifier("pi", n_operators=8).fit((u, true.simulate(u)))
    np.testing.assert_allclose(fit.model.weights, true.weights, atol=1e-9)
    assert fit.max_error_percent[0] < 1e-6
    assert np.all(fit.model.initial_loading_slopes() > 0)


def test_recovers_modified_pi_on_the_search_grid():
    u = _input()
    r = np.arange(8) * 50.0
    true = ModifiedPIModel(r=r, rc=0.5 * r, ra=1.4 * r, rb=0.7 * 1.4 * r,
                           weights=[0.01, 0.004, 0.003, 0.002, 0.002, 0.001, 0.0015, 0.0005])
    y = true.simulate(u)
    classical = PIIdentifier("pi", n_operators=8).fit((u, y))
    fit = PIIdentifier("modified-pi", n_operators=8, max_evaluations=200, input_warp=False).fit((u, y))
    assert classical.max_error_percent[0] > 2.0  # the CP asymmetry is not a PI model
    assert fit.max_error_percent[0] < 0.05
    assert fit.model.min_slope() > 0 and fit.model.input_warp == 0.0


def test_recovers_input_warp():
    u = _input()
    r = np.arange(8) * 50.0
    true = ModifiedPIModel(r=r, rc=0.5 * r, ra=1.4 * r, rb=0.7 * 1.4 * r, input_warp=0.2, warp_scale=400.0,
                           weights=[0.01, 0.004, 0.003, 0.002, 0.002, 0.001, 0.0015, 0.0005])
    y = true.simulate(u)
    without = PIIdentifier("modified-pi", n_operators=8, max_evaluations=200, input_warp=False).fit((u, y))
    fit = PIIdentifier("modified-pi", n_operators=8, max_evaluations=200).fit((u, y))
    assert without.max_error_percent[0] > 1.0
    assert fit.max_error_percent[0] < 0.05
    assert abs(fit.model.input_warp - 0.2) < 1e-3


def test_offsets_per_record_and_starting_state():
    u = _input()
    true = PIModel(r=np.arange(8) * 50.0, weights=[0.01, 0.004, 0.003, 0.002, 0.002, 0.001, 0.0015, 0.0005])
    y = true.simulate(u)[:, 0]
    # second record: other sensor zero, starts at -100 V having come up from below
    u2 = np.r_[np.linspace(-100, -50, 100), np.linspace(-50, -300, 300), np.linspace(-300, 100, 200)]
    start = true.with_state(true.consistent_state(-100.0, "ascending"))
    y2 = start.simulate(u2)[:, 0] + 1.7
    fit = PIIdentifier("pi", n_operators=8).fit([(u, y + 0.2), (u2, y2)])
    assert fit.initial_states == ("zero", "ascending")
    np.testing.assert_allclose(fit.output_offsets, [0.2, 1.7], atol=1e-9)
    _, yh = align_record(fit.model, u2, y2)
    np.testing.assert_allclose(yh[:, 0], y2, atol=1e-7)  # weights from a least-squares solve: ~1e-10 each, times 400 V


def test_monotone_constraint_active():
    # data that would need a falling branch: the constrained weights keep every slope >= eps
    u = _input()
    y = np.sin(u / 60.0)  # not monotone in u at all
    fit = PIIdentifier("pi", n_operators=10).fit((u, y))
    eps = 0.02 * np.ptp(y) / np.ptp(u)
    assert np.all(fit.model.initial_loading_slopes() >= eps * (1 - 1e-9))
    fit2 = PIIdentifier("modified-pi", n_operators=10, max_evaluations=40).fit((u, y))
    assert fit2.model.min_slope() >= eps * (1 - 1e-6)


def test_bad_hyperparameters():
    u = _input()
    with pytest.raises(IdentificationError, match="model"):
        PIIdentifier("preisach").fit((u, u))
    with pytest.raises(IdentificationError, match="n_operators"):
        PIIdentifier("pi", n_operators=1).fit((u, u))


@pytest.mark.parametrize("input_range", [(-270.0, 90.0), (-90.0, 270.0)])
def test_classical_fit_with_input_range_wider_than_the_data(input_range):
    # operators whose thresholds lie beyond the data never move: their columns are collinear
    # with the offset, the Gram matrix of the bounded fit is singular to rounding (this raised
    # numpy's LinAlgError "Matrix is not positive definite" before)
    from stageid.signals import forc_staircase

    u = forc_staircase(-90, 90, 50, 20, 1e-4, shape="cosine")
    r = np.arange(8) * 90 / 8
    true = ModifiedPIModel(r=r, rc=0.5 * r, ra=1.4 * r, rb=0.7 * 1.4 * r,
                           weights=[0.01, 0.004, 0.003, 0.002, 0.002, 0.001, 0.0015, 0.0005])
    y = true.simulate(u)[:, 0] + 1e-4 * np.random.default_rng(0).standard_normal(u.size)
    narrow = PIIdentifier("pi", n_operators=20).fit((u, y))
    fit = PIIdentifier("pi", n_operators=40, input_range=input_range).fit((u, y))
    assert np.all(fit.model.initial_loading_slopes() > 0)
    # 20 of the 40 operators cover the data's range: about as good as 20 over the range itself
    assert fit.max_error_percent[0] < 1.2 * narrow.max_error_percent[0]
