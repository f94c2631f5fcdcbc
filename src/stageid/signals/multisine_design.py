"""The design of a multisine: its lines, their amplitudes, realisations and MIMO experiments.

A multisine (:mod:`.multisine`) puts its power on lines of the FFT grid of its period; the
design says which (Pintelon & Schoukens, *System Identification: A Frequency Domain
Approach*, 2nd ed., sec. 3.4-3.5 and 4.3):

* :func:`multisine_lines`: the lines inside the band;
* **odd** and **random-odd** line sets (:func:`multisine_plan`) leave lines unexcited: even
  nonlinearities put power on even lines only, odd nonlinearities on odd lines only, so the
  unexcited odd and even *detection lines* tell the two apart;
* :func:`line_amplitudes`: a band shape in dB per decade;
* **random-phase realisations** (:func:`realisation_rng`: phases drawn anew per realisation,
  amplitudes and lines kept) let the best linear approximation's stochastic nonlinear
  distortions be seen as a scatter over realisations;
* **orthogonal MIMO designs** (:func:`orthogonal_matrix`): experiment ``e`` drives input ``j``
  with its multisine times ``T[j, e]`` of a Hadamard (``n`` a power of 2) or DFT matrix, so
  the input matrix at every line is well conditioned and one set of ``n`` experiments gives
  every FRF entry.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._errors import SignalError
from ._common import (
    check_band,
    check_dt,
    check_int,
    check_n_samples,
    check_seed,
)

__all__ = [
    "LINE_SETS",
    "MIMO_DESIGNS",
    "MultisinePlan",
    "multisine_lines",
    "multisine_plan",
    "line_amplitudes",
    "orthogonal_matrix",
    "realisation_rng",
    "check_option",
]

LINE_SETS = ("full", "odd", "random-odd")
MIMO_DESIGNS = ("independent", "orthogonal")


def multisine_lines(n_samples: int, dt: float, f_low: float, f_high: float, n_periods: int = 1) -> np.ndarray:
    """FFT-line indices (of one period) inside the band of a multisine.

    Lines are ``k / (N dt)`` with ``N = n_samples / n_periods`` samples per period, for
    every ``k`` with ``f_low <= k / (N dt) <= f_high`` and ``0 < k < N / 2`` (DC and the
    Nyquist line are never excited: a sine has no DC, and at Nyquist its amplitude would
    depend on its phase).  With ``lines="full"`` these are the lines :func:`~.multisine.multisine`
    excites; the other line sets excite a subset (:func:`multisine_plan`).

    Parameters
    ----------
    n_samples, dt, f_low, f_high, n_periods
        As in :func:`~.multisine.multisine`.

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
    lo, hi = check_band(f_low, f_high, ("f_low", "f_high"), step, name)
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
    its lines.  Parameters as in :func:`~.multisine.multisine`.

    Examples
    --------
    >>> plan = multisine_plan(1000, 1e-3, 1.0, 10.0, lines="odd")
    >>> plan.excited.tolist(), plan.detection_even.tolist()
    ([1, 3, 5, 7, 9], [2, 4, 6, 8, 10])
    """
    name = "multisine"
    band = multisine_lines(n_samples, dt, f_low, f_high, n_periods)
    line_set = check_option(lines, "lines", LINE_SETS)
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
    n_exp = orthogonal_matrix(n_inputs).shape[1] if check_option(mimo, "mimo", MIMO_DESIGNS) == "orthogonal" else 1
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


def check_option(value: object, param: str, choices: tuple[str, ...]) -> str:
    """``value`` if it is one of ``choices``, else the multisine's one-line SignalError."""
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
