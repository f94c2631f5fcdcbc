"""Chirps: instantaneous frequency from zero crossings, bounds, parameter errors."""

from __future__ import annotations

import re

import numpy as np
import pytest

from stageid import SignalError
from stageid.signals import chirp, log_chirp, time_vector


def _zero_crossings(x: np.ndarray, dt: float) -> np.ndarray:
    """Times of sign changes, linearly interpolated between samples."""
    s = np.signbit(x)
    i = np.nonzero(s[1:] != s[:-1])[0]
    return (i + x[i] / (x[i] - x[i + 1])) * dt


def _crossing_frequency(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean frequency between successive zero crossings (half a cycle apart)."""
    tc = _zero_crossings(x, dt)
    return 0.5 * (tc[1:] + tc[:-1]), 0.5 / np.diff(tc)


def test_linear_chirp_instantaneous_frequency_matches_law():
    f0, f1, T, dt = 1.0, 100.0, 10.0, 1e-4
    x = chirp(f0, f1, T, dt)
    t_mid, f_est = _crossing_frequency(x, dt)
    # For a linear chirp the mean frequency between two crossings equals f at their
    # midpoint exactly; what remains is the linear interpolation of the crossings
    # (< 1e-3 relative at 100 samples per cycle).
    f_law = f0 + (f1 - f0) * t_mid / T
    np.testing.assert_allclose(f_est, f_law, rtol=1e-3)
    # start and end: a straight line through the estimates gives f0 at t = 0 and f1 at T
    slope, intercept = np.polyfit(t_mid, f_est, 1)
    assert intercept == pytest.approx(f0, abs=0.01)
    assert intercept + slope * T == pytest.approx(f1, rel=1e-3)


def test_linear_chirp_crossings_are_roots_of_the_phase():
    f0, f1, T, dt = 5.0, 50.0, 2.0, 1e-4
    x = chirp(f0, f1, T, dt)
    tc = _zero_crossings(x, dt)
    m = np.arange(1, tc.size + 1)
    k = (f1 - f0) / T
    # phi(t) = 2 pi (f0 t + k t^2 / 2) = m pi  ->  t_m = (-f0 + sqrt(f0^2 + k m)) / k
    t_true = (-f0 + np.sqrt(f0**2 + k * m)) / k
    np.testing.assert_allclose(tc, t_true, atol=1e-7)  # interpolation error ~ (2 pi f dt)^2 dt


def test_log_chirp_instantaneous_frequency_at_start_and_end():
    f0, f1, T, dt = 2.0, 200.0, 4.0, 1e-4
    x = log_chirp(f0, f1, T, dt)
    tc = _zero_crossings(x, dt)
    m = np.arange(1, tc.size + 1)
    r = np.log(f1 / f0)
    # phi(t) = 2 pi f0 T (exp(r t / T) - 1) / r = m pi  ->  t_m below
    t_true = T / r * np.log1p(m * r / (2 * f0 * T))
    np.testing.assert_allclose(tc, t_true, atol=1e-7)  # interpolation error only
    t_mid, f_est = _crossing_frequency(x, dt)
    f_law = f0 * (f1 / f0) ** (t_mid / T)
    # half-cycle averages of an exponential law: second-order error, < 0.5 % here
    np.testing.assert_allclose(f_est, f_law, rtol=5e-3)
    assert f_est[0] < 1.5 * f0  # starts at f0 (first estimate is 0.3 s in)
    assert abs(f_est[-1] - f1) / f1 < 0.01
    assert np.array_equal(x, chirp(f0, f1, T, dt, method="logarithmic"))


def test_cao_chen_chirp_bounds_and_offset():
    # 20 um chirp on a 20 um offset, 1-100 Hz, 2 ms sampling: spans 0..40 um
    x = chirp(1.0, 100.0, 20.0, 2e-3, amplitude=20.0, offset=20.0, limits=(0.0, 40.0))
    assert x.shape == (10000,) and x.dtype == np.float64
    assert x.min() >= 0.0 and x.max() <= 40.0
    assert x.min() < 0.1 and x.max() > 39.9  # really uses the full swing
    assert x[0] == 20.0  # phase 0 starts at the offset
    start_low = chirp(1.0, 100.0, 20.0, 2e-3, amplitude=20.0, offset=20.0, phase=-np.pi / 2)
    assert start_low[0] == pytest.approx(0.0, abs=1e-12)


def test_shakir_kim_chirp_up_to_nyquist():
    # 1 um from DC to 2500 Hz in 2 s at 5 kHz: f1 equals the Nyquist frequency
    dt = 1 / 5000
    x = chirp(0.0, 2500.0, 2.0, dt, amplitude=1.0)
    assert x.shape == (10000,)
    assert np.all(np.abs(x) <= 1.0)
    t = time_vector(x.size, dt)
    np.testing.assert_allclose(x, np.sin(2 * np.pi * 0.5 * 2500.0 / 2.0 * t**2), atol=1e-9)


def test_chirp_limits_error_names_span_and_limits():
    with pytest.raises(SignalError, match=r"^chirp spans \[-1(\.0+\d*)?, 41(\.0+\d*)?\] but limits are \[0, 40\]\.$"):
        chirp(0.0, 100.0, 1.0, 1e-3, amplitude=21.0, offset=20.0, phase=-np.pi / 2, limits=(0.0, 40.0))


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        (
            dict(f0=0.0, f1=10.0, duration=1.0, dt=1e-3, method="logarithmic"),
            "`f0` of a logarithmic chirp must be > 0 Hz",
        ),
        (dict(f0=1.0, f1=600.0, duration=1.0, dt=1e-3), "Nyquist frequency 1/(2 dt) = 500 Hz; got 600 Hz"),
        (dict(f0=10.0, f1=5.0, duration=1.0, dt=1e-3), "greater than f0 = 10 Hz; got 5 Hz"),
        (dict(f0=1.0, f1=5.0, duration=-1.0, dt=1e-3), "`duration` of chirp must be a number > 0; got -1"),
        (dict(f0=1.0, f1=5.0, duration=1.0, dt=0.0), "`dt` of chirp must be a number > 0; got 0"),
        (dict(f0=1.0, f1=5.0, duration=1.0, dt=0.8), "at least 2 samples"),
        (dict(f0=1.0, f1=5.0, duration=1.0, dt=1e-3, amplitude=-1.0), "`amplitude` of chirp must be a number > 0"),
        (dict(f0=1.0, f1=5.0, duration=1.0, dt=1e-3, method="cubic"), "'linear', 'logarithmic'; got 'cubic'"),
        (dict(f0=-1.0, f1=5.0, duration=1.0, dt=1e-3), "`f0` of chirp must be a number >= 0; got -1"),
        (dict(f0=1.0, f1=float("nan"), duration=1.0, dt=1e-3), "`f1` of chirp must be a number > 0; got nan"),
    ],
)
def test_chirp_parameter_errors(kwargs, fragment):
    with pytest.raises(SignalError, match=re.escape(fragment)):
        chirp(**kwargs)


def test_chirp_does_not_change_with_repeated_calls():
    a = chirp(1.0, 10.0, 1.0, 1e-3)
    b = chirp(1.0, 10.0, 1.0, 1e-3)
    assert np.array_equal(a, b)
