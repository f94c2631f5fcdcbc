"""The k-step prediction error of ``studies/hysteresis/forc_pair_mode_study.py`` against its closed form."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import lfilter


@pytest.mark.parametrize("seed", [0, 1])
def test_k_step_prediction_error_of_an_autoregressive_residual_matches_its_closed_form(seed):
    """A residual ``e = eps / (1 - p q^-1)`` (white ``eps`` of RMS s): the k-step prediction error
    has RMS ``s sqrt((1 - p^2k) / (1 - p^2))``, one step ``s``, many steps the residual's own RMS."""
    sys.path.insert(0, str(Path(__file__).parents[1] / "studies" / "hysteresis"))
    from forc_pair_mode_study import STEPS, step_scores

    rng = np.random.default_rng(seed)
    p, s, span = 0.9, 1e-3, 1.0
    train = [lfilter([1.0], [1.0, -p], s * rng.standard_normal(40000))]
    test = lfilter([1.0], [1.0, -p], s * rng.standard_normal(40000))
    scores = step_scores([(train, [(test, span)])], np.ones(1))
    expected = [100 * s * np.sqrt((1 - p ** (2 * k)) / (1 - p**2)) / span for k in STEPS]
    # 40000 samples: the RMS estimates scatter by ~1 % (more for long horizons, whose errors correlate)
    np.testing.assert_allclose(scores, expected, rtol=0.05)
    assert scores[-1] == pytest.approx(100 * np.sqrt(np.mean(test**2)) / span, rel=0.05)
