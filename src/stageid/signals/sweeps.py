"""Swept sines (chirps): linear and logarithmic frequency sweeps.

Both papers identify with chirps: Cao & Chen (2013) drive the 3-DOF piezo stage with a
20 um chirp on a 20 um offset from 1 to 100 Hz sampled every 2 ms; Shakir & Kim drive the
maglev stage in closed loop with a 1 um chirp from DC to 2500 Hz in 2 s at 5 kHz.
"""

from __future__ import annotations

import numpy as np

from .._errors import SignalError
from ._common import check_band, check_choice, check_dt, check_finite, check_limits, check_swing, n_from_duration
from ._docs import fill_doc

__all__ = ["chirp", "log_chirp"]

_METHODS = ("linear", "logarithmic")


@fill_doc
def chirp(
    f0: float,
    f1: float,
    duration: float,
    dt: float,
    amplitude: float = 1.0,
    offset: float = 0.0,
    method: str = "linear",
    phase: float = 0.0,
    limits: tuple[float, float] | None = None,
) -> np.ndarray:
    """Swept sine ``offset + amplitude * sin(phi(t))`` from ``f0`` to ``f1`` Hz.

    The instantaneous frequency ``f(t) = phi'(t) / (2 pi)`` is ``f0`` at ``t = 0`` and
    reaches ``f1`` at ``t = duration``:

    * ``method="linear"``: ``f(t) = f0 + (f1 - f0) t / T`` and
      ``phi(t) = 2 pi (f0 t + (f1 - f0) t^2 / (2 T)) + phase``;
    * ``method="logarithmic"``: ``f(t) = f0 (f1 / f0)^(t / T)`` and
      ``phi(t) = 2 pi f0 T ((f1 / f0)^(t / T) - 1) / ln(f1 / f0) + phase``
      (equal time per decade; needs ``f0 > 0``).

    Parameters
    ----------
    f0, f1 : float
        Start and end frequency in Hz, ``0 <= f0 < f1 <= 1 / (2 dt)``.
    duration : float
        Sweep time ``T`` in seconds (``round(duration / dt)`` samples, end point excluded).
    {dt}
    amplitude : float, default 1.0
        Half the peak-to-peak swing, > 0.
    offset : float, default 0.0
        Centre value; the signal stays within ``offset +- amplitude``.
    method : {"linear", "logarithmic"}, default "linear"
        Frequency law.
    phase : float, default 0.0
        Phase in radians added to ``phi``.  ``0`` starts at ``offset``; ``-pi/2``
        starts at ``offset - amplitude`` (e.g. 0 um for the Cao & Chen chirp).
    limits : (float, float), optional
        Allowed range ``(lo, hi)`` of the signal (e.g. the stage travel).

    Returns
    -------
    ndarray of shape (n_samples,)

    Raises
    ------
    SignalError
        If a parameter is out of range (``f1 <= f0``, ``f1`` above Nyquist, ``f0 <= 0`` with
        ``method="logarithmic"``, ...) or the signal would leave ``limits``.

    Examples
    --------
    Cao & Chen's excitation of the Z channel: 20 um chirp on a 20 um offset, 1-100 Hz,
    2 ms sampling, kept within the 0-40 um travel:

    >>> from stageid.signals import chirp
    >>> u = chirp(1.0, 100.0, duration=10.0, dt=2e-3, amplitude=20.0, offset=20.0, limits=(0.0, 40.0))
    >>> u.shape
    (5000,)
    >>> bool(u.min() >= 0.0 and u.max() <= 40.0)
    True

    Shakir & Kim: 1 um from DC to 2500 Hz in 2 s at 5 kHz:

    >>> chirp(0.0, 2500.0, duration=2.0, dt=1 / 5000, amplitude=1.0).shape
    (10000,)
    """
    name = "chirp" if method == "linear" else f"{method} chirp"
    method = check_choice(method, "method", "chirp", _METHODS)
    step = check_dt(dt, name)
    n = n_from_duration(duration, step, name)
    fa, fb = check_band(f0, f1, ("f0", "f1"), step, name)
    amp, off = check_swing(amplitude, offset, name)
    ph = check_finite(phase, "phase", name)
    phi = _PHASES[method](fa, fb, float(duration), np.arange(n, dtype=float) * step)
    x = off + amp * np.sin(phi + ph)
    check_limits(x, limits, name)
    return x


def _linear_phase(fa: float, fb: float, T: float, t: np.ndarray) -> np.ndarray:
    """``phi(t) = 2 pi (f0 t + (f1 - f0) t^2 / (2 T))``: the frequency rises by equal steps."""
    return 2.0 * np.pi * (fa * t + 0.5 * (fb - fa) / T * t**2)


def _log_phase(fa: float, fb: float, T: float, t: np.ndarray) -> np.ndarray:
    """``phi(t) = 2 pi f0 T ((f1 / f0)^(t / T) - 1) / ln(f1 / f0)``: equal time per decade."""
    if fa <= 0:
        raise SignalError(f"`f0` of a logarithmic chirp must be > 0 Hz (log sweeps cannot start at DC); got {fa:g} Hz.")
    log_ratio = np.log(fb / fa)
    # expm1 keeps the phase accurate near t = 0
    return 2.0 * np.pi * fa * T / log_ratio * np.expm1(log_ratio * t / T)


_PHASES = {"linear": _linear_phase, "logarithmic": _log_phase}


@fill_doc
def log_chirp(
    f0: float,
    f1: float,
    duration: float,
    dt: float,
    amplitude: float = 1.0,
    offset: float = 0.0,
    phase: float = 0.0,
    limits: tuple[float, float] | None = None,
) -> np.ndarray:
    """Logarithmic swept sine: :func:`chirp` with ``method="logarithmic"``.

    The instantaneous frequency is ``f(t) = f0 (f1 / f0)^(t / T)``, so every decade gets
    the same time.

    Parameters
    ----------
    f0, f1 : float
        Start and end frequency in Hz, ``0 < f0 < f1 <= 1 / (2 dt)``.
    duration : float
        Sweep time in seconds.
    {dt}
    amplitude : float, default 1.0
        Half the peak-to-peak swing, > 0.
    offset : float, default 0.0
        Centre value.
    phase : float, default 0.0
        Phase in radians.
    {limits}

    Returns
    -------
    ndarray of shape (n_samples,)
        The chirp, ``n_samples = round(duration / dt)``.

    Raises
    ------
    SignalError
        As :func:`chirp`; in particular if ``f0 <= 0``.

    Examples
    --------
    >>> from stageid.signals import log_chirp
    >>> u = log_chirp(1.0, 100.0, duration=4.0, dt=1e-3)
    >>> u.shape
    (4000,)
    """
    return chirp(
        f0,
        f1,
        duration,
        dt,
        amplitude=amplitude,
        offset=offset,
        method="logarithmic",
        phase=phase,
        limits=limits,
    )
