"""Periodic excitations: sine, triangle and multisines (random-phase and Schroeder).

A multisine puts all its power on lines of the FFT grid of its period, so a record of a
whole number of periods has no leakage and each excited line can be read directly from
the FFT of the input and the output.
"""

from __future__ import annotations

import numpy as np

from .._errors import SignalError
from ._common import (
    add_offset,
    check_choice,
    check_dt,
    check_finite,
    check_int,
    check_limits,
    check_n_channels,
    check_n_samples,
    check_nonnegative,
    check_nyquist,
    check_positive,
    check_seed,
    check_span,
    n_from_duration,
    scale_to,
)

__all__ = ["sine", "triangle", "multisine", "multisine_lines"]

_MULTISINE_KINDS = ("random-phase", "schroeder")


def triangle_wave(cycles: np.ndarray) -> np.ndarray:
    """Unit triangle in phase with ``sin(2 pi cycles)``: 0 at 0, +1 at 1/4, -1 at 3/4.

    Shared with the hysteresis drives (:mod:`stageid.signals.hysteresis`).
    """
    u = np.mod(cycles + 0.25, 1.0)
    return 1.0 - 4.0 * np.abs(u - 0.5)


def _check_periodic(
    name: str, freq: float, duration: float, dt: float, amplitude: float, offset: float
) -> tuple[float, int, float, float, float]:
    step = check_dt(dt, name)
    n = n_from_duration(duration, step, name)
    f = check_positive(freq, "freq", name)
    check_nyquist(f, "freq", step, name, strict=True)
    amp = check_positive(amplitude, "amplitude", name)
    off = check_finite(offset, "offset", name)
    check_span(off, amp, name)
    return step, n, f, amp, off


def sine(
    freq: float,
    duration: float,
    dt: float,
    amplitude: float = 1.0,
    offset: float = 0.0,
    phase: float = 0.0,
    limits: tuple[float, float] | None = None,
) -> np.ndarray:
    """Sine ``offset + amplitude * sin(2 pi freq t + phase)``.

    Parameters
    ----------
    freq : float
        Frequency in Hz, ``0 < freq < 1 / (2 dt)`` (at Nyquist a sine samples to a constant).
    duration : float
        Length in seconds; ``round(duration / dt)`` samples at ``t = k dt``.
    dt : float
        Sample time in seconds.
    amplitude : float, default 1.0
        Peak value about ``offset``, > 0.
    offset : float, default 0.0
        Centre value.
    phase : float, default 0.0
        Phase in radians.
    limits : (float, float), optional
        Allowed range ``(lo, hi)`` of the signal.

    Returns
    -------
    ndarray of shape (n_samples,)
        The sine.

    Raises
    ------
    SignalError
        If a parameter is out of range or the signal leaves ``limits``.

    Examples
    --------
    Cao & Chen's validation input, a 1 Hz sine:

    >>> from stageid.signals import sine
    >>> u = sine(1.0, duration=2.0, dt=0.25, amplitude=10.0, offset=20.0)
    >>> u.round(6).tolist()
    [20.0, 30.0, 20.0, 10.0, 20.0, 30.0, 20.0, 10.0]
    """
    name = "sine"
    step, n, f, amp, off = _check_periodic(name, freq, duration, dt, amplitude, offset)
    ph = check_finite(phase, "phase", name)
    t = np.arange(n, dtype=float) * step
    x = off + amp * np.sin(2.0 * np.pi * f * t + ph)
    check_limits(x, limits, name)
    return x


