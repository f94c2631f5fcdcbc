"""Multisines: sums of sines on the FFT lines of one period, random-phase or Schroeder.

A multisine puts all its power on lines of the FFT grid of its period, so a record of a
whole number of periods has no leakage and each excited line can be read directly from
the FFT of the input and the output.  Which lines, with which amplitudes, in which
realisation and MIMO experiment is the design (:mod:`.multisine_design`); here the waveform:

* :func:`multisine`: the phases (random from the realisation's generator, or Schroeder's),
  one period by the inverse FFT, the orthogonal MIMO weighting, the periods, the scale;
* :func:`clip_crest_factor`: **crest-factor optimisation** by iterative clipping (van der
  Ouderaa, Schoukens & Renneboog 1988: clip the peaks, restore the amplitude spectrum, keep
  the new phases) gets a lower peak for the same power than Schroeder's phases.
"""

from __future__ import annotations

import numpy as np

from .._errors import SignalError
from ._common import add_offset, as_channels, check_finite, check_int, check_n_channels, check_n_samples, scale_to
from .multisine_design import (
    LINE_SETS,
    MIMO_DESIGNS,
    MultisinePlan,
    check_option,
    line_amplitudes,
    multisine_lines,
    multisine_plan,
    orthogonal_matrix,
    realisation_rng,
)

__all__ = [
    "multisine",
    "LINE_SETS",
    "MIMO_DESIGNS",
    "MultisinePlan",
    "multisine_lines",
    "multisine_plan",
    "orthogonal_matrix",
    "line_amplitudes",
    "clip_crest_factor",
    "realisation_rng",
]


