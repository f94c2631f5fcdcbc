"""The statistics of eq. 9 (Cao & Chen 2013) of a record larger than memory, chunk by chunk.

Every statistic ``HankelMAP`` needs from the data is a sum over samples, so it maps over
sample ranges and reduces by addition:

* :func:`column_moments`: count, mean, centred sum of squares (Chan's pairwise update), range
  of every channel: the mean removal, the unit-RMS scales and the "input does not move" check
  of :mod:`~stageid.subspace.records`;
* :func:`range_lag_sums`: the lag correlations ``R[c] = sum_t z(t) z(t+c)^T`` of the
  mean-removed, scaled channels over one or several sample ranges.  A chunk ``[a, b)`` of a
  range ending at ``e`` reads ``L - 1`` samples of history past ``b`` (at most to ``e``) and
  keeps only the products whose first sample is in ``[a, b)``: the sums are the in-memory
  ones, whatever the chunk length (also chunks shorter than the window ``L = 2p``);
* the window Gram matrix from the summed lags and the first and last ``L`` samples of every
  range (:func:`~.correlations.gram_from_lags`, the same exact correction the in-memory
  statistics use), so :func:`ranged_statistics` equals
  :func:`~.hankel_toeplitz.segments_statistics` (and, over ``[(0, n)]``,
  :func:`~.hankel_toeplitz.window_statistics`) to rounding;
* :func:`range_lag_sums` also adds the input periodogram of 1024-sample blocks (on the grid
  of :func:`~.correlations.input_periodogram`'s 512 bins) for the excited band: a
  block-averaged estimate of the in-memory one (the record's own FFT would need it whole).

Each task gets a :class:`~stageid.data.chunked.ChunkedRecord` (a path and column names) and
a sample range, and reads that range itself: with a ``dask.distributed`` client the tasks run
on its workers and only ranges and the small sums travel; without one they run here, one
after the other.  A task that is lost with its worker is recomputed by Dask from its range.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..._errors import DataError
from ...data.chunked import DEFAULT_CHUNK, ChunkedRecord, check_finite_rows, map_reduce
from .correlations import lag_correlations
from .hankel_toeplitz import WindowStatistics, lag_statistics

__all__ = [
    "SPECTRUM_BLOCK",
    "ColumnMoments",
    "column_moments",
    "chunk_pieces",
    "range_lag_sums",
    "ranged_statistics",
]

#: Block length of the chunked input periodogram: bins of 1/1024 cycles per sample, the
#: grid of ``input_periodogram``'s 512 bins.
SPECTRUM_BLOCK = 1024


@dataclasses.dataclass(frozen=True)
class ColumnMoments:
    """Per channel: ``count`` samples, their ``mean``, centred sum of squares ``m2``, ``low`` and ``high``."""

    count: int
    mean: np.ndarray
    m2: np.ndarray
    low: np.ndarray
    high: np.ndarray

    def __add__(self, other: ColumnMoments) -> ColumnMoments:
        # Chan, Golub & LeVeque (1979): the pairwise update keeps m2 accurate for large offsets
        n = self.count + other.count
        delta = other.mean - self.mean
        mean = self.mean + delta * (other.count / n)
        m2 = self.m2 + other.m2 + delta**2 * (self.count * other.count / n)
        return ColumnMoments(n, mean, m2, np.minimum(self.low, other.low), np.maximum(self.high, other.high))

    @property
    def rms(self) -> np.ndarray:
        """RMS of each mean-removed channel (1 for a channel that is zero), as ``records.channel_scales``."""
        s = np.sqrt(self.m2 / self.count)
        return np.where(np.isfinite(s) & (s > 0), s, 1.0)


def chunk_pieces(ranges: Sequence[tuple[int, int]], chunk: int) -> list[tuple[int, int, int, int]]:
    """``(range index, a, b, range stop)`` for every chunk ``[a, b)`` of ``chunk`` samples of every range."""
    if chunk < 1:
        raise DataError(f"`chunk` must be a positive number of samples; got {chunk}.")
    return [
        (i, a, min(a + chunk, stop), stop) for i, (start, stop) in enumerate(ranges) for a in range(start, stop, chunk)
    ]


def _moments_task(record: ChunkedRecord, a: int, b: int) -> ColumnMoments:
    x = record.read(a, b)
    check_finite_rows(x, record.names, a, record.name)
    xt = np.ascontiguousarray(x.T)  # numpy reduces a few-column array along axis 0 slowly
    mean = xt.mean(axis=1)
    d = xt - mean[:, None]
    return ColumnMoments(b - a, mean, np.einsum("ij,ij->i", d, d), xt.min(axis=1), xt.max(axis=1))


def column_moments(record: ChunkedRecord, chunk: int = DEFAULT_CHUNK, client=None) -> ColumnMoments:
    """Mean, centred sum of squares and range of every channel (inputs then outputs), chunk by chunk.

    Raises
    ------
    DataError
        A NaN or inf sample (naming the column and row).
    """
    pieces = [(record, a, b) for _, a, b, _ in chunk_pieces([(0, record.n_samples)], chunk)]
    return map_reduce(_moments_task, pieces, lambda total, _, m: m if total is None else total + m, client)


def _own_lag_sums(z: np.ndarray, n_own: int, max_lag: int) -> np.ndarray:
    """``sum_{t < n_own, t + c < len(z)} z(t) z(t+c)^T`` for ``c = 0 .. max_lag``: the lag sums
    of the rows ``z[:n_own]`` with the rows after them as history."""
    n, r = z.shape
    R = np.zeros((max_lag + 1, r, r))
    if n * (max_lag + 1) > 1 << 16:  # long: FFTs; short: the direct products cost less than their set-up
        top = min(max_lag, n - 1)  # near the record's end fewer lags than asked fit in z
        R[: top + 1] += lag_correlations(z, top)
    else:
        for c in range(min(n, max_lag + 1)):
            R[c] += z[: n - c].T @ z[c:]
    tail = z[n_own:]  # products whose first sample is past the chunk: the next chunk's
    for c in range(min(max_lag, tail.shape[0] - 1) + 1):
        R[c] -= tail[: tail.shape[0] - c].T @ tail[c:]
    return R


def _block_periodogram(x: np.ndarray, first: int, a: int, b: int, n: int) -> np.ndarray:
    """Summed ``|rfft|^2`` of the 1024-sample blocks starting on the absolute grid in ``[a, b)``
    and ending by ``n``; ``x`` holds the rows from ``first`` (bins of ``input_periodogram``)."""
    B = SPECTRUM_BLOCK
    starts = np.arange(-(-a // B) * B, b, B)
    starts = starts[starts + B <= n]
    power = np.zeros((B // 2, x.shape[1]))
    # a Hann window: without it the leakage of a block's edges lifts the bins past the band's
    # edge above the 1 % threshold of the excited band (the record's own FFT has no such edges)
    window = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(B) / B)
    for j in range(x.shape[1]):
        for s in range(0, starts.size, 256):  # 256 blocks (2 MB) per FFT batch
            s0 = starts[s : s + 256] - first
            seg = x[s0[:, None] + np.arange(B)[None, :], j]
            X = np.fft.rfft(seg * window, axis=1)
            P = (X.real**2 + X.imag**2).sum(axis=0)
            power[:, j] += P[: B // 2]
            power[-1, j] += P[B // 2]  # the Nyquist line falls in the last bin, as in input_periodogram
    return power


def _lag_task(record, a, b, stop, max_lag, shift, scale, n_inputs_spectrum):
    """One task: the lag sums of the chunk ``[a, b)`` of a range ending at ``stop`` (history read
    past ``b``, at most to ``stop``) and the periodogram of its blocks (history to the record's end)."""
    history = max(max_lag, SPECTRUM_BLOCK - 1 if n_inputs_spectrum else 0)
    end = min(b + history, record.n_samples)
    x = record.read(a, end)
    check_finite_rows(x, record.names, a, record.name)
    z = (x - shift) / scale  # the in-memory order: mean removal, then the unit-RMS division
    R = _own_lag_sums(z[: min(end, stop, b + max_lag) - a], b - a, max_lag)
    power = _block_periodogram(z[:, :n_inputs_spectrum], a, a, b, record.n_samples) if n_inputs_spectrum else None
    return R, power


def range_lag_sums(
    record: ChunkedRecord,
    ranges: Sequence[tuple[int, int]],
    max_lag: int,
    shift: np.ndarray,
    scale: np.ndarray,
    chunk: int = DEFAULT_CHUNK,
    client=None,
    spectrum: bool = False,
) -> tuple[list[np.ndarray], np.ndarray | None]:
    """Lag sums (lags ``0 .. max_lag``) of ``(x - shift) / scale`` over each range, and optionally
    the block periodogram of the inputs over all of them.

    Returns
    -------
    R : list of ndarray of shape (max_lag + 1, r, r)
        One per range.
    power : ndarray of shape (512, n_inputs) or None
    """
    pieces = chunk_pieces(ranges, chunk)
    m = record.n_inputs if spectrum else 0
    args = [(record, a, b, stop, max_lag, shift, scale, m) for _, a, b, stop in pieces]
    r = len(record.names)
    lags = [np.zeros((max_lag + 1, r, r)) for _ in ranges]
    power = [np.zeros((SPECTRUM_BLOCK // 2, m))] if spectrum else [None]

    def add(total, i, value):
        lags[pieces[i][0]] += value[0]
        if spectrum:
            power[0] += value[1]
        return total

    map_reduce(_lag_task, args, add, client)
    return lags, power[0]


def ranged_statistics(
    record: ChunkedRecord,
    ranges: Sequence[tuple[int, int]],
    lags: Sequence[np.ndarray],
    horizon: int,
    shift: np.ndarray,
    scale: np.ndarray,
) -> WindowStatistics:
    """Eq. 9 statistics over the windows inside ``ranges`` from their lag sums (:func:`range_lag_sums`,
    at least ``2 horizon - 1`` lags) and their first and last ``2 horizon`` samples (read here).

    Equal to :func:`~.hankel_toeplitz.segments_statistics` on the same ranges; without the
    input spectrum.

    Raises
    ------
    DataError
        A range too short for the horizon.
    """
    L = 2 * int(horizon)
    short = [(a, b) for a, b in ranges if b - a <= L]
    if short:
        raise DataError(f"horizon {horizon} needs ranges of more than {L} samples; got {short[0][1] - short[0][0]}.")
    R = sum(lag[:L] for lag in lags)
    heads = np.stack([(record.read(a, a + L) - shift) / scale for a, _ in ranges])
    tails = np.stack([(record.read(b - L, b) - shift) / scale for _, b in ranges])
    count = int(sum(b - a - L + 1 for a, b in ranges))
    return lag_statistics(R, heads, tails, count, record.n_inputs)  # as segments_statistics, from the same parts