def triangle(
    freq: float,
    duration: float,
    dt: float,
    amplitude: float = 1.0,
    offset: float = 0.0,
    phase: float = 0.0,
    limits: tuple[float, float] | None = None,
) -> np.ndarray:
    """Symmetric triangle wave in phase with :func:`sine`.

    With ``phase = 0`` it starts at ``offset`` rising, peaks at ``offset + amplitude``
    at ``t = 1 / (4 freq)``, passes ``offset`` at ``1 / (2 freq)`` and reaches
    ``offset - amplitude`` at ``3 / (4 freq)``: straight lines of slope
    ``+- 4 amplitude freq`` in between.

    Parameters
    ----------
    freq : float
        Frequency in Hz, ``0 < freq < 1 / (2 dt)``.
    duration : float
        Length in seconds; ``round(duration / dt)`` samples at ``t = k dt``.
    dt : float
        Sample time in seconds.
    amplitude : float, default 1.0
        Peak value about ``offset``, > 0.
    offset : float, default 0.0
        Centre value.
    phase : float, default 0.0
        Phase in radians (``2 pi`` is one period).
    limits : (float, float), optional
        Allowed range ``(lo, hi)`` of the signal.

    Returns
    -------
    ndarray of shape (n_samples,)
        The triangle wave.

    Raises
    ------
    SignalError
        If a parameter is out of range or the signal leaves ``limits``.

    Examples
    --------
    The 1 Hz, 3 um triangle of the hysteresis-compensation test:

    >>> from stageid.signals import triangle
    >>> triangle(1.0, duration=1.0, dt=0.125, amplitude=3.0).tolist()
    [0.0, 1.5, 3.0, 1.5, 0.0, -1.5, -3.0, -1.5]
    """
    name = "triangle"
    step, n, f, amp, off = _check_periodic(name, freq, duration, dt, amplitude, offset)
    ph = check_finite(phase, "phase", name)
    cycles = np.arange(n, dtype=float) * step * f + ph / (2.0 * np.pi)
    x = off + amp * triangle_wave(cycles)
    check_limits(x, limits, name)
    return x


