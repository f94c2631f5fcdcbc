"""The letter's error measures on cases with known answers."""

import numpy as np
import pytest

from stageid import DataError
from stageid.hysteresis import hysteresis_percent, max_error_percent, rms_error_percent, tracking_error_percent


def test_letter_tracking_example():
    # +-0.33 um error on a 3 um triangle is 11 % FSR (Fig. 10)
    ref = np.r_[np.linspace(0, 3, 50), np.linspace(3, 0, 50)]
    assert tracking_error_percent(ref, ref + 0.33 * np.sign(np.sin(np.arange(100)))) == pytest.approx(11.0)


def test_max_and_rms():
    y = np.linspace(0, 10, 101)
    e = np.zeros(101)
    e[7] = 0.5
    assert max_error_percent(y, y + e) == pytest.approx(5.0)
    assert rms_error_percent(y, y + e) == pytest.approx(100 * 0.5 / np.sqrt(101) / 10)


def test_hysteresis_of_a_parallelogram():
    # a play operator's loop: branches x - r and x + r -> width 2r over output range
    from stageid.hysteresis import play

    x = np.concatenate([np.linspace(0, 10, 101), np.linspace(10, -10, 201), np.linspace(-10, 10, 201)])
    z, _ = play(x, [2.0])
    assert hysteresis_percent(x, z) == pytest.approx(100 * 4.0 / 16.0)
    assert hysteresis_percent(x, x) == pytest.approx(0.0, abs=1e-12)


def test_errors():
    with pytest.raises(DataError, match="rise and fall"):
        hysteresis_percent(np.arange(10.0), np.arange(10.0))
    with pytest.raises(DataError, match="equal length"):
        max_error_percent(np.zeros(3), np.zeros(4))
