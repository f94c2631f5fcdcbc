"""The simplified Hankel-Toeplitz model of Cao & Chen (2013), section 2.1, and its normal equations.

For a horizon ``p`` the model (eq. 9) is

    y_p(k) = [Gamma  Phi  D_p] [u_p(k-p); y_p(k-p); u_p(k)] + Delta(k)

with ``u_p(k) = [u(k); u(k+1); ...; u(k+p-1)]`` (eq. 3, time ascending, channels fastest),
``Gamma`` of shape (p q, p m), ``Phi`` of shape (p q, p q) and ``D_p`` of shape (p q, p m).
Every regression sample is one *window* of ``2 p`` consecutive samples of
``z(t) = [u(t); y(t)]``, so the normal equations never need the (n_windows x n_regressors)
matrix: the Gram matrix of the windows is assembled from the lag correlations of ``z``
(:mod:`.correlations`).  This is :class:`WindowStatistics`, the sufficient statistic of
both the batch least-squares and the MAP estimators; :func:`hankel_toeplitz_statistics`
pools it over the records of a fit.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..._errors import DataError
from .correlations import RecordRows, gram_from_lags, input_periodogram, lag_correlations, range_ends, window_gram

__all__ = [
    "WindowStatistics",
    "hankel_toeplitz_statistics",
    "statistics_bytes",
    "row_residuals",
    "window_statistics",
    "record_statistics",
    "segments_statistics",
    "lag_statistics",
    "regressor_indices",
    "dense_regression",
    "split_theta",
]


@dataclass(frozen=True, eq=False)
class WindowStatistics:
    """Sufficient statistics of the Hankel-Toeplitz regression for one horizon.

    ``W = sum_k w(k) w(k)^T`` over all windows ``w(k) = [z(k); ...; z(k+2p-1)]`` with
    ``z = [u; y]`` (window positions ``0..p-1`` are the past, ``p..2p-1`` the future).

    Attributes
    ----------
    W : ndarray of shape (2 p r, 2 p r), ``r = n_inputs + n_outputs``
    n_windows : float
        Number of windows (their weights' sum when forgetting is used).
    count : int
        Number of windows (unweighted).
    horizon, n_inputs, n_outputs : int
    input_power : ndarray of shape (n_freq, n_inputs) or None
        Block-averaged input periodogram (for the excited band), from the FFT pass.
    freqs : ndarray of shape (n_freq,) or None
        Frequencies of ``input_power`` in cycles per sample.
    """

    W: np.ndarray
    n_windows: float
    horizon: int
    n_inputs: int
    n_outputs: int
    input_power: np.ndarray | None = None
    freqs: np.ndarray | None = None
    count: int = 0

    def __add__(self, other: WindowStatistics) -> WindowStatistics:
        if (self.horizon, self.n_inputs, self.n_outputs) != (other.horizon, other.n_inputs, other.n_outputs):
            raise DataError("window statistics can only be added for the same horizon and channels.")
        power = None
        if (
            self.input_power is not None
            and other.input_power is not None
            and self.input_power.shape == other.input_power.shape
        ):
            power = self.input_power + other.input_power
        elif self.input_power is not None:
            power = self.input_power
        else:
            power = other.input_power
        return WindowStatistics(
            self.W + other.W,
            self.n_windows + other.n_windows,
            self.horizon,
            self.n_inputs,
            self.n_outputs,
            power,
            self.freqs if self.freqs is not None else other.freqs,
            self.count + other.count,
        )

    def scaled(self, factor: float) -> WindowStatistics:
        """The statistics with every window's weight multiplied by ``factor`` (forgetting)."""
        return WindowStatistics(
            self.W * factor,
            self.n_windows * factor,
            self.horizon,
            self.n_inputs,
            self.n_outputs,
            self.input_power,
            self.freqs,
            self.count,
        )

    def leading(self, horizon: int) -> WindowStatistics:
        """The statistics of a horizon up to this one over the same windows: the leading block
        of ``W`` (window positions ``0 .. 2 horizon - 1``), without the input spectrum."""
        k = 2 * int(horizon) * (self.n_inputs + self.n_outputs)
        return WindowStatistics(
            self.W[:k, :k], self.n_windows, int(horizon), self.n_inputs, self.n_outputs, None, None, self.count
        )

    def blocks(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(XX, YX, YY)``: ``sum x x^T``, ``sum y_p x^T`` and ``sum y_p y_p^T`` of eq. 9
        (computed once per statistics object; read-only views)."""
        return self._blocks

    @cached_property
    def _blocks(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        xi, yi = regressor_indices(self.horizon, self.n_inputs, self.n_outputs)
        # whole rows first, then the columns of that smaller matrix: ~2.5x faster than three
        # np.ix_ gathers at d = 540; row indexing rather than `take`, which first copies a
        # strided W (the leading block of a larger horizon's) whole (RESULTS-subspace.md)
        rows = self.W[np.concatenate([xi, yi])]
        x_cols = rows[:, xi]
        out = (x_cols[: xi.size], x_cols[xi.size :], rows[xi.size :][:, yi])
        for a in out:
            a.flags.writeable = False
        return out


def regressor_indices(horizon: int, n_inputs: int, n_outputs: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions of the regressor ``X`` and of ``y_p(k)`` (eq. 9) inside a window vector.

    Returns
    -------
    x_index : ndarray of shape (2 p m + p q,)
        ``[u_p(k-p); y_p(k-p); u_p(k)]`` in that order.
    y_index : ndarray of shape (p q,)
        ``y_p(k)``.
    """
    p, m, q = horizon, n_inputs, n_outputs
    r = m + q
    pos = np.arange(p)
    u_past = (pos[:, None] * r + np.arange(m)[None, :]).ravel()
    y_past = (pos[:, None] * r + m + np.arange(q)[None, :]).ravel()
    u_fut = ((p + pos)[:, None] * r + np.arange(m)[None, :]).ravel()
    y_fut = ((p + pos)[:, None] * r + m + np.arange(q)[None, :]).ravel()
    return np.concatenate([u_past, y_past, u_fut]), y_fut


def window_statistics(
    u: np.ndarray, y: np.ndarray, horizon: int, forgetting: float = 1.0, with_spectrum: bool = True
) -> WindowStatistics:
    """Normal-equation statistics of eq. 9 for one record, without forming the regressor matrix.

    Parameters
    ----------
    u : ndarray of shape (n_samples, n_inputs)
    y : ndarray of shape (n_samples, n_outputs)
    horizon : int
        ``p`` of eq. 2-9, >= 1; the record needs more than ``2 p`` samples.
    forgetting : float, default 1.0
        Exponential forgetting factor ``lambda`` in (0, 1]: window ``k`` of ``K`` gets the
        weight ``lambda^(K-1-k)``, as in the recursive estimator with forgetting.
    with_spectrum : bool
        Also return the block periodogram of the inputs (for the excited band).

    Returns
    -------
    WindowStatistics

    Raises
    ------
    DataError
        When the record is too short for the horizon.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal((200, 1)); y = np.cumsum(u, axis=0) * 0.1
    >>> s = window_statistics(u, y, horizon=3)
    >>> s.W.shape, s.n_windows
    ((12, 12), 195.0)
    """
    return record_statistics(u, y, [horizon], forgetting, with_spectrum)[horizon]


def record_statistics(
    u: np.ndarray,
    y: np.ndarray,
    horizons: list[int] | tuple[int, ...],
    forgetting: float = 1.0,
    with_spectrum: bool = True,
) -> dict[int, WindowStatistics]:
    """:func:`window_statistics` for several horizons from one pass over the data.

    The lag correlations up to ``2 max(horizons) - 1`` are computed once; each horizon's
    Gram matrix is then assembled from them (cost independent of the record length).
    Horizons that need more samples than the record has are left out of the result.
    """
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    n = u.shape[0]
    if not 0.0 < forgetting <= 1.0:
        raise DataError(f"`forgetting` must be in (0, 1]; got {forgetting}.")
    usable = sorted({int(p) for p in horizons if 2 * int(p) + 1 <= n and int(p) >= 1})
    if not usable:
        raise DataError(f"horizon {min(horizons)} needs records of more than {2 * min(horizons)} samples; got {n}.")
    r = u.shape[1] + y.shape[1]
    Lmax = 2 * usable[-1]
    if forgetting != 1.0:
        t = np.arange(n)
        z = np.hstack([u, y]) * (forgetting ** ((n - 1 - t) / 2.0))[:, None]
        R = lag_correlations(z, Lmax - 1)
    else:  # no joined copy of the record: its ends are all the Gram corrections need
        R = lag_correlations(RecordRows([u, y]), Lmax - 1)
        z = np.vstack([np.hstack([u[:Lmax], y[:Lmax]]), np.hstack([u[n - Lmax :], y[n - Lmax :]])])
    power = freqs = None
    if with_spectrum:
        power, freqs = input_periodogram(u)
    out = {}
    for p in usable:
        L = 2 * p
        K = n - L + 1
        W = window_gram(z, R[:L], p)
        if forgetting != 1.0:
            # z~(t) = lam^((n-1-t)/2) z(t): the weighted window sum is the unweighted one of z~
            # times lam^((K-1) - (n-1) + (a+b)/2) for window positions a, b.
            pos = np.repeat(np.arange(L), r)
            W = W * forgetting ** ((K - 1) - (n - 1) + (pos[:, None] + pos[None, :]) / 2.0)
            n_windows = float(np.sum(forgetting ** np.arange(K)))
        else:
            n_windows = float(K)
        out[p] = WindowStatistics(W, n_windows, p, u.shape[1], y.shape[1], power, freqs, K)
    return out


def hankel_toeplitz_statistics(
    records: list[tuple[np.ndarray, np.ndarray]], horizon: int, forgetting: float = 1.0
) -> WindowStatistics:
    """Eq. 9: the normal-equation statistics of ``y_p(k) = [Gamma Phi D_p] [u_p(k-p); y_p(k-p); u_p(k)]``
    pooled over records ``(u, y)``.

    No window straddles two records; with forgetting, the earlier records' windows are
    discounted by ``forgetting`` to the power of the later records' window counts, as if the
    records had been fed one after the other to the recursion of eq. 17-18.
    """
    stats = None
    for u, y in records:
        s = record_statistics(u, y, [horizon], forgetting)[horizon]
        stats = s if stats is None else stats.scaled(forgetting**s.count) + s
    if stats is None:
        raise DataError("eq. 9 needs at least one record; got none.")
    return stats


def statistics_bytes(horizon: int, n_inputs: int, n_outputs: int) -> float:
    """Memory the statistics of eq. 9 and the posterior of eq. 16-18 take at one horizon.

    The window Gram matrix (``2 p r`` square, ``r = m + q``), its blocks ``XX``, ``YX``, ``YY``,
    and the posterior's information matrix with the solver's copies of it: about five
    float64 matrices of the Gram matrix's size.
    """
    side = 2.0 * horizon * (n_inputs + n_outputs)
    return 5.0 * 8.0 * side * side


def row_residuals(theta: np.ndarray, stats: WindowStatistics) -> np.ndarray:
    """``sum ||y_p - theta x||^2`` over the windows of ``stats``, per row of ``y_p`` (``p q`` values)."""
    XX, YX, YY = stats.blocks()
    return np.diag(YY) - 2.0 * np.einsum("rd,rd->r", theta, YX) + np.einsum("rd,rd->r", theta @ XX, theta)


def segments_statistics(u: np.ndarray, y: np.ndarray, ranges: list[tuple[int, int]], horizon: int) -> WindowStatistics:
    """Statistics of eq. 9 summed over the windows lying inside sample ranges of one record.

    Equal to the sum of :func:`window_statistics` over ``u[a:b], y[a:b]`` for every range, but
    with one FFT pass over all ranges (joined with zero gaps longer than the largest lag) and
    one correction for all range ends, whatever their number (held-out splits).

    Parameters
    ----------
    u : ndarray of shape (n_samples, n_inputs)
    y : ndarray of shape (n_samples, n_outputs)
    ranges : list of (start, stop)
        Sample ranges, each longer than ``2 horizon`` samples.
    horizon : int

    Returns
    -------
    WindowStatistics
        Without the input spectrum.

    Raises
    ------
    DataError
        When a range is too short for the horizon or no range is given.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal((300, 1)); y = rng.standard_normal((300, 1))
    >>> s = segments_statistics(u, y, [(0, 100), (150, 300)], 3)
    >>> t = window_statistics(u[:100], y[:100], 3) + window_statistics(u[150:], y[150:], 3)
    >>> bool(np.allclose(s.W, t.W)), s.count
    (True, 240)
    """
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    p = int(horizon)
    L = 2 * p
    if not ranges:
        raise DataError("segments_statistics needs at least one sample range; got none.")
    short = [(a, b) for a, b in ranges if b - a <= L]
    if short:
        raise DataError(f"horizon {p} needs ranges of more than {L} samples; got {short[0][1] - short[0][0]}.")
    R = lag_correlations(RecordRows([u, y], ranges, gap=L), L - 1)
    heads, tails = range_ends(u, y, ranges, L)
    return lag_statistics(R, heads, tails, int(sum(b - a - L + 1 for a, b in ranges)), u.shape[1])


def lag_statistics(R: np.ndarray, heads: np.ndarray, tails: np.ndarray, count: int, n_inputs: int) -> WindowStatistics:
    """:class:`WindowStatistics` (no input spectrum) of the windows inside segments, from their
    summed lag correlations ``R`` (lags ``0 .. 2 p - 1``), the first and last ``2 p`` samples
    of each (``heads``, ``tails``) and the number of windows (:func:`~.correlations.gram_from_lags`)."""
    L, r, _ = R.shape
    W = gram_from_lags(R, heads, tails)
    return WindowStatistics(W, float(count), L // 2, n_inputs, r - n_inputs, None, None, int(count))


def dense_regression(u: np.ndarray, y: np.ndarray, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """The explicit regression of eq. 9 (reference implementation for tests and small data).

    Returns
    -------
    X : ndarray of shape (n_windows, 2 p m + p q)
        Rows ``[u_p(k-p); y_p(k-p); u_p(k)]^T``.
    Y : ndarray of shape (n_windows, p q)
        Rows ``y_p(k)^T``.
    """
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    p = horizon
    n = u.shape[0]
    if n < 2 * p + 1:
        raise DataError(f"horizon {p} needs records of more than {2 * p} samples; got {n}.")
    k = np.arange(p, n - p + 1)

    def stack(s: np.ndarray, offset: int) -> np.ndarray:
        return np.hstack([s[k + offset + i] for i in range(p)])

    X = np.hstack([stack(u, -p), stack(y, -p), stack(u, 0)])
    return X, stack(y, 0)


def split_theta(
    theta: np.ndarray, horizon: int, n_inputs: int, n_outputs: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``theta = [Gamma Phi D_p]`` (eq. 16) -> ``(Gamma, Phi, D_p)``."""
    p, m, q = horizon, n_inputs, n_outputs
    expected = (p * q, 2 * p * m + p * q)
    if theta.shape != expected:
        raise DataError(f"`theta` must have shape {expected}; got {theta.shape}.")
    return theta[:, : p * m], theta[:, p * m : p * m + p * q], theta[:, p * m + p * q :]