def multisine_lines(n_samples: int, dt: float, f_low: float, f_high: float, n_periods: int = 1) -> np.ndarray:
    """FFT-line indices (of one period) that :func:`multisine` excites.

    Lines are ``k / (N dt)`` with ``N = n_samples / n_periods`` samples per period, for
    every ``k`` with ``f_low <= k / (N dt) <= f_high`` and ``0 < k < N / 2`` (DC and the
    Nyquist line are never excited: a sine has no DC, and at Nyquist its amplitude would
    depend on its phase).

    Parameters
    ----------
    n_samples, dt, f_low, f_high, n_periods
        As in :func:`multisine`.

    Returns
    -------
    ndarray of int, shape (n_lines,)
        Line indices ``k`` on the grid of one period (multiply by ``n_periods`` for the
        grid of the whole record).

    Raises
    ------
    SignalError
        If parameters are invalid or no line falls in the band.

    Examples
    --------
    >>> from stageid.signals import multisine_lines
    >>> multisine_lines(1000, 1e-3, 1.0, 5.0).tolist()
    [1, 2, 3, 4, 5]
    """
    name = "multisine"
    n = check_n_samples(n_samples, name)
    step = check_dt(dt, name)
    p = check_int(n_periods, "n_periods", name, 1)
    if n % p:
        raise SignalError(f"`n_samples` of {name} must be a multiple of n_periods = {p}; got {n}.")
    period = n // p
    if period < 4:
        raise SignalError(f"{name} needs at least 4 samples per period; got {period} (n_samples {n} / n_periods {p}).")
    lo = check_nonnegative(f_low, "f_low", name)
    hi = check_positive(f_high, "f_high", name)
    if hi <= lo:
        raise SignalError(f"`f_high` of {name} must be greater than f_low = {lo:g} Hz; got {hi:g} Hz.")
    check_nyquist(hi, "f_high", step, name)
    df = 1.0 / (period * step)
    # a tiny slack so that band edges given as exact line frequencies are included
    k_lo = max(1, int(np.ceil(lo / df - 1e-9)))
    k_hi = min((period - 1) // 2, int(np.floor(hi / df + 1e-9)))
    if k_hi < k_lo:
        raise SignalError(
            f"{name} needs at least one line k/(N dt) (spacing {df:g} Hz, N = {period} "
            f"samples per period) in [{lo:g}, {hi:g}] Hz below Nyquist; got none."
        )
    return np.arange(k_lo, k_hi + 1)


def multisine(
    n_samples: int,
    dt: float,
    f_low: float,
    f_high: float,
    kind: str = "random-phase",
    amplitude: float | None = None,
    rms: float | None = None,
    seed: int | np.random.Generator | None = None,
    n_periods: int = 1,
    offset: float = 0.0,
    n_channels: int | None = None,
    limits: tuple[float, float] | None = None,
) -> np.ndarray:
    """Sum of equal-amplitude sines on the FFT lines of one period inside a band.

    ``x(t) = offset + c * sum_k cos(2 pi k t / (N dt) + phi_k)`` over the lines
    ``k`` returned by :func:`multisine_lines` (``N = n_samples / n_periods``), so the
    spectrum of a whole number of periods is exactly zero off those lines.  Phases:

    * ``"random-phase"``: ``phi_k`` uniform on ``[0, 2 pi)`` from ``seed``;
    * ``"schroeder"``: ``phi_k = -pi j (j - 1) / F`` for the ``j``-th of ``F`` lines
      (Schroeder 1970), deterministic, with a low crest factor for a flat spectrum.

    ``c`` is chosen so the peak ``max |x - offset|`` equals ``amplitude`` (default 1)
    or the RMS equals ``rms``.

    Parameters
    ----------
    n_samples : int
        Total number of samples, a multiple of ``n_periods``.
    dt : float
        Sample time in seconds.
    f_low, f_high : float
        Band in Hz, ``0 <= f_low < f_high <= 1 / (2 dt)``.
    kind : {"random-phase", "schroeder"}, default "random-phase"
        Phase choice, see above.
    amplitude : float, optional
        Peak value about ``offset``; exclusive with ``rms``.  Default 1 if neither.
    rms : float, optional
        RMS value about ``offset``.
    seed : int or numpy.random.Generator, optional
        Seed of the random phases (unused for ``"schroeder"``).
    n_periods : int, default 1
        Number of identical periods in the record.
    offset : float, default 0.0
        Centre value.
    n_channels : int, optional
        ``None`` returns shape (n_samples,); an int returns (n_samples, n_channels):
        independent random phases per channel for ``"random-phase"``, and for
        ``"schroeder"`` the same period circularly shifted by ``j * N // n_channels``
        samples in channel ``j``.
    limits : (float, float), optional
        Allowed range ``(lo, hi)`` of the signal.

    Returns
    -------
    ndarray of shape (n_samples,) or (n_samples, n_channels)
        The multisine.

    Raises
    ------
    SignalError
        If parameters are invalid, no line lies in the band, or the signal leaves
        ``limits``.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.signals import multisine, crest_factor
    >>> u = multisine(2000, 1e-3, 1.0, 100.0, kind="schroeder", amplitude=5.0)
    >>> u.shape, round(float(np.abs(u).max()), 6)
    ((2000,), 5.0)
    >>> bool(crest_factor(u) < 2.0)
    True
    """
    name = "multisine"
    lines = multisine_lines(n_samples, dt, f_low, f_high, n_periods)
    kind = check_choice(kind, "kind", name, _MULTISINE_KINDS)
    off = check_finite(offset, "offset", name)
    n = int(n_samples)
    channels = check_n_channels(n_channels, name, n)
    n_ch = 1 if channels is None else channels
    period = n // int(n_periods)

    n_lines = lines.size
    if kind == "random-phase":
        phases = np.random.default_rng(check_seed(seed, name)).uniform(0.0, 2.0 * np.pi, size=(n_lines, n_ch))
    else:
        j = np.arange(1, n_lines + 1)
        phases = np.repeat((-np.pi * j * (j - 1) / n_lines)[:, None], n_ch, axis=1)
    spectrum = np.zeros((period // 2 + 1, n_ch), dtype=complex)
    spectrum[lines, :] = np.exp(1j * phases)
    one_period = np.fft.irfft(spectrum, n=period, axis=0)
    if kind == "schroeder" and n_ch > 1:
        shift = period // n_ch
        one_period = np.stack([np.roll(one_period[:, 0], j * shift) for j in range(n_ch)], axis=1)
    x = np.tile(one_period, (int(n_periods), 1))
    x = add_offset(scale_to(x, rms, amplitude, name), off, name)
    if channels is None:
        x = x[:, 0]
    check_limits(x, limits, name)
    return x
