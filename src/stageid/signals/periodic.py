"""Periodic excitations: sine and triangle (multisines live in :mod:`stageid.signals.multisine`).

A multisine puts all its power on lines of the FFT grid of its period, so a record of a
whole number of periods has no leakage and each excited line can be read directly from
the FFT of the input and the output.
"""

from __future__ import annotations

import numpy as np

from ._common import (
    check_dt,
    check_finite,
    check_limits,
    check_swing,
    check_tone,
    n_from_duration,
)
from ._docs import fill_doc

__all__ = ["sine", "triangle"]


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
    f = check_tone(freq, step, name)
    amp, off = check_swing(amplitude, offset, name)
    return step, n, f, amp, off


@fill_doc
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
    {duration}
    {dt}
    {amplitude}
    {offset}
    phase : float, default 0.0
        Phase in radians.
    {limits}

    Returns
    -------
    ndarray of shape (n_samples,)
        The sine.

    Raises
    ------
    {raises}

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


@fill_doc
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
    {duration}
    {dt}
    {amplitude}
    {offset}
    phase : float, default 0.0
        Phase in radians (``2 pi`` is one period).
    {limits}

    Returns
    -------
    ndarray of shape (n_samples,)
        The triangle wave.

    Raises
    ------
    {raises}

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