def clip_crest_factor(spectrum: np.ndarray, lines: np.ndarray, period: int, iterations: int) -> np.ndarray:
    """Phases of lower crest factor by iterative clipping; the amplitude spectrum is kept.

    Each iteration clips the time signal at a level between its RMS and its peak, takes
    the clipped signal's phases on ``lines`` and restores the amplitudes (van der Ouderaa,
    Schoukens & Renneboog, IEEE Trans. Instrum. Meas. 37(2), 1988); the lowest-crest phases
    seen are returned, so the result is never worse than the start.

    Parameters
    ----------
    spectrum : ndarray of shape (n_lines, n_channels), complex
        Start phasors of each channel on ``lines``.
    lines : ndarray of int
    period : int
        Samples per period.
    iterations : int
        Clipping iterations (0 returns ``spectrum``).
    """
    amp = np.abs(spectrum)
    best = spectrum.copy()
    full = np.zeros((period // 2 + 1, spectrum.shape[1]), dtype=complex)
    full[lines] = spectrum
    x = np.fft.irfft(full, n=period, axis=0)
    best_cf = np.max(np.abs(x), axis=0) / np.sqrt(np.mean(x**2, axis=0))
    for _ in range(int(iterations)):
        rms = np.sqrt(np.mean(x**2, axis=0))
        peak = np.max(np.abs(x), axis=0)
        level = rms + 0.7 * (peak - rms)  # clip the tallest peaks only; deeper clips stall
        X = np.fft.rfft(np.clip(x, -level, level), axis=0)[lines]
        current = amp * np.exp(1j * np.angle(X))
        full[lines] = current
        x = np.fft.irfft(full, n=period, axis=0)
        cf = np.max(np.abs(x), axis=0) / np.sqrt(np.mean(x**2, axis=0))
        better = cf < best_cf
        best[:, better] = current[:, better]
        best_cf = np.where(better, cf, best_cf)
    return best


_KINDS = ("random-phase", "schroeder")


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
    lines: str = "full",
    detection_group: int = 4,
    shape: str | None = None,
    crest_iterations: int = 0,
    mimo: str = "independent",
    realisation: int = 0,
    experiment: int = 0,
) -> np.ndarray:
    """Sum of sines on the FFT lines of one period inside a band.

    ``x(t) = offset + c * sum_k A_k cos(2 pi k t / (N dt) + phi_k)`` over the excited lines
    ``k`` of :func:`multisine_plan` (``N = n_samples / n_periods``), so the spectrum of a
    whole number of periods is exactly zero off those lines.  Phases:

    * ``"random-phase"``: ``phi_k`` uniform on ``[0, 2 pi)`` from ``seed`` (realisation 0)
      or from ``[seed, realisation]``;
    * ``"schroeder"``: ``phi_k = -pi j (j - 1) / F`` for the ``j``-th of ``F`` lines
      (Schroeder 1970), deterministic, with a low crest factor for a flat spectrum.

    ``c`` is chosen so the peak ``max(abs(x - offset))`` equals ``amplitude`` (default 1)
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
        Seed of the random phases and of the random-odd line choice.
    n_periods : int, default 1
        Number of identical periods in the record.
    offset : float, default 0.0
        Centre value.
    n_channels : int, optional
        Channels (inputs); omitted, the result is 1-D.
        An int returns shape (n_samples, n_channels):
        independent random phases per channel for ``"random-phase"``, and for
        ``"schroeder"`` the same period circularly shifted by ``j * N // n_channels``
        samples in channel ``j`` (with ``mimo="independent"``).
    limits : (float, float), optional
        Allowed range ``(lo, hi)`` of the signal.
    lines : {"full", "odd", "random-odd"}, default "full"
        Line set: full, odd, or random-odd (odd lines less one per group, at random).
        Every band line, the odd ones, or the odd ones less one at random per
        group of ``detection_group`` (unexcited lines detect nonlinear distortion).
    detection_group : int, default 4
        Random-odd: consecutive odd lines per group, one of which is left unexcited.
    shape : str, optional
        Amplitude spectrum as breakpoints f1:a1,f2:a2,... (Hz:gain, log-log); flat if omitted.
    crest_iterations : int, default 0
        Iterations of crest-factor reduction by clipping (100-200 give about 1.5).
        See :func:`clip_crest_factor`.
    mimo : {"independent", "orthogonal"}, default "independent"
        MIMO design: independent phases, or orthogonal (one experiment per input).
        ``"orthogonal"``: channel ``j`` of experiment ``e`` is multiplied line by line by
        ``T[j, e]`` of :func:`orthogonal_matrix`, so the experiments together excite every
        input independently at every line.
    realisation : int, default 0
        Random-phase realisation (> 0 needs an integer ``seed``); amplitudes and lines stay.
    experiment : int, default 0
        Orthogonal design: which of the ``n_experiments`` of the plan.

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
    kind = check_option(kind, "kind", _KINDS)
    off = check_finite(offset, "offset", name)
    n = int(check_n_samples(n_samples, name))
    channels = check_n_channels(n_channels, name, n)
    n_ch = 1 if channels is None else channels
    r = check_int(realisation, "realisation", name, 0)
    plan = multisine_plan(n_samples, dt, f_low, f_high, n_periods, lines, detection_group, shape, seed, n_ch, mimo)
    e = _experiment_index(experiment, plan, name)
    iterations = check_int(crest_iterations, "crest_iterations", name, 0)
    one_period = _one_period(plan, kind, realisation_rng(seed, r) if kind == "random-phase" else None, n_ch, iterations)
    if mimo == "orthogonal":
        one_period = _orthogonal_experiment(one_period, e)
    x = np.tile(one_period, (plan.n_periods, 1))
    return as_channels(add_offset(scale_to(x, rms, amplitude, name), off, name), channels, limits, name)


def _experiment_index(experiment: int, plan: MultisinePlan, name: str) -> int:
    """The experiment of the design, an integer below its ``n_experiments``, else SignalError."""
    e = check_int(experiment, "experiment", name, 0)
    if e >= plan.n_experiments:
        raise SignalError(f"`experiment` of {name} must be below the design's {plan.n_experiments}; got {e}.")
    return e


def _orthogonal_experiment(one_period: np.ndarray, e: int) -> np.ndarray:
    """Channel ``j`` of experiment ``e`` weighted line by line by ``T[j, e]`` of :func:`orthogonal_matrix`."""
    full = np.fft.rfft(one_period, axis=0) * orthogonal_matrix(one_period.shape[1])[:, e][None, :]
    return np.fft.irfft(full, n=one_period.shape[0], axis=0)


def _one_period(
    plan: MultisinePlan, kind: str, rng: np.random.Generator | None, n_ch: int, iterations: int
) -> np.ndarray:
    """One period (samples_per_period, n_ch): random or Schroeder phases, clipped to a lower crest factor."""
    n_lines, period = plan.excited.size, plan.samples_per_period
    if rng is not None:
        phases = rng.uniform(0.0, 2.0 * np.pi, size=(n_lines, n_ch))
    else:
        j = np.arange(1, n_lines + 1)
        phases = np.repeat((-np.pi * j * (j - 1) / n_lines)[:, None], n_ch, axis=1)
    spectrum = clip_crest_factor(plan.amplitudes[:, None] * np.exp(1j * phases), plan.excited, period, iterations)
    full = np.zeros((period // 2 + 1, n_ch), dtype=complex)
    full[plan.excited] = spectrum
    one_period = np.fft.irfft(full, n=period, axis=0)
    if rng is None and n_ch > 1:  # Schroeder channels: the same period shifted
        shift = period // n_ch
        one_period = np.stack([np.roll(one_period[:, 0], j * shift) for j in range(n_ch)], axis=1)
    return one_period
