"""Shared helpers of :mod:`stageid.signals`: the time grid, parameter checks, limits.

Sampling convention used by every generator
-------------------------------------------
A signal of ``duration`` seconds sampled every ``dt`` seconds has
``n_samples = round(duration / dt)`` samples at ``t_k = k * dt`` for
``k = 0, ..., n_samples - 1`` (the end point ``t = duration`` is *not* included, as in
``np.arange(0, duration, dt)``).  A whole number of periods therefore gives an exactly
periodic record, which is what FFT-based analysis wants.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import checks
from .._errors import SignalError
from ..runtime.resources import require_memory

__all__ = ["time_vector", "crest_factor", "check_limits"]

# Relative slack when comparing a generated signal with its limits: sin() may return
# 1 + 1 ulp, and offset + amplitude may round; a few ulps must not raise.
_LIMIT_RTOL = 1e-12


def time_vector(n_samples: int, dt: float) -> np.ndarray:
    """Sample instants ``t_k = k * dt`` of a record of ``n_samples`` samples.

    Parameters
    ----------
    n_samples : int
        Number of samples, at least 2.
    dt : float
        Sample time in seconds, > 0.

    Returns
    -------
    t : ndarray of shape (n_samples,)
        Time in seconds, starting at 0.

    Raises
    ------
    SignalError
        If ``n_samples`` < 2 or ``dt`` <= 0.

    Examples
    --------
    >>> from stageid.signals import time_vector
    >>> time_vector(4, 0.5)
    array([0. , 0.5, 1. , 1.5])
    """
    n = check_n_samples(n_samples, "time_vector")
    step = check_dt(dt, "time_vector")
    return np.arange(n, dtype=float) * step


def crest_factor(signal: np.ndarray) -> float:
    """Peak-to-RMS ratio of the zero-mean part of a signal, ``max|x - mean| / rms``.

    Parameters
    ----------
    signal : array_like of shape (n_samples,)
        The signal.

    Returns
    -------
    float
        Crest factor (sqrt(2) for a sine, 1 for a binary sequence).

    Raises
    ------
    SignalError
        If the signal is not 1-D with at least 2 samples or is constant.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.signals import crest_factor
    >>> round(crest_factor(np.sin(2 * np.pi * np.arange(100) / 100)), 6)
    1.414214
    """
    x = np.asarray(signal, dtype=float)
    if x.ndim != 1 or x.size < 2:
        raise SignalError(f"crest_factor expects a 1-D signal with at least 2 samples; got shape {x.shape}.")
    x = x - x.mean()
    rms = float(np.sqrt(np.mean(x**2)))
    if rms == 0.0:
        raise SignalError("crest_factor of a constant signal is undefined; got a constant signal.")
    return float(np.max(np.abs(x)) / rms)


def check_limits(signal: np.ndarray, limits: tuple[float, float] | None, name: str, unit: str = "") -> None:
    """Raise :class:`SignalError` if ``signal`` leaves ``limits = (lo, hi)``.

    Signals are never clipped silently: a generator asked for a signal that would leave
    the actuator's range raises instead, naming the range it would span.

    Parameters
    ----------
    signal : ndarray of shape (n_samples,) or (n_samples, n_channels)
        The generated signal.
    limits : (float, float) or None
        Allowed closed range ``[lo, hi]``; ``None`` checks nothing.
    name : str
        Name of the generator, used in the message.
    unit : str, optional
        Unit appended to the numbers in the message, e.g. ``"um"``.

    Raises
    ------
    SignalError
        If ``limits`` is malformed or the signal spans beyond it, e.g.
        "chirp spans [-1, 41] um but limits are [0, 40] um."

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.signals import check_limits
    >>> check_limits(np.array([0.0, 40.0]), (0, 40), "chirp")  # inside: no error
    >>> check_limits(np.array([-1.0, 41.0]), (0, 40), "chirp", "um")
    Traceback (most recent call last):
    ...
    stageid._errors.SignalError: chirp spans [-1, 41] um but limits are [0, 40] um.
    """
    if limits is None:
        return
    lo, hi = _parse_limits(limits, name)
    x = np.asarray(signal, dtype=float)
    x_lo, x_hi = float(np.min(x)), float(np.max(x))
    slack = _LIMIT_RTOL * max(abs(lo), abs(hi), hi - lo, 1.0)
    if x_lo < lo - slack or x_hi > hi + slack:
        u = f" {unit}" if unit else ""
        raise SignalError(f"{name} spans [{x_lo:.6g}, {x_hi:.6g}]{u} but limits are [{lo:.6g}, {hi:.6g}]{u}.")


def as_channels(x: np.ndarray, channels: int | None, limits: tuple[float, float] | None, name: str) -> np.ndarray:
    """A generator's output ``x`` (n_samples, n_channels): 1-D when no channel count was asked
    (``channels`` None), after :func:`check_limits`."""
    if channels is None:
        x = x[:, 0]
    check_limits(x, limits, name)
    return x


def _parse_limits(limits: Any, name: str) -> tuple[float, float]:
    try:
        lo, hi = limits
        lo, hi = float(lo), float(hi)
    except (TypeError, ValueError):
        raise SignalError(f"`limits` of {name} must be a pair (lo, hi) of numbers; got {limits!r}.") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or not lo < hi:
        raise SignalError(f"`limits` of {name} must be finite with lo < hi; got ({lo:g}, {hi:g}).")
    return lo, hi


# --------------------------------------------------------------------------------------
# Parameter checks: the package's one rule per kind of setting (stageid.checks), raising
# SignalError so callers of the generators keep catching one type.
# --------------------------------------------------------------------------------------


def check_positive(value: Any, param: str, name: str) -> float:
    """Return ``value`` as float if it is finite and > 0, else raise SignalError."""
    return checks.check_real(value, param, name, low=0.0, closed="right", error=SignalError)


def check_nonnegative(value: Any, param: str, name: str) -> float:
    """Return ``value`` as float if it is finite and >= 0, else raise SignalError."""
    return checks.check_real(value, param, name, low=0.0, error=SignalError)


def check_finite(value: Any, param: str, name: str) -> float:
    """Return ``value`` as float if it is a finite real number, else raise SignalError."""
    return checks.check_real(value, param, name, error=SignalError)


def check_int(value: Any, param: str, name: str, minimum: int) -> int:
    """Return ``value`` as int if it is an integer >= ``minimum``, else raise SignalError."""
    return checks.check_integer(value, param, name, low=minimum, error=SignalError)


def check_dt(dt: Any, name: str) -> float:
    """Return the sample time if it is finite and > 0, else raise SignalError."""
    return check_positive(dt, "dt", name)


def check_n_samples(n_samples: Any, name: str) -> int:
    """Return ``n_samples`` if it is an integer >= 2 that fits in memory, else raise SignalError.

    Raises :class:`~stageid.ResourceError` when the record would not fit in memory.
    """
    return require_samples(check_int(n_samples, "n_samples", name, 2), name)


#: Bytes per sample a generator may hold at once: the signal, its time axis and the
#: temporaries of the synthesis (phases, spectra, filter states).
BYTES_PER_SAMPLE = 128


def require_samples(n: int, name: str, n_channels: int = 1) -> int:
    """``n``, after refusing with :class:`~stageid.ResourceError` a record that would not fit in memory."""
    on = f" on {n_channels} channels" if n_channels > 1 else ""
    require_memory(float(n) * n_channels * BYTES_PER_SAMPLE, f"{name} with {n} samples{on}")
    return n


def n_from_duration(duration: Any, dt: float, name: str) -> int:
    """Number of samples ``round(duration / dt)`` of a record; at least 2."""
    d = check_positive(duration, "duration", name)
    ratio = d / dt
    if not ratio >= 2:
        raise SignalError(
            f"{name} needs at least 2 samples (duration / dt >= 2); "
            f"got duration {d:g} s with dt {dt:g} s ({ratio:.3g} samples)."
        )
    if not math.isfinite(ratio):
        raise SignalError(f"{name} with duration {d:g} s and dt {dt:g} s would have infinitely many samples.")
    return require_samples(int(round(ratio)), name)


def check_nyquist(freq: float, param: str, dt: float, name: str, strict: bool = False) -> None:
    """Raise SignalError if ``freq`` (Hz) exceeds the Nyquist frequency ``1 / (2 dt)``.

    Equality is allowed for the end of a band (Shakir & Kim sweep up to exactly 2500 Hz at
    5 kHz); ``strict=True`` also refuses it, for a single tone, which sampled at exactly
    Nyquist is ``sin(pi k + phase)``: all zeros at phase 0.
    """
    nyquist = 0.5 / dt
    if strict and freq >= nyquist * (1 - 1e-12):
        raise SignalError(
            f"`{param}` of {name} must be below the Nyquist frequency 1/(2 dt) = "
            f"{nyquist:g} Hz; got {freq:g} Hz (a tone at Nyquist samples to a constant)."
        )
    if freq > nyquist * (1 + 1e-12):
        raise SignalError(
            f"`{param}` of {name} must be at most the Nyquist frequency 1/(2 dt) = {nyquist:g} Hz; got {freq:g} Hz."
        )


def check_seed(seed: Any, name: str) -> Any:
    """``None``, a ``numpy.random.Generator`` or an integer >= 0, else raise SignalError."""
    return checks.check_seed(seed, "seed", name, error=SignalError)


_FLOAT_MAX = float(np.finfo(float).max)


def check_span(offset: float, amplitude: float, name: str) -> None:
    """Raise SignalError unless ``offset +- amplitude`` is finite in float64 (checked before computing)."""
    if amplitude > _FLOAT_MAX - abs(offset):
        raise SignalError(
            f"{name} would span offset +- amplitude = {offset:g} +- {amplitude:g}, beyond the "
            f"largest float ({_FLOAT_MAX:.3g}); expected |offset| + amplitude <= {_FLOAT_MAX:.3g}."
        )


def check_swing(amplitude: Any, offset: Any, name: str) -> tuple[float, float]:
    """``(amplitude, offset)`` of a signal that swings ``offset +- amplitude``: ``amplitude > 0``,
    ``offset`` finite, the span finite; else SignalError."""
    amp = check_positive(amplitude, "amplitude", name)
    off = check_finite(offset, "offset", name)
    check_span(off, amp, name)
    return amp, off


def check_band(low: Any, high: Any, params: tuple[str, str], dt: float, name: str) -> tuple[float, float]:
    """``(low, high)`` in Hz with ``0 <= low < high <= 1 / (2 dt)``, else SignalError naming ``params``."""
    lo = check_nonnegative(low, params[0], name)
    hi = check_positive(high, params[1], name)
    if hi <= lo:
        raise SignalError(f"`{params[1]}` of {name} must be greater than {params[0]} = {lo:g} Hz; got {hi:g} Hz.")
    check_nyquist(hi, params[1], dt, name)
    return lo, hi


def check_tone(freq: Any, dt: float, name: str) -> float:
    """The frequency of a single tone in Hz: ``0 < freq < 1 / (2 dt)``, else SignalError."""
    f = check_positive(freq, "freq", name)
    check_nyquist(f, "freq", dt, name, strict=True)
    return f


def add_offset(x: np.ndarray, offset: float, name: str) -> np.ndarray:
    """``x + offset``, raising SignalError instead of overflowing to inf."""
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if not math.isfinite(peak) or peak > _FLOAT_MAX - abs(offset):
        raise SignalError(
            f"{name} would reach {peak:g} about offset {offset:g}, beyond the largest float "
            f"({_FLOAT_MAX:.3g}); expected a smaller amplitude, rms or offset."
        )
    return x + offset


def check_choice(value: Any, param: str, name: str, choices: tuple[str, ...]) -> str:
    """Return ``value`` if it is one of ``choices``, else raise SignalError listing them."""
    return checks.check_choice(value, param, name, choices, error=SignalError)


def check_n_channels(n_channels: Any, name: str, n_samples: int = 0) -> int | None:
    """``None`` (one channel, 1-D output) or an integer >= 1 (2-D output).

    With ``n_samples``, a record of that many samples on all channels must fit in memory
    (:class:`~stageid.ResourceError` otherwise).
    """
    if n_channels is None:
        return None
    n_ch = check_int(n_channels, "n_channels", name, 1)
    require_samples(n_samples, name, n_ch)
    return n_ch


def scale_to(x: np.ndarray, rms: Any, amplitude: Any, name: str) -> np.ndarray:
    """Scale zero-mean ``x`` (per column) to the requested RMS or peak value.

    Exactly one of ``rms`` / ``amplitude`` may be given; neither means peak amplitude 1.
    """
    if rms is not None and amplitude is not None:
        raise SignalError(
            f"{name} takes either `rms` or `amplitude`, not both; got rms={rms!r}, amplitude={amplitude!r}."
        )
    if rms is not None:
        target = check_positive(rms, "rms", name)
        current = np.sqrt(np.mean(x**2, axis=0))
    else:
        target = 1.0 if amplitude is None else check_positive(amplitude, "amplitude", name)
        current = np.max(np.abs(x), axis=0)
    if np.any(current == 0):
        raise SignalError(f"{name} produced an all-zero signal; got no excited frequency.")
    # scale each column so its peak stays finite: target / current alone may overflow
    peak = np.max(np.abs(x), axis=0)
    ratio = peak / current
    if np.any(target > _FLOAT_MAX / ratio):
        what = f"rms {target:g}" if rms is not None else f"amplitude {target:g}"
        raise SignalError(
            f"{name} with {what} would exceed the largest float ({_FLOAT_MAX:.3g}); "
            f"expected a smaller {'rms' if rms is not None else 'amplitude'}."
        )
    with np.errstate(over="ignore"):
        gain = target / current
    if np.all(np.isfinite(gain)):
        return x * gain
    return (x / peak) * (target * ratio)  # a tiny raw signal scaled to a huge target
