"""Multisine design: line sets with detection lines, random-phase realisations, crest factor, MIMO.

A multisine puts all its power on lines of the FFT grid of its period, so a record of a
whole number of periods has no leakage and each excited line can be read directly from
the FFT of the input and the output.  For nonlinear systems (Pintelon & Schoukens, *System
Identification: A Frequency Domain Approach*, 2nd ed., sec. 3.4-3.5 and 4.3):

* **random-phase realisations** (phases drawn anew per realisation, amplitudes kept) let the
  best linear approximation's stochastic nonlinear distortions be seen as a scatter over
  realisations;
* **odd** and **random-odd** line sets leave lines unexcited: even nonlinearities put
  power on even lines only, odd nonlinearities on odd lines only, so the unexcited odd and
  even *detection lines* tell the two apart;
* **crest-factor optimisation** by iterative clipping (van der Ouderaa, Schoukens & Renneboog
  1988: clip the peaks, restore the amplitude spectrum, keep the new phases) gets a lower
  peak for the same power than Schroeder's phases;
* **orthogonal MIMO designs**: experiment ``e`` drives input ``j`` with its multisine times
  ``T[j, e]`` of a Hadamard (``n`` a power of 2) or DFT matrix, so the input matrix at every
  line is well conditioned and one set of ``n`` experiments gives every FRF entry.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._errors import SignalError
from ._common import (
    add_offset,
    as_channels,
    check_dt,
    check_finite,
    check_int,
    check_n_channels,
    check_n_samples,
    check_nonnegative,
    check_nyquist,
    check_positive,
    check_seed,
    scale_to,
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

LINE_SETS = ("full", "odd", "random-odd")
MIMO_DESIGNS = ("independent", "orthogonal")


def multisine_lines(n_samples: int, dt: float, f_low: float, f_high: float, n_periods: int = 1) -> np.ndarray:
    """FFT-line indices (of one period) inside the band of a multisine.

    Lines are ``k / (N dt)`` with ``N = n_samples / n_periods`` samples per period, for
    every ``k`` with ``f_low <= k / (N dt) <= f_high`` and ``0 < k < N / 2`` (DC and the
    Nyquist line are never excited: a sine has no DC, and at Nyquist its amplitude would
    depend on its phase).  With ``lines="full"`` these are the lines :func:`multisine`
    excites; the other line sets excite a subset (:func:`multisine_plan`).

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


@dataclasses.dataclass(frozen=True)
class MultisinePlan:
    """The line design of a multisine experiment (what a BLA analysis needs to know).

    Attributes
    ----------
    samples_per_period : int
    n_periods : int
    dt : float
    excited : ndarray of int
        Excited lines ``k`` (frequency ``k / (samples_per_period dt)``).
    detection_odd, detection_even : ndarray of int
        Unexcited odd and even lines inside the band, where odd and even nonlinear
        distortions show.
    amplitudes : ndarray of float, shape (n_excited,)
        Relative amplitude of each excited line (1 for a flat spectrum).
    n_experiments : int
        Experiments per realisation (``n_inputs`` rounded up to the orthogonal matrix's size
        for ``mimo="orthogonal"``, else 1).
    """

    samples_per_period: int
    n_periods: int
    dt: float
    excited: np.ndarray
    detection_odd: np.ndarray
    detection_even: np.ndarray
    amplitudes: np.ndarray
    n_experiments: int

    def to_dict(self) -> dict:
        """JSON-ready description (line indices as lists, the frequency step in Hz)."""
        return {
            "samples_per_period": self.samples_per_period,
            "n_periods": self.n_periods,
            "dt": self.dt,
            "line_spacing_hz": 1.0 / (self.samples_per_period * self.dt),
            "excited_lines": self.excited.tolist(),
            "detection_odd_lines": self.detection_odd.tolist(),
            "detection_even_lines": self.detection_even.tolist(),
            "amplitudes": self.amplitudes.tolist(),
            "experiments_per_realisation": self.n_experiments,
        }


def multisine_plan(
    n_samples: int,
    dt: float,
    f_low: float,
    f_high: float,
    n_periods: int = 1,
    lines: str = "full",
    detection_group: int = 4,
    shape: str | None = None,
    seed: int | np.random.Generator | None = None,
    n_inputs: int = 1,
    mimo: str = "independent",
) -> MultisinePlan:
    """Excited and detection lines, line amplitudes and experiment count of a multisine.

    ``lines``: ``"full"`` excites every band line; ``"odd"`` the odd ones (the even lines are
    detection lines); ``"random-odd"`` the odd ones less one chosen at random (from ``seed``)
    in each group of ``detection_group`` consecutive odd lines (those become odd detection
    lines).  The choice depends on ``seed`` only, so every realisation of one design shares
    its lines.  Parameters as in :func:`multisine`.

    Examples
    --------
    >>> plan = multisine_plan(1000, 1e-3, 1.0, 10.0, lines="odd")
    >>> plan.excited.tolist(), plan.detection_even.tolist()
    ([1, 3, 5, 7, 9], [2, 4, 6, 8, 10])
    """
    name = "multisine"
    band = multisine_lines(n_samples, dt, f_low, f_high, n_periods)
    line_set = _choice(lines, "lines", LINE_SETS)
    group = check_int(detection_group, "detection_group", name, 2)
    odd, even = band[band % 2 == 1], band[band % 2 == 0]
    det_odd = np.zeros(0, dtype=int)
    det_even = np.zeros(0, dtype=int) if line_set == "full" else even
    excited = band if line_set == "full" else odd
    if line_set == "random-odd":
        rng = realisation_rng(seed, 0)
        picks = [g[rng.integers(g.size)] for g in np.array_split(odd, np.arange(group, odd.size, group)) if g.size > 1]
        det_odd = np.asarray(picks, dtype=int)
        excited = np.setdiff1d(odd, det_odd)
    if excited.size == 0:
        raise SignalError(f"{name} with lines={line_set!r} excites no line in [{f_low:g}, {f_high:g}] Hz; got none.")
    period = int(n_samples) // int(n_periods)
    amplitudes = line_amplitudes(excited / (period * float(dt)), shape)
    n_exp = orthogonal_matrix(n_inputs).shape[1] if _choice(mimo, "mimo", MIMO_DESIGNS) == "orthogonal" else 1
    return MultisinePlan(period, int(n_periods), float(dt), excited, det_odd, det_even, amplitudes, n_exp)


