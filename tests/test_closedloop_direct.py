"""The direct prediction-error route on closed-loop data of an unstable 2x2 stage, controller not told.

Truth: :mod:`stageid.plants.levitated_pair` (unstable poles at 31.4 and 50 rad/s) under a
filtered PD the fit never sees, with saturation or a one-sample delay, 2 % measurement noise.
"""

import numpy as np
import pytest

from stageid import DataError
from stageid.closedloop.direct import DirectPredictionError
from stageid.data import Experiment
from stageid.plants import levitated_pair as lp

BAND = np.geomspace(0.5, 50.0, 80)  # Hz: the controlled band (closed loop at 20 Hz)


def _fit(seed=0, order=4, **loop):
    r, u, y = lp.record(5000, seed=seed, noise=0.02, **loop)
    return DirectPredictionError(order=order).fit(Experiment(u, y, lp.DT)), (r, u, y)


def _frf_error(result):
    true = lp.model().frequency_response(BAND)
    return np.abs(result.plant.frequency_response(BAND) - true).max() / np.abs(true).max()


@pytest.mark.parametrize("loop", [{}, {"saturation": 0.5}, {"delay": 1}], ids=["pd", "saturated", "delayed"])
def test_unstable_poles_and_response_without_the_controller(loop):
    res, _ = _fit(seed=3, **loop)
    found = np.sort(res.unstable_poles.real)
    assert found.size == 2
    # the targets: unstable poles within 2 %, FRF within 1 % of its peak over the band
    np.testing.assert_allclose(found, lp.UNSTABLE_POLES, rtol=0.02)
    assert _frf_error(res) < 0.01
    # the predictor that made this possible is stable although the plant is not
    assert np.max(np.abs(res.innovation.predictor_poles)) < 1
    assert np.max(np.abs(res.plant.poles())) > 1


def test_bands_cover_the_error_and_the_checks_pass():
    res, _ = _fit(seed=5)
    err = np.abs(np.sort(res.unstable_poles.real) - lp.UNSTABLE_POLES)
    std = res.unstable_pole_std[np.argsort(res.unstable_poles.real)]
    assert np.all(std > 0) and np.all(err < 4 * std)  # 4 std: a band that is neither empty nor vacuous
    fr = res.response_uncertainty(BAND)
    true = lp.model().frequency_response(BAND)
    assert np.all(np.abs(fr.response - true) < 4 * fr.std + 1e-3 * np.abs(true).max())
    assert res.passed, res.summary()


def test_a_too_small_model_is_flagged_by_the_residual_checks():
    res, _ = _fit(seed=5, order=2)
    failed = {c.name for c in res.checks if not c.passed}
    assert "whiteness" in failed


def test_references_only_feed_the_excitation_check():
    r, u, y = lp.record(3000, seed=1)
    exp = Experiment(np.hstack([r, u]), y, lp.DT, ("r1", "r2", "u1", "u2"), ("x1", "x2"))
    res = DirectPredictionError(order=4, references=["r1", "r2"]).fit(exp)
    assert res.plant.inputs == ("u1", "u2")
    share = {c.name: c for c in res.checks}["reference_share"]
    assert share.passed and 0.05 < share.value <= 1.0
    with pytest.raises(DataError, match="reference column 'r3'"):
        DirectPredictionError(order=4, references=["r3"]).fit(exp)


def test_summary_states_assumptions_and_checks():
    res, _ = _fit(seed=2)
    text = res.summary()
    assert "noise model" in text and "whiteness" in text and "+-" in text
