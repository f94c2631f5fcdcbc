"""Welch's H1 estimate of a MIMO frequency response, with multiple coherence and uncertainty.

All auto- and cross-spectra of the channels ``x = [u; y]`` are accumulated at once: each
segment of each record is detrended (mean removed), windowed and transformed once per
channel, and the outer products ``conj(X) X^T`` of every segment are summed (one FFT per
channel per segment, never one per pair).  The records are pooled: one record per excited
input, or several inputs excited at once, all add to the same sums.  With one record the
spectra are exactly ``scipy.signal.csd(x_a, x_b, fs, window, nperseg=N, noverlap, detrend=
"constant")`` for every pair.

``H1 = S_yu S_uu^-1`` (Bendat & Piersol, *Random Data*, 4th ed., eq. 7.36), the multiple
coherence ``gamma_i^2 = 1 - S_vv,i / S_yy,ii`` with the residual spectrum
``S_vv,i = S_yy,ii - S_yu,i S_uu^-1 S_uy,i`` (eq. 7.39), and the variance of each entry
``var(H_ij) = S_vv,i [S_uu^-1]_jj / (L_eff - m)`` (Pintelon & Schoukens, *System
Identification*, 2nd ed., sec. 2.5 and 7.2), ``L_eff`` the number of segments corrected for
the overlap (Welch 1967, eq. 14: ``L / (1 + 2 sum_k (1 - k/L) rho(k)^2)``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from .._errors import DataError, ParameterError
from ..base import Estimator, InstanceOf, Interval
from ..checks import check_integer, check_real
from ..data import Experiment
from ..models.frequency_response import FrequencyResponse
from ..runtime.resources import require_memory
from .estimate import FRFResult
from .records import ChannelRecord, as_channel_records, check_finite_batch

__all__ = [
    "CrossSpectra",
    "cross_spectra",
    "segment_sums",
    "spectra_from_sums",
    "WelchFRF",
    "welch_frf",
    "h1_from_spectra",
    "default_segment",
    "get_window",
]

#: Bytes of segment data transformed at once (a batch of segments x channels).
BATCH_BYTES = 32e6


@dataclasses.dataclass(frozen=True)
class CrossSpectra:
    """Pooled one-sided spectral densities of the channels ``[inputs..., outputs...]``.

    ``S[k, a, b]`` is the mean over segments of ``conj(X_a) X_b`` scaled as
    ``scipy.signal.csd`` (density, one-sided); ``n_segments`` segments of ``segment``
    samples, ``overlap_correlation`` the ``rho(k)`` of the window at the segment shifts.
    """

    freqs: np.ndarray
    S: np.ndarray
    n_inputs: int
    n_segments: int
    segment: int
    effective_segments: float


def default_segment(n_samples: int) -> int:
    """The largest power of two giving at least 16 half-overlapping segments, 64 to 65536."""
    n = 2 ** int(np.floor(np.log2(max(n_samples / 8.5, 1.0))))
    return int(min(max(n, 64), 65536))


def get_window(name: str, n: int) -> np.ndarray:
    """``scipy.signal.get_window(name, n)`` (periodic), with a one-line error for an unknown name.

    The default ``hann`` is computed here as scipy does (``0.5 - 0.5 cos(2 pi k / n)``):
    importing scipy.signal costs seconds of the command's start.
    """
    if name == "hann":
        return 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)
    from scipy.signal import get_window as scipy_window

    try:
        w = scipy_window(name, n)
    except (ValueError, TypeError) as exc:
        raise ParameterError(f"`window` must be a scipy window name such as 'hann'; got {name!r} ({exc}).") from None
    if not np.any(w != 0):
        raise ParameterError(f"`window` {name!r} is zero everywhere for {n} samples.")
    return w


def _effective_segments(w: np.ndarray, step: int, counts: Sequence[int]) -> float:
    """Welch's (1967, eq. 14) equivalent number of independent segments, per record, summed."""
    energy = float(w @ w)
    total = 0.0
    for L in counts:
        var = 1.0
        for k in range(1, L):
            shift = k * step
            if shift >= w.size:
                break
            rho = float(w[:-shift] @ w[shift:]) / energy
            var += 2.0 * (1.0 - k / L) * rho * rho
        total += L / var
    return total


