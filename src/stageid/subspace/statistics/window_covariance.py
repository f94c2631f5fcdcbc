"""Covariance of the eq. 9 response under overlapping windows (Cao & Chen 2013, eq. 9 and 16-18).

Consecutive windows of eq. 9 share ``2 p - 1`` samples, so the errors ``Delta(k)`` of nearby
windows are correlated: with white output noise, ``Delta(k)`` holds the noise of samples
``k - p .. k + p - 1`` and is a moving average of order ``2 p - 1``.  The recursion of eq. 17
treats the windows as independent, so ``P (x) Sigma`` understates the least-squares
coefficients' covariance; the ``p P`` allowance of ``response_bands`` is a rough fix.  This
module computes the covariance the least-squares (MAP) coefficients actually have, for the one
thing the uncertainty needs: the eq. 9 response on a grid.

To first order ``dG_k = L_k^+ dtheta V_k`` and ``dtheta = sum_t Delta(t) x(t)^T P``, so

    dG_k = sum_t b_t(k) a_t(k)^T,   b_t(k) = L_k^+ Delta(t),   a_t(k) = (P V_k)^T x(t),

two FIR-filtered versions of the window signal ``z = [u; y]``.  With ``Delta`` independent of
the regressors and stationary (a heteroskedasticity-and-autocorrelation-consistent sandwich
with the truncated kernel, lags ``|l| <= 2 p - 1``: exact for a moving average of that order),

    E[dG_k(i, j) conj dG_l(i', j')] = sum_l Sb_l[(k,i), (l,i')] A_l[(k,j), (l,j')],

``A_l = sum_t a_t conj(a_(t+l))^T`` (the sample lag products of the regressor filter) and
``Sb_l = E[b_t conj(b_(t+l))^T]`` (the residual filter's lag covariance, estimated from the
residuals per window); the pseudo-covariance likewise without the conjugates.  Both come from
the lag correlations ``R(c) = sum_t z(t) z(t+c)^T`` of the records up to ``c = 4 p - 2`` and
their first and last ``4 p - 2`` samples (:class:`WindowLags`, kept by the fit), through the
spectral identity ``sum_(a,b) h(a)^T R(l + b - a) conj h'(b) = 1/n sum_w e^(i w l) H(w)^T S(w) conj H'(w)``
with ``S`` the DFT of ``R`` (no lag wraps for ``n = 8 p``), minus the pairs in which a window
sticks out of a record.  Only the lags ``l >= 0`` are formed: those at ``-l`` are their
(conjugate) transposes.  :func:`self_lag_products` forms them, splitting the double sum so that
the products and the inverse DFT need ``4 p`` points instead of ``8 p``: cost ``~ 4 p (n_freqs max(q, m))^2`` times
``(m + q + 3 n_records)`` for the products and ``log(4 p)`` for the transform, independent of
the record length (``benchmarks/RESULTS-uncertainty.md``).  The covariance under overlapping
windows of Hankel-Toeplitz estimates and its calibration are measured in
``studies/uncertainty/RESULTS.md``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .correlations import RecordRows, lag_correlations, range_ends
from .hankel_toeplitz import WindowStatistics, lag_statistics, regressor_indices
from .theta_response import response_systems

__all__ = [
    "WindowLags",
    "window_lags",
    "WindowFilter",
    "lag_spectrum",
    "self_lag_products",
    "lag_sum",
    "overlap_response_covariance",
    "response_directions",
]

#: Most complex entries of the per-frequency spectral products formed at once (cache, memory).
BLOCK_ENTRIES = 1 << 18


@dataclass(frozen=True, eq=False)
class WindowLags:
    """What :func:`overlap_response_covariance` needs of the records, kept by the fit (a few
    ``(m + q)^2 p`` numbers, not the records).  Taken once per fit at its largest candidate
    horizon, they also give the records' eq. 9 statistics at any horizon up to it
    (:meth:`statistics`) and, less the held-out segments', the training segments' lag
    correlations (:func:`~stageid.subspace.selection.split_statistics`).

    Attributes
    ----------
    lags : ndarray of shape (4 p - 1, m + q, m + q)
        ``R(c) = sum_t z(t) z(t+c)^T`` of ``z = [u y]``, summed over the records.
    heads, tails : ndarray of shape (n_records, 4 p - 2, m + q)
        The first and last ``4 p - 2`` samples of every record: the windows sticking out of a
        record (which ``R`` counts, zero-padded) are subtracted exactly from them.
    lengths : tuple of int
        The records' numbers of samples.
    """

    lags: np.ndarray
    heads: np.ndarray
    tails: np.ndarray
    lengths: tuple[int, ...]

    def weighted(self, scale: np.ndarray) -> WindowLags:
        """The same for ``z`` times ``scale`` (per channel)."""
        return WindowLags(
            self.lags * np.outer(scale, scale)[None], self.heads * scale, self.tails * scale, self.lengths
        )

    @property
    def horizon(self) -> int:
        """The horizon ``p`` the lags are for (``4 p - 1`` of them)."""
        return (self.lags.shape[0] + 1) // 4

    def at(self, horizon: int) -> WindowLags:
        """The same for a horizon up to :attr:`horizon` (fewer lags and end samples)."""
        p = int(horizon)
        if p == self.horizon:
            return self
        e = 4 * p - 2
        return WindowLags(self.lags[: e + 1].copy(), self.heads[:, :e].copy(), self.tails[:, -e:].copy(), self.lengths)

    def statistics(self, horizon: int, n_inputs: int) -> WindowStatistics:
        """The records' eq. 9 statistics at a horizon up to :attr:`horizon` (no input spectrum):
        their lag correlations less the windows sticking out (:func:`~.correlations.gram_from_lags`)."""
        L = 2 * int(horizon)
        count = sum(n - L + 1 for n in self.lengths)
        return lag_statistics(self.lags[:L], self.heads[:, :L], self.tails[:, -L:], count, n_inputs)


def window_lags(records: list[tuple[np.ndarray, np.ndarray]], horizon: int) -> WindowLags | None:
    """:class:`WindowLags` of the records at ``horizon``; None when a record is shorter than ``8 p``
    (its head and tail windows would meet)."""
    p = int(horizon)
    if any(u.shape[0] < 8 * p for u, _ in records):
        return None
    L = 4 * p - 1
    r = records[0][0].shape[1] + records[0][1].shape[1]
    R = np.zeros((L, r, r))
    for u, y in records:
        R += lag_correlations(RecordRows([u, y]), L - 1)
    ends = [range_ends(u, y, [(0, u.shape[0])], L - 1) for u, y in records]
    heads = np.concatenate([h for h, _ in ends])
    tails = np.concatenate([t for _, t in ends])
    return WindowLags(R, heads, tails, tuple(u.shape[0] for u, _ in records))


def lag_spectrum(R: np.ndarray, n: int) -> np.ndarray:
    """``S(w_k) = sum_c R(c) e^(-i w_k c)`` over ``c = -(L-1) .. L-1`` (``R(-c) = R(c)^T``), shape (n, r, r)."""
    L = R.shape[0]
    full = np.zeros((n,) + R.shape[1:])
    full[:L] = R
    full[n - L + 1 :] = R[:0:-1].transpose(0, 2, 1)
    return np.fft.fft(full, axis=0)


class WindowFilter:
    """A filter of the windows, ``s_t = sum_pos h[pos]^T w_t[pos]`` (one column per output), with
    the DFTs the lag products need over the window positions: ``H`` on ``n / 2`` points and, on
    ``n`` points, the real DFT ``H_parts`` of ``[Re h, Im h]`` (the window signal is real)."""

    def __init__(self, weights: np.ndarray, positions: np.ndarray, horizon: int, r: int, n: int):
        c = weights.shape[1]
        parts = np.zeros((2 * horizon * r, 2 * c))  # [Re h, Im h]
        parts[positions, :c] = np.real(weights)
        parts[positions, c:] = np.imag(weights)
        self.parts = parts.reshape(2 * horizon, r, 2 * c)
        self.h = (parts[:, :c] + 1j * parts[:, c:]).reshape(2 * horizon, r, c)
        self.H = np.fft.fft(self.h, n=n // 2, axis=0)  # sum_a h(a) e^(-i w a)
        self.H_parts = np.fft.rfft(self.parts, n=n, axis=0)

    def edge_series(self, samples: np.ndarray, head: bool) -> np.ndarray:
        """``s_t`` of the ``4 p - 2`` windows at a record's head (``t = -(2p-1) .. 2p-2``) or tail
        (``t = K-(2p-1) .. n-1``), the record zero-padded, from its ``4 p - 2`` end samples."""
        L, r, c = self.h.shape
        pad = np.zeros((L - 1, samples.shape[1]))
        z = np.vstack([pad, samples]) if head else np.vstack([samples, pad])
        win = np.lib.stride_tricks.sliding_window_view(z, L, axis=0)  # (4p-2, r, L)
        # real windows times a complex filter: one real product with [Re h, Im h]
        win = win.transpose(0, 2, 1).reshape(win.shape[0], L * r)
        s = win @ self.parts.reshape(L * r, 2 * c)
        return s[:, :c] + 1j * s[:, c:]


def self_lag_products(f: WindowFilter, S: np.ndarray, stats: WindowLags) -> tuple[np.ndarray, np.ndarray]:
    """``sum_t s_t conj(s_(t+l))^T`` and ``sum_t s_t s_(t+l)^T`` of one filter over the pairs of
    windows lying wholly inside a record, at the lags ``0 .. 2 p - 1``, on half the DFT points:
    two arrays of shape (2 p, cols, cols).

    ``sum_(a,b) h(a)^T R(l + b - a) conj h(b)`` is split as ``sum_a h(a)^T Q(l - a)`` with
    ``Q(c) = sum_b R(c + b) conj h(b)`` (``r`` columns per filter column: cheap on ``8 p`` points),
    kept at ``|c| <= 2 p - 1``, the only ``c`` the lags ``0 .. 2 p - 1`` reach, so the outer sum
    needs ``4 p`` points, not ``8 p``.  Of the pairs with a window sticking out of a record,
    only those at ``l >= 0`` are formed (at a head the first window is outside, at a tail the
    second), and none of them wraps on ``4 p`` points.
    """
    p = f.h.shape[0] // 2
    n, n2, half = S.shape[0], 4 * p, 2 * p - 1
    r, c = f.h.shape[1:]
    # R and the window signal are real: Q(c) = Q_re(c) - i Q_im(c) from one real correlation with
    # [Re h, Im h] (half the spectrum); the pseudo's sum_b R(c + b) h(b) is its conjugate
    parts = np.fft.irfft(np.matmul(S[: n // 2 + 1], np.conj(f.H_parts)), n=n, axis=0)
    Q2 = np.zeros((n2, r, c), dtype=complex)
    Q2.real[: half + 1] = parts[: half + 1, :, :c]
    Q2.real[n2 - half :] = parts[n - half :, :, :c]
    Q2.imag[: half + 1] = parts[: half + 1, :, c:]
    Q2.imag[n2 - half :] = parts[n - half :, :, c:]
    np.conjugate(Q2, out=Q2)
    zero = np.zeros((half, c), dtype=complex)
    xs, ys = [], []
    for samples in stats.heads:
        # the first window outside (t < 0), the second anywhere: t + l <= 2p - 2, no wrap
        x = f.edge_series(samples, True)
        xs.append(np.concatenate([x[:half], zero]))
        ys.append(np.hstack([np.conj(x), x]))
    for samples in stats.tails:
        # the second window outside (t + l >= K), the first anywhere: t + l <= 4p - 3, no wrap
        x = f.edge_series(samples, False)
        outer = np.concatenate([zero, x[half:]])
        xs.append(x)
        ys.append(np.hstack([np.conj(outer), outer]))
    # sum_t x_t y_(t+l)^T is the inverse DFT of X~(w) Y(w)^T, X~(w) = sum_t x_t e^(+i w t)
    Xt = np.conj(np.fft.fft(np.conj(np.stack(xs)), n=n2, axis=1)).transpose(1, 2, 0)  # (n2, cols, pieces)
    Y = np.fft.fft(np.stack(ys), n=n2, axis=1).transpose(1, 0, 2)  # (n2, pieces, 2 cols)
    left = np.concatenate([f.H.transpose(0, 2, 1), -Xt], axis=2)
    right = np.empty((n2, r + Y.shape[1], 2 * c), dtype=complex)
    np.fft.fft(Q2, axis=0, out=right[:, :r, :c])
    # the DFT of conj(Q) at w is conj(DFT of Q) at -w
    np.conjugate(right[0, :r, :c], out=right[0, :r, c:])
    np.conjugate(right[:0:-1, :r, :c], out=right[1:, :r, c:])
    right[:, r:] = Y
    # stored lag-last (the transform's output lines are contiguous, and :func:`lag_sum`'s
    # regrouping copies runs of lags), returned as (lag, row, column) views
    store = np.empty((c, 2 * c, n2), dtype=complex)
    both = store.transpose(2, 0, 1)
    step = max(1, BLOCK_ENTRIES // (n2 * right.shape[2]))  # a few MB per block: it stays in cache
    for lo in range(0, c, step):
        np.fft.ifft(np.matmul(left[:, lo : lo + step], right), axis=0, out=both[:, lo : lo + step])
    return both[: 2 * p, :, :c], both[: 2 * p, :, c:]


def overlap_response_covariance(
    theta: np.ndarray,
    column_cov: np.ndarray | Callable[[np.ndarray], np.ndarray],
    stats: WindowLags,
    n_windows: float,
    horizon: int,
    n_inputs: int,
    n_outputs: int,
    freqs: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The eq. 9 response on a grid and the covariance of its error across the grid (module docstring).

    Parameters
    ----------
    theta : ndarray of shape (p q, d)
        Posterior mean in the coordinates of ``lag_corr``.
    column_cov : ndarray of shape (d, d), or a callable
        ``P`` (the inverse of the posterior information ``sum x x^T + P_0^-1``), same coordinates,
        or ``V -> P V`` (a solve with the information: no inverse formed).
    stats : WindowLags
        Of the records, in the same coordinates.
    n_windows : float
        Windows of the fit (the residual covariance is their sum over ``n_windows - d``).

    Returns
    -------
    G : ndarray of shape (n_freqs, q, m), complex
    cov, pseudo : ndarrays of shape (n_freqs q m, n_freqs q m), complex (``vec`` in (k, i, j) order)
    """
    p, m, q = horizon, n_inputs, n_outputs
    r, d = m + q, theta.shape[1]
    G, Lp, V = response_directions(theta, p, m, q, freqs, dt)
    nz = G.shape[0]
    xi, yi = regressor_indices(p, m, q)
    n = 8 * p  # > 8 p - 4: no lag |l| <= 2p - 1 wraps (module docstring)
    S = lag_spectrum(stats.lags, n)
    # lags 0 .. 2p - 1 only: the products at -l are those at l transposed (and conjugated for cov)
    # a_t = (P V)^T x_t: the regressor filter, one column per (k, j)
    PV = column_cov(V) if callable(column_cov) else column_cov @ V
    A_c, A_p = self_lag_products(WindowFilter(PV, xi, p, r, n), S, stats)
    # b_t = L^+ (y_p - theta x)_t: the residual filter, one column per (k, i)
    E = np.zeros((p * q, 2 * p * r))
    E[:, yi] = np.eye(p * q)
    E[:, xi] = -theta
    fb = WindowFilter(E.T @ Lp.reshape(nz * q, p * q).T, np.arange(2 * p * r), p, r, n)
    B_c, B_p = self_lag_products(fb, S, stats)
    dof = max(float(n_windows) - d, 1.0)
    # sum over l >= 0 of B(l) (.) A(l), lag 0 at half weight; the negative lags add its (conjugate) transpose
    half_c = lag_sum(B_c, A_c, nz, q, m) / dof
    half_p = lag_sum(B_p, A_p, nz, q, m) / dof
    return G, half_c + np.conj(half_c).T, half_p + half_p.T


