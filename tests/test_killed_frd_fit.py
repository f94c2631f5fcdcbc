"""Tests written to kill survivors of the ``frd-fit`` mutation group (tests/MUTATION.md)."""

import numpy as np
import pytest

from stageid import DataError
from stageid.frf import FRDIdentification, FrequencyResponse
from stageid.frf.identification import frequency_weights
from stageid.models import StateSpaceModel


def test_coherence_weights_are_the_signal_to_noise_ratio_by_hand():
    # gamma^2 / (1 - gamma^2) is the signal-to-noise power ratio of each output; averaged over outputs
    coh = np.array([[0.5, 0.9], [0.8, 0.8], [0.0, 0.99]])
    frd = FrequencyResponse([1.0, 2.0, 3.0], np.ones((3, 2, 1)), None, coh)
    kind, w = frequency_weights(frd, "coherence", np.ones(1))
    snr = np.array([(1.0 + 9.0) / 2, (4.0 + 4.0) / 2, (0.0 + 99.0) / 2])
    assert kind == "coherence"
    np.testing.assert_allclose(w, snr / snr.mean(), rtol=1e-12)
    # a coherence of 1 is capped at 1e6, not infinite
    frd1 = FrequencyResponse([1.0, 2.0], np.ones((2, 1, 1)), None, np.array([[1.0], [0.5]]))
    _, w1 = frequency_weights(frd1, "coherence", np.ones(1))
    ratio = (1.0 - 1e-6) / 1e-6
    np.testing.assert_allclose(w1, np.array([ratio, 1.0]) / np.mean([ratio, 1.0]), rtol=1e-9)


def test_the_largest_order_the_band_supports():
    # 2 n m / (m + q) - 2 - q: 10 lines of a SISO response support order 7, not 8
    g = StateSpaceModel([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=1e-3)
    f = np.linspace(10.0, 400.0, 10)
    frd = FrequencyResponse(f, g.frequency_response(f))
    FRDIdentification(order=7, sample_time=1e-3).fit(frd)
    with pytest.raises(DataError, match="at most order 7 here"):
        FRDIdentification(order=8, sample_time=1e-3).fit(frd)