def line_amplitudes(freqs: np.ndarray, shape: str | None) -> np.ndarray:
    """Relative amplitudes at ``freqs`` from a band shape ``"f1:a1,f2:a2,..."`` (Hz: gain).

    Interpolated straight on log-log axes between the breakpoints (a slope in dB/decade, as
    a Bode plot draws it), held constant beyond the first and last; ``None`` is flat.

    Examples
    --------
    >>> line_amplitudes(np.array([1.0, 10.0, 100.0, 1000.0]), "10:1,100:0.1").round(12).tolist()
    [1.0, 1.0, 0.1, 0.1]
    """
    f = np.asarray(freqs, dtype=float)
    if shape is None:
        return np.ones(f.size)
    try:
        points = [(float(a), float(b)) for a, b in (item.split(":") for item in str(shape).split(","))]
    except ValueError:
        raise SignalError(f"`shape` of multisine must be 'f1:a1,f2:a2,...' (Hz:gain); got {shape!r}.") from None
    fp, ap = np.array(points).T
    if np.any(fp <= 0) or np.any(ap <= 0) or np.any(np.diff(fp) <= 0) or not np.all(np.isfinite(points)):
        raise SignalError(f"`shape` of multisine needs increasing frequencies > 0 Hz and gains > 0; got {shape!r}.")
    return np.exp(np.interp(np.log(f), np.log(fp), np.log(ap)))


def orthogonal_matrix(n_inputs: int) -> np.ndarray:
    """``T`` of shape (n_inputs, n_experiments) with orthogonal rows of unit-modulus entries.

    A Hadamard matrix (entries +-1, the signals only change sign) when ``n_inputs`` is a
    power of 2, else the ``n_inputs``-point DFT matrix (Pintelon & Schoukens, sec. 3.5).

    Examples
    --------
    >>> orthogonal_matrix(2).real.tolist()
    [[1.0, 1.0], [1.0, -1.0]]
    """
    n = check_int(n_inputs, "n_inputs", "orthogonal_matrix", 1)
    if n & (n - 1) == 0:
        T = np.ones((1, 1), dtype=complex)
        while T.shape[0] < n:
            T = np.block([[T, T], [T, -T]])
        return T
    j = np.arange(n)
    return np.exp(-2j * np.pi * np.outer(j, j) / n)


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


def _choice(value: object, param: str, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise SignalError(f"`{param}` of multisine must be one of {', '.join(map(repr, choices))}; got {value!r}.")
    return str(value)


def realisation_rng(seed: object, realisation: int) -> np.random.Generator:
    """The generator of one realisation: ``seed`` itself for realisation 0 (as before
    realisations existed), ``[seed, r]`` for realisation ``r`` so each is reproducible alone."""
    seed = check_seed(seed, "multisine")
    if realisation == 0:
        return np.random.default_rng(seed)
    if not isinstance(seed, int):
        raise SignalError(f"realisation {realisation} of multisine needs an integer `seed`; got {seed!r}.")
    return np.random.default_rng([seed, realisation])


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
    kind = _choice(kind, "kind", _KINDS)
    off = check_finite(offset, "offset", name)
    n = int(check_n_samples(n_samples, name))
    channels = check_n_channels(n_channels, name, n)
    n_ch = 1 if channels is None else channels
    r = check_int(realisation, "realisation", name, 0)
    plan = multisine_plan(n_samples, dt, f_low, f_high, n_periods, lines, detection_group, shape, seed, n_ch, mimo)
    e = check_int(experiment, "experiment", name, 0)
    if e >= plan.n_experiments:
        raise SignalError(f"`experiment` of {name} must be below the design's {plan.n_experiments}; got {e}.")
    iterations = check_int(crest_iterations, "crest_iterations", name, 0)
    one_period = _one_period(plan, kind, realisation_rng(seed, r) if kind == "random-phase" else None, n_ch, iterations)
    if mimo == "orthogonal":
        full = np.fft.rfft(one_period, axis=0) * orthogonal_matrix(n_ch)[:, e][None, :]
        one_period = np.fft.irfft(full, n=plan.samples_per_period, axis=0)
    x = np.tile(one_period, (plan.n_periods, 1))
    return as_channels(add_offset(scale_to(x, rms, amplitude, name), off, name), channels, limits, name)


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
