"""Broadband random excitations: band-limited Gaussian noise and binary sequences (PRBS).

All of them are reproducible: pass ``seed`` (an int, or a ``numpy.random.Generator``) and
the same signal comes back; they draw from ``np.random.default_rng(seed)`` only.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._errors import SignalError
from ._common import (
    add_offset,
    as_channels,
    check_band,
    check_choice,
    check_dt,
    check_finite,
    check_int,
    check_n_channels,
    check_n_samples,
    check_seed,
    check_swing,
    scale_to,
)

__all__ = ["band_limited_random", "prbs"]

_PRBS_METHODS = ("mls", "random")
_MAX_ORDER = 32  # scipy.signal.max_len_seq has primitive taps up to 32 bits
_MAX_GENERATED_BITS = 2**26  # memory guard: shifted channels of a long MLS


def band_limited_random(
    n_samples: int,
    dt: float,
    f_low: float,
    f_high: float,
    rms: float | None = None,
    amplitude: float | None = None,
    seed: int | np.random.Generator | None = None,
    offset: float = 0.0,
    n_channels: int | None = None,
    limits: tuple[float, float] | None = None,
) -> np.ndarray:
    """Gaussian noise with no energy outside the band ``[f_low, f_high]``.

    White Gaussian noise is transformed with the real FFT, every line ``k / (n dt)``
    outside ``[f_low, f_high]`` (bounds included in the band) is set to zero, and the
    result is transformed back, so the record has no spectral energy outside the band
    (to rounding, about 1e-16 relative).  The record is then scaled to the requested RMS
    or peak value and ``offset`` is added.

    Parameters
    ----------
    n_samples : int
        Number of samples, >= 2.
    dt : float
        Sample time in seconds.
    f_low, f_high : float
        Band edges in Hz, ``0 <= f_low < f_high <= 1 / (2 dt)``.  With ``f_low = 0``
        the DC line is random too (the mean is not exactly ``offset``).
    rms : float, optional
        RMS value of the noise (without ``offset``); exclusive with ``amplitude``.
    amplitude : float, optional
        Peak value ``max(abs(x - offset))``; the default when neither is given is
        ``amplitude=1``.
    seed : int or numpy.random.Generator, optional
        Seed of ``np.random.default_rng``; ``None`` draws fresh entropy.
    offset : float, default 0.0
        Added after scaling.
    n_channels : int, optional
        ``None`` returns shape (n_samples,); an int returns independent channels of
        shape (n_samples, n_channels), each scaled separately.
    limits : (float, float), optional
        Allowed range ``(lo, hi)`` of the signal.

    Returns
    -------
    ndarray of shape (n_samples,) or (n_samples, n_channels)
        The noise.

    Raises
    ------
    SignalError
        If parameters are invalid, no FFT line falls in the band, or the signal leaves
        ``limits``.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.signals import band_limited_random
    >>> u = band_limited_random(4000, 2e-3, 1.0, 100.0, rms=5.0, offset=20.0, seed=1)
    >>> u.shape, round(float(np.sqrt(np.mean((u - 20.0) ** 2))), 6)
    ((4000,), 5.0)
    """
    name = "band-limited random signal"
    n = check_n_samples(n_samples, name)
    step = check_dt(dt, name)
    lo, hi = check_band(f_low, f_high, ("f_low", "f_high"), step, name)
    off = check_finite(offset, "offset", name)
    channels = check_n_channels(n_channels, name, n)
    n_ch = 1 if channels is None else channels

    x = _band_noise(n, step, lo, hi, n_ch, np.random.default_rng(check_seed(seed, name)), name)
    return as_channels(add_offset(scale_to(x, rms, amplitude, name), off, name), channels, limits, name)


def _band_noise(
    n: int, step: float, lo: float, hi: float, n_ch: int, rng: np.random.Generator, name: str
) -> np.ndarray:
    """White Gaussian noise (n, n_ch) with every FFT line ``k / (n step)`` outside ``[lo, hi]`` set
    to zero; SignalError when no line falls inside."""
    freqs = np.fft.rfftfreq(n, step)
    in_band = (freqs >= lo) & (freqs <= hi)
    if not np.any(in_band):
        raise SignalError(
            f"{name} needs at least one FFT line k/(n dt) (spacing {1 / (n * step):g} Hz) "
            f"in [{lo:g}, {hi:g}] Hz; got none (use more samples)."
        )
    spectrum = np.fft.rfft(rng.standard_normal((n, n_ch)), axis=0)
    spectrum[~in_band, :] = 0.0
    return np.fft.irfft(spectrum, n=n, axis=0)


def prbs(
    n_samples: int,
    amplitude: float = 1.0,
    seed: int | np.random.Generator | None = None,
    n_channels: int | None = None,
    order: int | None = None,
    clock_period: int = 1,
    method: str = "mls",
    offset: float = 0.0,
    limits: tuple[float, float] | None = None,
) -> np.ndarray:
    """Pseudo-random binary sequence taking the values ``offset +- amplitude``.

    Two constructions (``method``):

    * ``"mls"`` (default): a maximum-length sequence of a linear-feedback shift register
      of ``order`` bits (``scipy.signal.max_len_seq``, primitive feedback polynomials).
      Its period is ``2**order - 1`` bits, each nonzero ``order``-bit pattern occurs
      exactly once per period, so one period has ``2**(order-1)`` high and
      ``2**(order-1) - 1`` low bits and its periodic autocorrelation is two-valued.
      ``seed`` only chooses the (nonzero) initial register state, i.e. a circular shift;
      ``seed=None`` uses the all-ones state (deterministic).
    * ``"random"``: independent fair coin flips per clock period (not periodic);
      ``seed=None`` draws fresh entropy.

    Each bit is held for ``clock_period`` samples, which moves the excitation towards
    low frequencies (first spectral null at ``1 / (clock_period dt)``).

    Parameters
    ----------
    n_samples : int
        Number of samples, >= 2.
    amplitude : float, default 1.0
        The sequence is ``offset + amplitude`` (bit 1) or ``offset - amplitude`` (bit 0).
    seed : int or numpy.random.Generator, optional
        See above.
    n_channels : int, optional
        ``None`` returns shape (n_samples,); an int returns (n_samples, n_channels).
        For ``"mls"`` channel ``j`` is the same sequence circularly shifted by
        ``j * floor(period / n_channels)`` bits (shifted MLSs are nearly uncorrelated:
        periodic cross-correlation ``-1 / period``); for ``"random"`` the channels are
        independent.
    order : int, optional
        Register length of ``"mls"``, 2..32.  Default: the smallest order whose period
        ``(2**order - 1) * clock_period`` covers ``n_samples``.  For a periodic
        experiment choose ``n_samples`` a multiple of the period; with more samples than
        one period the sequence repeats, with fewer it is truncated.
    clock_period : int, default 1
        Samples per bit, >= 1.
    method : {"mls", "random"}, default "mls"
        Construction, see above.
    offset : float, default 0.0
        Centre value.
    limits : (float, float), optional
        Allowed range ``(lo, hi)`` of the signal.

    Returns
    -------
    ndarray of shape (n_samples,) or (n_samples, n_channels)
        The binary sequence.

    Raises
    ------
    SignalError
        If parameters are invalid (``order`` outside 2..32, ``clock_period < 1``,
        ``order`` given with ``method="random"``, ...) or the signal leaves ``limits``.

    Examples
    --------
    One period of a 5-bit MLS, values +-2:

    >>> import numpy as np
    >>> from stageid.signals import prbs
    >>> u = prbs(31, amplitude=2.0, order=5)
    >>> sorted(set(u.tolist())), int((u > 0).sum()), int((u < 0).sum())
    ([-2.0, 2.0], 16, 15)
    >>> prbs(1000, n_channels=3, seed=0).shape
    (1000, 3)
    """
    name = "prbs"
    n = check_n_samples(n_samples, name)
    amp, off = check_swing(amplitude, offset, name)
    seed = check_seed(seed, name)
    method = check_choice(method, "method", name, _PRBS_METHODS)
    channels = check_n_channels(n_channels, name, n)
    hold = check_int(clock_period, "clock_period", name, 1)
    n_bits = -(-n // hold)  # bits needed to cover n samples
    bits = _prbs_bits(method, n_bits, 1 if channels is None else channels, order, seed, n)
    x = off + amp * (2.0 * np.repeat(bits, hold, axis=0)[:n].astype(float) - 1.0)
    return as_channels(x, channels, limits, name)


def _prbs_bits(method: str, n_bits: int, n_ch: int, order: Any, seed: Any, n: int) -> np.ndarray:
    """``n_bits`` bits per channel: independent coin flips, or a shifted maximum-length sequence."""
    if method == "mls":
        return _mls_bits(n_bits, n_ch, order, seed, n)
    if order is not None:
        raise SignalError(f"`order` of prbs applies to method='mls' only; got order={order!r} with method='random'.")
    return np.random.default_rng(seed).integers(0, 2, size=(n_bits, n_ch))


def _mls_bits(n_bits: int, n_ch: int, order: Any, seed: Any, n: int) -> np.ndarray:
    """``n_bits`` bits per channel of one maximum-length sequence, channels shifted by period / n_ch."""
    name = "prbs"
    if order is None:
        m = 2
        while (2**m - 1) < n_bits and m < _MAX_ORDER:
            m += 1
    else:
        m = check_int(order, "order", name, 2)
        if m > _MAX_ORDER:
            raise SignalError(f"`order` of prbs must be an integer in 2..32; got {m}.")
    period = 2**m - 1
    if seed is None:
        state = np.ones(m, dtype=np.int8)
    else:
        start = int(np.random.default_rng(seed).integers(1, 2**m))
        state = np.array([(start >> i) & 1 for i in range(m)], dtype=np.int8)
    shift = period // n_ch
    # bits actually read: n_bits from each of n_ch shifted starts (at most one period)
    length = min(period, n_bits + (n_ch - 1) * shift)
    if length > _MAX_GENERATED_BITS:
        raise SignalError(
            f"prbs of order {m} with {n_ch} channels would generate {length} register "
            f"bits (limit {_MAX_GENERATED_BITS}); got too large an `order` for "
            f"n_samples={n} (use a smaller order or the default)."
        )
    from scipy.signal import max_len_seq  # imported here: scipy.signal is slow to import

    base, _ = max_len_seq(m, state=state, length=length)
    idx = np.arange(n_bits)
    bits = np.stack([base[(idx + j * shift) % period] for j in range(n_ch)], axis=1)
    return bits