def lag_sum(B: np.ndarray, A: np.ndarray, nz: int, q: int, m: int) -> np.ndarray:
    """``sum_l w_l B(l)[(k,i),(k',i')] A(l)[(k,j),(k',j')]`` over the lags of ``B`` and ``A``
    (shapes (n_lags, nz q, nz q) and (n_lags, nz m, nz m)), ``w_0 = 1/2``, else 1, as a matrix
    over ``(k, i, j)`` x ``(k', i', j')``: one product over the lags per pair ``(k, k')``."""
    L = B.shape[0]
    # both regrouped lags-last (contiguous runs when the lags are, as from :func:`self_lag_products`)
    Bt = B.reshape(L, nz, q, nz, q).transpose(1, 3, 2, 4, 0).reshape(nz, nz, q * q, L)
    At = A.reshape(L, nz, m, nz, m).transpose(1, 3, 2, 4, 0).reshape(nz, nz, m * m, L)
    # lag 0 at half weight: its term taken off again (no in-place scaling of what may be a view)
    out = np.matmul(Bt, At.swapaxes(2, 3)) - 0.5 * Bt[..., :1] * At[:, :, None, :, 0]
    out = out.reshape(nz, nz, q, q, m, m)
    N = nz * q * m
    return out.transpose(0, 2, 4, 1, 3, 5).reshape(N, N)


def response_directions(
    theta: np.ndarray, p: int, m: int, q: int, freqs: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(G, L^+, V)``: the eq. 9 response ``G_k = L_k^+ theta V_k`` on a grid, each block system's
    least-squares inverse ``L_k^+`` (nz, q, pq) and ``V_k = [e_past (x) I_m; e_past (x) G_k;
    e_fut (x) I_m]`` for all ``k`` side by side (d, nz m): ``dG_k = L_k^+ dtheta V_k``."""
    lhs, rhs, e_past, e_fut = response_systems(theta, p, m, q, freqs, dt)
    nz = e_past.shape[0]
    lh = np.conj(lhs).transpose(0, 2, 1)
    Lp = np.linalg.solve(lh @ lhs, lh)
    G = Lp @ rhs
    eye = np.eye(m)[None, :, None, :]
    V = np.concatenate(
        [
            (e_past.T[:, None, :, None] * eye).reshape(p * m, nz * m),
            (e_past.T[:, None, :, None] * G.transpose(1, 0, 2)[None]).reshape(p * q, nz * m),
            (e_fut.T[:, None, :, None] * eye).reshape(p * m, nz * m),
        ]
    )
    return G, Lp, V
