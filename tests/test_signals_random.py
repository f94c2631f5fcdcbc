"""Band-limited random noise and PRBS: band edges, maximal length, scaling, seeds."""

from __future__ import annotations

import re

import numpy as np
import pytest

from stageid import SignalError
from stageid.signals import band_limited_random, prbs


def _out_of_band_fraction(x: np.ndarray, dt: float, f_low: float, f_high: float) -> float:
    spec = np.abs(np.fft.rfft(x, axis=0)) ** 2
    f = np.fft.rfftfreq(x.shape[0], dt)
    out = (f < f_low) | (f > f_high)
    return float(spec[out].sum() / spec.sum())


# ---------------------------------------------------------------- band-limited random


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("n", [4000, 4001])  # even and odd lengths (Nyquist bin or not)
def test_band_limited_random_has_no_energy_outside_band(seed, n):
    dt, lo, hi = 2e-3, 3.0, 40.0
    x = band_limited_random(n, dt, lo, hi, rms=2.0, offset=20.0, seed=seed)
    # the offset is DC, outside the band by construction: remove it before the check
    frac = _out_of_band_fraction(x - 20.0, dt, lo, hi)
    assert frac < 1e-10
    # and the band itself is populated up to its edges
    spec = np.abs(np.fft.rfft(x - 20.0)) ** 2
    f = np.fft.rfftfreq(n, dt)
    assert spec[(f >= lo) & (f < lo + 2)].sum() > 0 and spec[(f > hi - 2) & (f <= hi)].sum() > 0


def test_band_limited_random_scaling_rms_and_peak():
    x = band_limited_random(5000, 1e-3, 0.0, 200.0, rms=0.5, seed=3)
    assert np.sqrt(np.mean(x**2)) == pytest.approx(0.5, rel=1e-12)
    y = band_limited_random(5000, 1e-3, 0.0, 200.0, amplitude=4.0, offset=-1.0, seed=3)
    assert np.max(np.abs(y + 1.0)) == pytest.approx(4.0, rel=1e-12)
    z = band_limited_random(5000, 1e-3, 0.0, 200.0, seed=3)  # default: peak 1
    assert np.max(np.abs(z)) == pytest.approx(1.0, rel=1e-12)
    # the same draw, only scaled differently
    np.testing.assert_allclose(x / 0.5 * np.sqrt(np.mean(z**2)), z, rtol=1e-12, atol=1e-15)


def test_band_limited_random_is_deterministic_with_seed():
    a = band_limited_random(1000, 1e-3, 1.0, 50.0, seed=11)
    b = band_limited_random(1000, 1e-3, 1.0, 50.0, seed=11)
    c = band_limited_random(1000, 1e-3, 1.0, 50.0, seed=12)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)


def test_band_limited_random_multichannel_independent_and_band_limited():
    x = band_limited_random(8000, 1e-3, 5.0, 100.0, rms=1.0, seed=5, n_channels=3)
    assert x.shape == (8000, 3)
    for j in range(3):
        assert _out_of_band_fraction(x[:, j], 1e-3, 5.0, 100.0) < 1e-10
        assert np.sqrt(np.mean(x[:, j] ** 2)) == pytest.approx(1.0, rel=1e-12)
    corr = np.corrcoef(x.T)
    # 8000 samples of ~1500 independent lines: |r| ~ 1/sqrt(1500) ~ 0.03; 0.15 is 5 sigma
    assert np.all(np.abs(corr[np.triu_indices(3, 1)]) < 0.15)
    assert band_limited_random(100, 1e-3, 5.0, 100.0, seed=5, n_channels=1).shape == (100, 1)


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        (dict(n_samples=1000, dt=1e-3, f_low=1.0, f_high=600.0), "Nyquist frequency 1/(2 dt) = 500 Hz; got 600 Hz"),
        (dict(n_samples=1000, dt=1e-3, f_low=50.0, f_high=10.0), "greater than f_low = 50 Hz; got 10 Hz"),
        (
            dict(n_samples=1, dt=1e-3, f_low=1.0, f_high=10.0),
            "`n_samples` of band-limited random signal must be an integer >= 2; got 1",
        ),
        (dict(n_samples=100, dt=1e-3, f_low=1.0, f_high=5.0), "at least one FFT line"),
        (dict(n_samples=100, dt=1e-3, f_low=1.0, f_high=50.0, rms=1.0, amplitude=1.0), "either `rms` or `amplitude`"),
        (
            dict(n_samples=100, dt=-1e-3, f_low=1.0, f_high=50.0),
            "`dt` of band-limited random signal must be a number > 0",
        ),
        (
            dict(n_samples=100, dt=1e-3, f_low=1.0, f_high=50.0, n_channels=0),
            "`n_channels` of band-limited random signal must be an integer >= 1; got 0",
        ),
    ],
)
def test_band_limited_random_parameter_errors(kwargs, fragment):
    with pytest.raises(SignalError, match=re.escape(fragment)):
        band_limited_random(**kwargs)


def test_band_limited_random_limits_error():
    with pytest.raises(SignalError, match=r"^band-limited random signal spans \[.*\] but limits are \[0, 40\]\.$"):
        band_limited_random(1000, 1e-3, 1.0, 100.0, amplitude=21.0, offset=20.0, seed=0, limits=(0, 40))
    x = band_limited_random(1000, 1e-3, 1.0, 100.0, amplitude=20.0, offset=20.0, seed=0, limits=(0, 40))
    assert x.min() >= 0.0 and x.max() <= 40.0


# ---------------------------------------------------------------------------- PRBS