def cross_spectra(
    data: Experiment | ChannelRecord | Sequence[Experiment | ChannelRecord],
    segment: int,
    overlap: float = 0.5,
    window: str = "hann",
) -> CrossSpectra:
    """Auto- and cross-spectral densities of all channels of all records, pooled.

    Parameters
    ----------
    data : Experiment, ChannelRecord or a sequence of them
    segment : int
        Samples per segment (``nperseg``), >= 2 and at most the shortest record.
    overlap : float
        Fraction of a segment shared with the next, ``0 <= overlap < 1``; ``noverlap =
        int(overlap * segment)``.
    window : str
        A ``scipy.signal.get_window`` name.

    Returns
    -------
    CrossSpectra
        ``S`` of shape (segment // 2 + 1, m + q, m + q), channels inputs first.

    Raises
    ------
    DataError
        A record shorter than one segment.

    Examples
    --------
    >>> import numpy as np, scipy.signal
    >>> from stageid.data import Experiment
    >>> rng = np.random.default_rng(0); u = rng.standard_normal(4096); y = np.convolve(u, [1, 0.5])[:4096]
    >>> cs = cross_spectra(Experiment(u, y, 0.01), 256)
    >>> f, p = scipy.signal.csd(u, y, fs=100.0, nperseg=256)
    >>> bool(np.allclose(cs.S[:, 0, 1], p, rtol=1e-10))
    True
    """
    recs = as_channel_records(data)
    segment = check_integer(segment, "segment", "welch_frf", low=2)
    overlap = check_real(overlap, "overlap", "welch_frf", low=0.0, high=1.0, closed="left")
    w = get_window(window, segment)
    noverlap = int(overlap * segment)
    step = segment - noverlap
    for r in recs:
        if r.n_samples < segment:
            raise DataError(
                f"record '{r.name or 'data'}' has {r.n_samples} samples, fewer than one segment of {segment}; "
                "give a shorter `segment=`."
            )
    n_ch = len(recs[0].channels)
    nf = segment // 2 + 1
    batch = max(1, int(BATCH_BYTES // (8.0 * n_ch * segment * 3)))
    require_memory(16.0 * nf * (n_ch * n_ch + 2 * n_ch * batch) + 24.0 * batch * n_ch * segment, "Welch spectra")
    acc = np.zeros((nf, n_ch, n_ch), complex)
    counts = [_accumulate(r, w, step, batch, acc) for r in recs]
    return spectra_from_sums(acc, counts, w, step, recs[0].dt, recs[0].n_inputs)


def spectra_from_sums(
    acc: np.ndarray, counts: Sequence[int], w: np.ndarray, step: int, dt: float, n_inputs: int
) -> CrossSpectra:
    """The :class:`CrossSpectra` of ``acc = sum conj(X) X^T`` over the segments of records with
    ``counts`` segments each (window ``w``, ``step`` samples apart); ``acc`` is scaled in place."""
    segment, nf = w.size, acc.shape[0]
    n_seg = int(sum(counts))
    scale = 1.0 / (n_seg * (1.0 / dt) * float(w @ w))
    one_sided = np.full(nf, 2.0)
    one_sided[0] = 1.0
    if segment % 2 == 0:
        one_sided[-1] = 1.0
    acc *= (scale * one_sided)[:, None, None]
    freqs = np.fft.rfftfreq(segment, dt)
    return CrossSpectra(freqs, acc, n_inputs, n_seg, segment, _effective_segments(w, step, counts))


def segment_sums(record: ChannelRecord, w: np.ndarray, step: int) -> tuple[np.ndarray, int]:
    """``sum conj(X) X^T`` (unscaled, shape (segment // 2 + 1, n_ch, n_ch)) over the segments of
    one record, ``step`` samples apart and windowed by ``w``, and their count: the part of
    :func:`cross_spectra` that adds over segments (:mod:`.welch_chunked` sums it over chunks)."""
    n_ch = len(record.channels)
    batch = max(1, int(BATCH_BYTES // (8.0 * n_ch * w.size * 3)))
    acc = np.zeros((w.size // 2 + 1, n_ch, n_ch), complex)
    return acc, _accumulate(record, w, step, batch, acc)


def _accumulate(r: ChannelRecord, w: np.ndarray, step: int, batch: int, acc: np.ndarray) -> int:
    """Add ``sum conj(X) X^T`` over the segments of record ``r`` to ``acc``; returns their count.

    Segment batches are cut from each channel as strided views, mean-removed, windowed and
    transformed once per channel; the samples after the last segment are checked as well.
    """
    segment = w.size
    n_ch, nf = len(r.channels), acc.shape[0]
    views = [np.lib.stride_tricks.sliding_window_view(x, segment)[::step] for x in r.channels]  # (L, N) each
    L = views[0].shape[0]
    for c, x in enumerate(r.channels):
        tail = x[(L - 1) * step + segment :]
        check_finite_batch(r, tail[None, :], c, (L - 1) * step + segment, 0)
    for b in range(0, L, batch):
        X = np.empty((n_ch, min(batch, L - b), nf), complex)
        for c, view in enumerate(views):
            seg = view[b : b + batch]
            check_finite_batch(r, seg, c, b * step, step)
            seg = seg - seg.mean(axis=1, keepdims=True)  # scipy's default detrend="constant"
            X[c] = np.fft.rfft(seg * w, axis=1)  # one FFT per channel per segment
        Xf = X.transpose(2, 0, 1)  # (nf, ch, batch)
        acc += np.conj(Xf) @ Xf.transpose(0, 2, 1)
    return L


def h1_from_spectra(
    spectra: CrossSpectra, inputs: Sequence[str] = (), outputs: Sequence[str] = ()
) -> FrequencyResponse:
    """H1, multiple coherence and the standard deviation of H from pooled spectra.

    The DC line is left out: the mean removal of every segment leaves no input there.

    Raises
    ------
    DataError
        A pooled input spectrum that is singular at some frequency (an input without
        excitation, or inputs that are always proportional), or too few segments
        (``L_eff <= m``) to estimate the noise.
    """
    m = spectra.n_inputs
    S = spectra.S[1:]
    f = spectra.freqs[1:]
    Suu = S[:, :m, :m]
    Suy = S[:, :m, m:]
    Syy = np.real(np.diagonal(S[:, m:, m:], axis1=1, axis2=2))
    lam = np.linalg.eigvalsh(Suu)  # ascending, per frequency
    top = lam[:, -1]
    singular = (lam[:, 0] <= 1e-12 * top) | (top <= 1e-24 * max(float(top.max(initial=0.0)), 1e-300))
    if np.any(singular):
        k = int(np.flatnonzero(singular)[0])
        what = "an input without excitation" if m == 1 else "an input without excitation or inputs always proportional"
        raise DataError(
            f"the pooled input spectrum is singular at {int(singular.sum())} of {f.size} frequencies "
            f"(first {f[k]:g} Hz): {what}; excite every input independently."
        )
    if spectra.effective_segments <= m + 0.5:
        raise DataError(
            f"Welch needs more independent segments than inputs ({m}) to estimate the noise; got "
            f"{spectra.n_segments} segments: give a shorter `segment=` or longer records."
        )
    Suu_inv = np.linalg.inv(Suu)
    HT = Suu_inv @ Suy  # (nf, m, q): H^T = S_uu^-1 S_uy
    explained = np.real(np.einsum("kaq,kaq->kq", np.conj(Suy), HT))
    Svv = np.clip(Syy - explained, 0.0, None)
    with np.errstate(invalid="ignore", divide="ignore"):
        coh = np.where(Syy > 0, 1.0 - Svv / np.where(Syy > 0, Syy, 1.0), 0.0)
    dof = spectra.effective_segments - m
    var = Svv[:, :, None] * np.real(np.diagonal(Suu_inv, axis1=1, axis2=2))[:, None, :] / dof
    return FrequencyResponse(f, HT.transpose(0, 2, 1), np.sqrt(var), coh, tuple(inputs), tuple(outputs))


class WelchFRF(Estimator):
    """Welch H1 estimate with coherence and standard deviation (see the module docstring).

    Parameters
    ----------
    segment : int, optional
        Samples per segment; default :func:`default_segment` of the shortest record.
    overlap : float
        Fraction of a segment shared with the next, ``0 <= overlap < 1``.
    window : str
        A ``scipy.signal.get_window`` name.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment
    >>> rng = np.random.default_rng(1); u = rng.standard_normal(20000)
    >>> exp = Experiment(u, 2.0 * u + 0.01 * rng.standard_normal(20000), 0.001)
    >>> res = WelchFRF(segment=256).fit(exp)
    >>> bool(np.allclose(res.model.response, 2.0, rtol=1e-2)), bool(res.model.coherence.min() > 0.99)
    (True, True)
    >>> res.diagnostics["segment"], bool(np.array_equal(welch_frf(exp, 256).response, res.model.response))
    (256, True)
    """

    parameter_constraints = {
        "segment": [Interval(int, 2, None), None],
        "overlap": [Interval(float, 0.0, 1.0, closed="left")],
        "window": [InstanceOf(str, "a scipy window name such as 'hann'")],
    }

    def __init__(self, segment: int | None = None, overlap: float = 0.5, window: str = "hann") -> None:
        self.segment = segment
        self.overlap = overlap
        self.window = window

    def fit(self, data: Experiment | Sequence[Experiment]) -> FRFResult:
        """The H1 estimate of one record per excited input, or of records exciting several inputs at once.

        Returns
        -------
        FRFResult
            ``model`` at ``k / (segment dt)``, ``k = 1 .. segment // 2``, with ``std`` and
            ``coherence``; ``diagnostics`` the segment, the number of segments and Welch's
            equivalent number of independent ones.

        Raises
        ------
        ParameterError
            A bad setting or an unknown window.
        DataError
            A record shorter than a segment, an input without excitation, or too few segments.
        """
        self.validate_params()
        recs = as_channel_records(data)
        segment = default_segment(min(r.n_samples for r in recs)) if self.segment is None else int(self.segment)
        spectra = cross_spectra(recs, segment, float(self.overlap), self.window)
        frd = h1_from_spectra(spectra, recs[0].input_names, recs[0].output_names)
        diagnostics = {
            "segment": segment,
            "n_segments": spectra.n_segments,
            "effective_segments": spectra.effective_segments,
        }
        return FRFResult(frd, self.clone(), diagnostics)


def welch_frf(
    data: Experiment | Sequence[Experiment], segment: int | None = None, overlap: float = 0.5, window: str = "hann"
) -> FrequencyResponse:
    """The response of :class:`WelchFRF` ``(segment, overlap, window).fit(data)`` (its examples show both)."""
    return WelchFRF(segment, overlap, window).fit(data).model
