"""Inputs for hysteresis identification: decaying waves and first-order-reversal staircases.

A Prandtl-Ishlinskii or Preisach model is identified from an input that visits the whole
input range and then many reversal points inside it, so that the play operators of every
threshold are exercised:

* :func:`decaying_sine` / :func:`decaying_triangle` start at the centre, swing over the
  full range ``offset +- amplitude`` in the first cycle and then shrink cycle by cycle
  towards zero, drawing nested minor loops (the identification input of Fig. 4 of the
  modified Prandtl-Ishlinskii letter covers -500..500 V this way);
* :func:`forc_staircase` repeats cycles from the minimum up to a reversal maximum that
  rises in equal steps to the maximum (first-order reversal curves), as in the dSPACE
  piezo records of ``shared/data/piezo_dspace_preisach`` (-90 V up to maxima rising in
  3.6 V steps to +90 V at 20, 40 and 100 cycles/s).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._errors import SignalError
from ._common import (
    check_choice,
    check_dt,
    check_finite,
    check_int,
    check_limits,
    check_nonnegative,
    check_nyquist,
    check_positive,
    check_span,
    check_tone,
    n_from_duration,
)
from ._docs import fill_doc
from .periodic import triangle_wave

__all__ = ["decaying_sine", "decaying_triangle", "forc_staircase", "decay_envelope"]

_DECAYS = ("linear", "exponential")
_FORC_SHAPES = ("triangle", "cosine")
_DEFAULT_FINAL_EXPONENTIAL = 0.05


def decay_envelope(
    n_cycles: int,
    amplitude: float = 1.0,
    decay: str = "linear",
    final_fraction: float | None = None,
) -> np.ndarray:
    """Peak value of each cycle of :func:`decaying_sine` / :func:`decaying_triangle`.

    Cycle ``j = 0 .. n_cycles - 1`` has amplitude ``A_j``, with ``A_0 = amplitude`` and
    ``A_{n_cycles-1} = final_fraction * amplitude``:

    * ``"linear"``: ``A_j = amplitude (1 - j (1 - final_fraction) / (n_cycles - 1))``;
      the default ``final_fraction = 1 / n_cycles`` gives
      ``A_j = amplitude (n_cycles - j) / n_cycles``;
    * ``"exponential"``: ``A_j = amplitude final_fraction^(j / (n_cycles - 1))``
      (a constant ratio per cycle); default ``final_fraction = 0.05``.

    Parameters
    ----------
    n_cycles : int
        Number of cycles, >= 2.
    amplitude : float, default 1.0
        Amplitude of the first cycle, > 0.
    decay : {"linear", "exponential"}, default "linear"
        Envelope law.
    final_fraction : float, optional
        Amplitude of the last cycle relative to the first, in (0, 1).

    Returns
    -------
    ndarray of shape (n_cycles,)
        Strictly decreasing cycle amplitudes.

    Raises
    ------
    SignalError
        If a parameter is out of range.

    Examples
    --------
    >>> from stageid.signals import decay_envelope
    >>> decay_envelope(4, 500.0).tolist()
    [500.0, 375.0, 250.0, 125.0]
    >>> decay_envelope(3, 1.0, "exponential", 0.25).tolist()
    [1.0, 0.5, 0.25]
    """
    name = "decaying signal"
    n_c = check_int(n_cycles, "n_cycles", name, 2)
    amp = check_positive(amplitude, "amplitude", name)
    decay = check_choice(decay, "decay", name, _DECAYS)
    if final_fraction is None:
        ff = 1.0 / n_c if decay == "linear" else _DEFAULT_FINAL_EXPONENTIAL
    else:
        ff = check_positive(final_fraction, "final_fraction", name)
        if ff >= 1.0:
            raise SignalError(f"`final_fraction` of {name} must be in (0, 1) so the amplitude decays; got {ff:g}.")
    j = np.arange(n_c, dtype=float)
    if decay == "linear":
        return amp * (1.0 - j * (1.0 - ff) / (n_c - 1))
    return amp * ff ** (j / (n_c - 1))


def _decaying(
    name: str,
    wave: Callable[[np.ndarray], np.ndarray],
    freq: float,
    n_cycles: int,
    dt: float,
    amplitude: float,
    offset: float,
    decay: str,
    final_fraction: float | None,
    limits: tuple[float, float] | None,
) -> np.ndarray:
    step = check_dt(dt, name)
    f = check_tone(freq, step, name)
    off = check_finite(offset, "offset", name)
    env = decay_envelope(n_cycles, amplitude, decay, final_fraction)
    check_span(off, float(env[0]), name)
    n_c = env.size
    n = n_from_duration(n_c / f, step, name)
    cycles = np.arange(n, dtype=float) * step * f
    # a sample a rounding error below a cycle boundary belongs to the next cycle; the
    # wave is zero there, so either choice keeps the signal continuous
    index = np.clip(np.floor(cycles + 1e-9).astype(int), 0, n_c - 1)
    x = off + env[index] * wave(cycles)
    check_limits(x, limits, name)
    return x


@fill_doc
def decaying_sine(
    freq: float,
    n_cycles: int,
    dt: float,
    amplitude: float = 1.0,
    offset: float = 0.0,
    decay: str = "linear",
    final_fraction: float | None = None,
    limits: tuple[float, float] | None = None,
) -> np.ndarray:
    """Sine whose amplitude shrinks cycle by cycle from full range towards zero.

    ``x(t) = offset + A_j sin(2 pi freq t)`` during cycle ``j`` (``j / freq <= t <
    (j + 1) / freq``) with the amplitudes ``A_j`` of :func:`decay_envelope`.  Each cycle
    starts and ends at ``offset`` where the sine is zero, so the signal is continuous;
    the first cycle reaches ``offset + amplitude`` and ``offset - amplitude``, the later
    ones draw nested minor loops.

    Parameters
    ----------
    {decaying}

    Returns
    -------
    ndarray of shape (n_samples,)
        The decaying sine.  The peaks ``offset +- A_j`` are sampled exactly when
        ``1 / (freq dt)`` is a multiple of 4.

    Raises
    ------
    {raises}

    Examples
    --------
    A -500..500 V identification input like Fig. 4 of the modified-PI letter:

    >>> from stageid.signals import decaying_sine
    >>> u = decaying_sine(1.0, n_cycles=10, dt=1e-3, amplitude=500.0,
    ...                   limits=(-500.0, 500.0))
    >>> u.shape, round(float(u.max()), 6), round(float(u.min()), 6)
    ((10000,), 500.0, -500.0)
    """
    return _decaying(
        "decaying sine",
        lambda c: np.sin(2.0 * np.pi * c),
        freq,
        n_cycles,
        dt,
        amplitude,
        offset,
        decay,
        final_fraction,
        limits,
    )


@fill_doc
def decaying_triangle(
    freq: float,
    n_cycles: int,
    dt: float,
    amplitude: float = 1.0,
    offset: float = 0.0,
    decay: str = "linear",
    final_fraction: float | None = None,
    limits: tuple[float, float] | None = None,
) -> np.ndarray:
    """Triangle wave whose amplitude shrinks cycle by cycle from full range towards zero.

    As :func:`decaying_sine` with the triangle of :func:`triangle` (constant slope
    between reversals, so every part of the range is crossed at a steady rate).

    Parameters
    ----------
    {decaying}

    Returns
    -------
    ndarray of shape (n_samples,)
        The decaying triangle.

    Raises
    ------
    {raises}

    Examples
    --------
    >>> from stageid.signals import decaying_triangle
    >>> decaying_triangle(1.0, n_cycles=2, dt=0.25, amplitude=4.0).tolist()
    [0.0, 4.0, 0.0, -4.0, 0.0, 2.0, 0.0, -2.0]
    """
    return _decaying(
        "decaying triangle", triangle_wave, freq, n_cycles, dt, amplitude, offset, decay, final_fraction, limits
    )


@fill_doc
def forc_staircase(
    minimum: float,
    maximum: float,
    n_reversals: int,
    freq: float,
    dt: float,
    shape: str = "triangle",
    idle: float = 0.0,
    limits: tuple[float, float] | None = None,
) -> np.ndarray:
    """First-order-reversal staircase: cycles from ``minimum`` up to rising maxima.

    Cycle ``j = 0 .. n_reversals - 1`` lasts ``1 / freq`` seconds: it rises from
    ``minimum`` to the reversal maximum ``M_j = minimum + (j + 1) (maximum - minimum) /
    n_reversals`` in the first half and falls back to ``minimum`` in the second.  The
    maxima rise in equal steps and the last one is ``maximum``.

    Parameters
    ----------
    minimum, maximum : float
        Input range, ``minimum < maximum`` (e.g. -90 and 90 V).
    n_reversals : int
        Number of cycles (reversal maxima), >= 1; the step is
        ``(maximum - minimum) / n_reversals`` (50 gives the 3.6 V steps of the dSPACE
        records).
    freq : float
        Cycles per second, ``0 < freq <= 1 / (2 dt)``.
    {dt}
    shape : {"triangle", "cosine"}, default "triangle"
        Shape of one cycle: straight ramps, or the raised cosine
        ``minimum + (M_j - minimum) (1 - cos(2 pi freq t)) / 2``.  The dSPACE records
        in ``shared/data/piezo_dspace_preisach`` were driven with the raised cosine.
    idle : float, default 0.0
        Seconds held at ``minimum`` before the first cycle (the dSPACE records idle
        1.5 s).
    {limits}

    Returns
    -------
    ndarray of shape (n_samples,)
        The staircase, ``n_samples = round((idle + n_reversals / freq) / dt)`` samples at
        ``t = k dt``.  The maxima are sampled exactly when ``idle / dt`` is whole and
        ``1 / (freq dt)`` is even.

    Raises
    ------
    {raises}

    Examples
    --------
    >>> from stageid.signals import forc_staircase
    >>> u = forc_staircase(-90.0, 90.0, n_reversals=50, freq=20.0, dt=1e-4)
    >>> u.shape, float(u[250]), float(u[750]), float(u.max())
    ((25000,), -86.4, -82.8, 90.0)
    """
    name = "forc staircase"
    lo = check_finite(minimum, "minimum", name)
    hi = check_finite(maximum, "maximum", name)
    if hi <= lo:
        raise SignalError(f"`maximum` of {name} must be greater than minimum = {lo:g}; got {hi:g}.")
    n_r = check_int(n_reversals, "n_reversals", name, 1)
    step = check_dt(dt, name)
    f = check_positive(freq, "freq", name)
    check_nyquist(f, "freq", step, name)
    shape = check_choice(shape, "shape", name, _FORC_SHAPES)
    wait = check_nonnegative(idle, "idle", name)

    n = n_from_duration(wait + n_r / f, step, name)
    n_idle = int(round(wait / step))
    index, w = _forc_cycles(n, step, n_idle, f, n_r, shape)
    peaks = lo + (hi - lo) * np.arange(1, n_r + 1, dtype=float) / n_r
    x = lo + (peaks[index] - lo) * w
    x[:n_idle] = lo
    check_limits(x, limits, name)
    return x


def _forc_cycles(n: int, step: float, n_idle: int, f: float, n_r: int, shape: str) -> tuple[np.ndarray, np.ndarray]:
    """Every sample's cycle (0 .. n_r - 1, counted from the end of the idle part) and its height
    in that cycle, 0 at the minimum to 1 at the reversal: straight ramps or a raised cosine."""
    cycles = (np.arange(n, dtype=float) * step - n_idle * step) * f
    index = np.clip(np.floor(cycles + 1e-9).astype(int), 0, n_r - 1)
    u = cycles - index  # position within the cycle, 0..1
    if shape == "triangle":
        w = 1.0 - np.abs(2.0 * u - 1.0)
    else:
        w = 0.5 * (1.0 - np.cos(2.0 * np.pi * u))
    return index, np.clip(w, 0.0, 1.0)
