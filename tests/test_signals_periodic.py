"""Sine, triangle and multisines: values at known times, FFT lines, crest factor."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from stageid import SignalError
from stageid.signals import band_limited_random, crest_factor, multisine, multisine_lines, sine, time_vector, triangle


def test_sine_values_at_known_times():
    # 2 Hz at dt = 1/40 s: 20 samples per period, quarter period = 5 samples
    x = sine(2.0, 1.0, 1 / 40, amplitude=3.0, offset=10.0)
    assert x.shape == (40,)
    np.testing.assert_allclose(x[[0, 5, 10, 15, 20]], [10.0, 13.0, 10.0, 7.0, 10.0], atol=1e-12)
    t = time_vector(40, 1 / 40)
    np.testing.assert_allclose(x, 10.0 + 3.0 * np.sin(4 * np.pi * t), atol=1e-12)
    y = sine(2.0, 1.0, 1 / 40, phase=np.pi / 2)
    assert y[0] == pytest.approx(1.0, abs=1e-15)


def test_triangle_values_at_known_times_and_straight_ramps():
    f, dt = 2.0, 1 / 400  # 200 samples per period
    x = triangle(f, 1.0, dt, amplitude=3.0, offset=10.0)
    assert x.shape == (400,)
    # quarter-period knots exactly, and straight lines between them
    np.testing.assert_allclose(x[[0, 50, 100, 150, 200, 250]], [10.0, 13.0, 10.0, 7.0, 10.0, 13.0], atol=1e-12)
    t = time_vector(400, dt)
    knots_t = np.arange(0, 1.0 + 1e-9, 1 / (4 * f))
    knots_x = 10.0 + 3.0 * np.tile([0.0, 1.0, 0.0, -1.0], knots_t.size // 4 + 1)[: knots_t.size]
    np.testing.assert_allclose(x, np.interp(t, knots_t, knots_x), atol=1e-12)
    # it is the arcsine of the sine of the same phase
    z = triangle(f, 1.0, dt, phase=0.7)
    np.testing.assert_allclose(z, 2 / np.pi * np.arcsin(np.sin(2 * np.pi * f * t + 0.7)), atol=1e-12)


@pytest.mark.parametrize("func", [sine, triangle])
def test_periodic_parameter_errors_and_limits(func):
    name = func.__name__
    with pytest.raises(SignalError, match=re.escape(f"`freq` of {name} must be a number > 0; got 0")):
        func(0.0, 1.0, 1e-3)
    with pytest.raises(SignalError, match=re.escape("Nyquist frequency 1/(2 dt) = 500 Hz; got 501 Hz")):
        func(501.0, 1.0, 1e-3)
    with pytest.raises(SignalError, match=re.escape(f"`duration` of {name} must be a number > 0; got -2")):
        func(1.0, -2.0, 1e-3)
    with pytest.raises(SignalError, match=rf"^{name} spans \[-1, 1\] but limits are \[0, 2\]\.$"):
        func(1.0, 1.0, 1e-3, limits=(0.0, 2.0))
    assert func(1.0, 1.0, 1e-3, offset=1.0, limits=(0.0, 2.0)).max() == pytest.approx(2.0)


# -------------------------------------------------------------------------- multisine


def test_multisine_lines_on_period_grid():
    # N = 1000 samples per period, dt = 1 ms: lines every 1 Hz
    assert multisine_lines(1000, 1e-3, 10.0, 20.0).tolist() == list(range(10, 21))
    # DC and Nyquist are never excited
    assert multisine_lines(1000, 1e-3, 0.0, 500.0).tolist() == list(range(1, 500))
    # three periods of 400 samples: lines every 2.5 Hz of the period grid
    assert multisine_lines(1200, 1e-3, 5.0, 10.0, n_periods=3).tolist() == [2, 3, 4]


@pytest.mark.parametrize("kind", ["random-phase", "schroeder"])
def test_multisine_has_energy_only_on_excited_lines(kind):
    n, dt, lo, hi, p = 3000, 1e-3, 5.0, 60.0, 3
    x = multisine(n, dt, lo, hi, kind=kind, rms=2.0, seed=1, n_periods=p, offset=7.0)
    spec = np.abs(np.fft.rfft(x - 7.0)) ** 2
    lines = multisine_lines(n, dt, lo, hi, n_periods=p) * p  # on the grid of the record
    on = np.zeros(spec.size, dtype=bool)
    on[lines] = True
    assert spec[~on].sum() / spec.sum() < 1e-10
    # flat amplitude spectrum on the excited lines
    np.testing.assert_allclose(spec[on], spec[on].mean(), rtol=1e-9)
    # exactly periodic, exact RMS
    period = n // p
    np.testing.assert_allclose(x[:period], x[period : 2 * period], atol=1e-12)
    assert np.sqrt(np.mean((x - 7.0) ** 2)) == pytest.approx(2.0, rel=1e-12)


def test_schroeder_crest_factor_below_zero_phase_and_typical_random_phase():
    n, dt, lo, hi = 4000, 1e-3, 1.0, 200.0
    lines = multisine_lines(n, dt, lo, hi)
    t = time_vector(n, dt)
    zero_phase = np.cos(2 * np.pi * np.outer(t, lines / (n * dt))).sum(axis=1)
    schroeder = multisine(n, dt, lo, hi, kind="schroeder")
    cf_zero = crest_factor(zero_phase)  # sqrt(2 F) = 20 for F = 200 lines
    cf_schroeder = crest_factor(schroeder)
    assert cf_zero == pytest.approx(np.sqrt(2 * lines.size), rel=1e-9)
    assert cf_schroeder < 2.0 < cf_zero
    cf_random = [crest_factor(multisine(n, dt, lo, hi, seed=s)) for s in range(5)]
    assert cf_schroeder < min(cf_random)


def test_multisine_scaling_determinism_and_channels():
    a = multisine(1000, 1e-3, 1.0, 100.0, amplitude=3.0, seed=2)
    assert np.max(np.abs(a)) == pytest.approx(3.0, rel=1e-12)
    assert np.array_equal(a, multisine(1000, 1e-3, 1.0, 100.0, amplitude=3.0, seed=2))
    assert not np.allclose(a, multisine(1000, 1e-3, 1.0, 100.0, amplitude=3.0, seed=3))
    s1 = multisine(1000, 1e-3, 1.0, 100.0, kind="schroeder", seed=1)
    assert np.array_equal(s1, multisine(1000, 1e-3, 1.0, 100.0, kind="schroeder", seed=9))
    m = multisine(1000, 1e-3, 1.0, 100.0, seed=2, n_channels=2)
    assert m.shape == (1000, 2) and not np.allclose(m[:, 0], m[:, 1])
    s = multisine(1000, 1e-3, 1.0, 100.0, kind="schroeder", n_channels=4)
    for j in range(4):
        np.testing.assert_allclose(s[:, j], np.roll(s1, j * 250), atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        (
            dict(n_samples=1000, dt=1e-3, f_low=1.0, f_high=100.0, kind="flat"),
            "'random-phase', 'schroeder'; got 'flat'",
        ),
        (
            dict(n_samples=1000, dt=1e-3, f_low=1.0, f_high=100.0, n_periods=3),
            "must be a multiple of n_periods = 3; got 1000",
        ),
        (dict(n_samples=100, dt=1e-3, f_low=1.0, f_high=5.0), "at least one line"),
        (dict(n_samples=1000, dt=1e-3, f_low=1.0, f_high=501.0), "Nyquist frequency 1/(2 dt) = 500 Hz; got 501 Hz"),
        (dict(n_samples=1000, dt=1e-3, f_low=100.0, f_high=100.0), "greater than f_low = 100 Hz; got 100 Hz"),
        (dict(n_samples=1000, dt=1e-3, f_low=1.0, f_high=100.0, rms=1.0, amplitude=2.0), "either `rms` or `amplitude`"),
        (
            dict(n_samples=1000, dt=1e-3, f_low=1.0, f_high=100.0, rms=-1.0),
            "`rms` of multisine must be a number > 0; got -1",
        ),
    ],
)
def test_multisine_parameter_errors(kwargs, fragment):
    with pytest.raises(SignalError, match=re.escape(fragment)):
        multisine(**kwargs)


def test_multisine_limits_error():
    # the peak |x - offset| = 5 is reached on one side at least
    with pytest.raises(
        SignalError, match=r"^multisine spans \[1[5-9][.\d]*, 2[0-5][.\d]*\] but limits are \[16, 30\]\.$"
    ):
        multisine(1000, 1e-3, 1.0, 100.0, kind="schroeder", amplitude=5.0, offset=20.0, limits=(16, 30))


# ------------------------------------------------------------- property-based checks


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(min_value=16, max_value=3000),
    n_periods=st.integers(min_value=1, max_value=3),
    lo_frac=st.floats(min_value=0.0, max_value=0.9),
    width_frac=st.floats(min_value=0.05, max_value=1.0),
    seed=st.integers(min_value=0, max_value=2**32 - 1),
)
def test_band_confinement_property(n, n_periods, lo_frac, width_frac, seed):
    """Random sizes and bands (edges on or between lines): nothing leaks out of the band."""
    dt = 1e-3
    n -= n % n_periods
    nyq = 0.5 / dt
    lo = lo_frac * nyq
    hi = min(nyq, lo + width_frac * (nyq - lo) + 1e-9)
    assume(hi > lo)
    period = n // n_periods
    df = 1.0 / (period * dt)
    assume(np.floor(hi / df) >= max(1.0, np.ceil(lo / df)) and np.floor(hi / df) < period / 2)

    x = multisine(n, dt, lo, hi, n_periods=n_periods, seed=seed)
    spec = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(n, dt)
    assert spec[(f < lo - 1e-9) | (f > hi + 1e-9)].sum() / spec.sum() < 1e-10
    assert np.max(np.abs(x)) == pytest.approx(1.0, rel=1e-12)

    y = band_limited_random(n, dt, lo, hi, rms=1.0, seed=seed)
    spec = np.abs(np.fft.rfft(y)) ** 2
    assert spec[(f < lo) | (f > hi)].sum() / spec.sum() < 1e-10


# ----------------------------------------------------------------- regressions of the bug hunt
@pytest.mark.parametrize("make", [sine, triangle])
def test_tone_at_exactly_nyquist_is_refused(make):
    # regression: sine(50 Hz) at dt = 0.01 s sampled sin(pi k) = 0: an all-zero "excitation"
    with pytest.raises(SignalError, match=re.escape("must be below the Nyquist frequency 1/(2 dt) = 50 Hz; got 50 Hz")):
        make(50.0, duration=1.0, dt=0.01)
    x = make(49.0, duration=1.0, dt=0.01)
    assert np.ptp(x) > 0.1


@pytest.mark.parametrize("make", [sine, triangle])
def test_tone_overflow_is_refused_before_computing(make):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(SignalError, match=r"offset \+- amplitude = 1e\+308 \+- 1e\+308, beyond the largest float"):
            make(1.0, duration=1.0, dt=0.01, amplitude=1e308, offset=1e308)
    assert np.isfinite(make(1.0, duration=1.0, dt=0.01, amplitude=1e307, offset=1e307)).all()


def test_multisine_negative_seed_and_overflow():
    import warnings

    with pytest.raises(SignalError, match=r"`seed` of multisine must be an integer >= 0"):
        multisine(200, 0.01, 1.0, 10.0, seed=-1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(SignalError, match=r"largest float"):
            multisine(200, 0.01, 1.0, 10.0, amplitude=1e308, offset=1e308, seed=0)