@pytest.mark.parametrize("order", range(2, 13))
def test_mls_is_maximal_length(order):
    period = 2**order - 1
    x = prbs(2 * period, amplitude=0.5, order=order, offset=1.0)
    assert set(np.unique(x).tolist()) == {0.5, 1.5}
    bits = (x > 1.0).astype(int)
    # periodic with the full period ...
    assert np.array_equal(bits[:period], bits[period:])
    one = bits[:period]
    # ... and every nonzero order-bit pattern occurs exactly once per period, which is
    # the defining property of a maximum-length sequence (no shorter period possible)
    windows = np.stack([np.roll(one, -i)[:order] for i in range(period)])
    codes = windows @ (1 << np.arange(order))
    assert sorted(codes.tolist()) == list(range(1, 2**order))
    assert one.sum() == 2 ** (order - 1)
    # two-valued periodic autocorrelation of the +-1 sequence: period at lag 0, -1 else
    s = 2.0 * one - 1.0
    acf = np.real(np.fft.ifft(np.abs(np.fft.fft(s)) ** 2))
    np.testing.assert_allclose(acf, np.r_[period, -np.ones(period - 1)], atol=1e-9)


def test_mls_default_order_covers_n_samples_and_seed_shifts():
    x = prbs(1000)  # smallest period >= 1000 is 1023 (order 10)
    assert x.shape == (1000,)
    full = prbs(2046, order=10)
    assert np.array_equal(x, full[:1000])
    shifted = prbs(1023, order=10, seed=7)
    assert np.array_equal(shifted, prbs(1023, order=10, seed=7))  # deterministic
    # a seed only picks the start state: the result is a circular shift of the same MLS
    lags = [k for k in range(1023) if np.array_equal(np.roll(full[:1023], -k), shifted)]
    assert len(lags) == 1


def test_prbs_clock_period_holds_bits():
    x = prbs(3 * 31, order=5, clock_period=3)
    assert np.array_equal(x, np.repeat(prbs(31, order=5), 3))
    y = prbs(100, order=5, clock_period=3)  # 34 bits needed, 31 per period: wraps
    assert np.array_equal(y[:93], x) and np.array_equal(y[93:], x[:7])


def test_prbs_multichannel_shifted_copies_are_nearly_uncorrelated():
    order, n_ch = 7, 3
    period = 2**order - 1
    x = prbs(period, order=order, n_channels=n_ch)
    assert x.shape == (period, n_ch)
    shift = period // n_ch
    for j in range(1, n_ch):
        assert np.array_equal(x[:, j], np.roll(x[:, 0], -j * shift))
        # periodic cross-correlation at lag 0 of two shifted MLSs is -1/period
        assert np.mean(x[:, 0] * x[:, j]) == pytest.approx(-1.0 / period, abs=1e-12)
    assert np.array_equal(prbs(period, order=order, n_channels=1)[:, 0], x[:, 0])


def test_random_binary_values_and_seed():
    x = prbs(500, amplitude=2.0, method="random", seed=4, clock_period=5)
    assert set(np.unique(x).tolist()) == {-2.0, 2.0}
    assert np.all(x.reshape(100, 5) == x.reshape(100, 5)[:, :1])  # held 5 samples
    assert np.array_equal(x, prbs(500, amplitude=2.0, method="random", seed=4, clock_period=5))
    assert not np.array_equal(x, prbs(500, amplitude=2.0, method="random", seed=5, clock_period=5))
    y = prbs(500, method="random", seed=4, n_channels=2)
    assert y.shape == (500, 2) and not np.array_equal(y[:, 0], y[:, 1])


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        (dict(n_samples=100, order=1), "`order` of prbs must be an integer >= 2; got 1"),
        (dict(n_samples=100, order=33), "`order` of prbs must be an integer in 2..32; got 33"),
        (dict(n_samples=100, method="random", order=5), "applies to method='mls' only"),
        (dict(n_samples=100, clock_period=0), "`clock_period` of prbs must be an integer >= 1; got 0"),
        (dict(n_samples=100, method="gold"), "'mls', 'random'; got 'gold'"),
        (dict(n_samples=100, amplitude=0.0), "`amplitude` of prbs must be a number > 0; got 0"),
        (dict(n_samples=1), "`n_samples` of prbs must be an integer >= 2; got 1"),
        (dict(n_samples=100, order=32, n_channels=2), "would generate"),
    ],
)
def test_prbs_parameter_errors(kwargs, fragment):
    with pytest.raises(SignalError, match=re.escape(fragment)):
        prbs(**kwargs)


def test_prbs_limits_error():
    with pytest.raises(SignalError, match=re.escape("prbs spans [-2, 2] but limits are [-1, 1].")):
        prbs(100, amplitude=2.0, limits=(-1, 1))


# ----------------------------------------------------------------- regressions of the bug hunt
@pytest.mark.parametrize(
    "make",
    [
        lambda seed: prbs(100, seed=seed),
        lambda seed: prbs(100, method="random", seed=seed),
        lambda seed: band_limited_random(100, 0.01, 1.0, 10.0, seed=seed),
    ],
)
def test_negative_seed_is_a_signal_error(make):
    # regression: numpy's "expected non-negative integer" ValueError leaked out
    with pytest.raises(SignalError, match=r"`seed` of .* must be an integer >= 0 or a numpy Generator; got -1\.$"):
        make(-1)
    assert make(0).shape == (100,)


@pytest.mark.parametrize(
    "make",
    [
        lambda: prbs(100, amplitude=1e308, offset=1e308),
        lambda: band_limited_random(100, 0.01, 1.0, 10.0, amplitude=1e308, offset=1e308, seed=0),
        lambda: band_limited_random(100, 0.01, 1.0, 10.0, rms=1e308, seed=0),
    ],
)
def test_overflowing_levels_raise_before_any_warning(make):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an overflow RuntimeWarning would fail here
        with pytest.raises(SignalError, match=r"largest float"):
            make()
