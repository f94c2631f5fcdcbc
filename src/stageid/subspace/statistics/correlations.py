"""Lag correlations and the exact window Gram matrix of eq. 9 from them (Cao & Chen 2013, 2.1).

Every regression sample of eq. 9 is one window of ``2 p`` consecutive samples of
``z(t) = [u(t); y(t)]``; the Gram matrix of the windows is the lag correlations of ``z``
(computed in blocks with FFTs, cost independent of ``p``) minus exact corrections for the
first and last samples of every record or segment.  :mod:`.hankel_toeplitz` builds its
:class:`~stageid.subspace.statistics.hankel_toeplitz.WindowStatistics` from these.  The lag products
straddling the boundaries between segments (:func:`straddling_lags`) turn a record's lag
correlations into those of its segments.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import as_strided

from ..._errors import DataError

__all__ = [
    "lag_correlations",
    "spectral_products",
    "straddling_lags",
    "RecordRows",
    "range_ends",
    "gram_from_lags",
    "diagonal_rows",
    "window_gram",
    "window_gram_python",
    "input_periodogram",
]


def lag_correlations(z: np.ndarray, max_lag: int, block: int | None = None) -> np.ndarray:
    """Lag correlations ``R[c] = sum_t z(t) z(t+c)^T`` for ``c = 0 .. max_lag``.

    Computed with zero-padded FFTs of consecutive blocks (overlap-add of the cross-spectra),
    so the cost is about ``n_samples (r^2 + r log block)`` whatever ``max_lag`` is, and the
    memory is a few blocks.  The result is exact to rounding.

    Parameters
    ----------
    z : ndarray of shape (n_samples, r)
    max_lag : int
        Largest lag, ``0 <= max_lag < n_samples``.
    block : int, optional
        Block length (>= max_lag); default the next power of two >= max(128, max_lag).

    Returns
    -------
    ndarray of shape (max_lag + 1, r, r)
        ``R[c, a, b] = sum_{t=0}^{N-1-c} z[t, a] z[t+c, b]``.

    Examples
    --------
    >>> import numpy as np
    >>> z = np.arange(10.0).reshape(5, 2)
    >>> R = lag_correlations(z, 1)
    >>> bool(np.allclose(R[1], z[:-1].T @ z[1:]))
    True
    """
    src = z if isinstance(z, RecordRows) else RecordRows([np.asarray(z, dtype=float)])
    n, r = src.n, src.r
    if not 0 <= max_lag < max(n, 1):
        raise DataError(f"`max_lag` must satisfy 0 <= max_lag < n_samples = {n}; got {max_lag}.")
    if block is None:
        block = 1 << max(7, int(np.ceil(np.log2(max(max_lag, 1)))))
    if block < max_lag:
        raise DataError(f"`block` must be >= max_lag = {max_lag}; got {block}.")
    n_blocks = -(-n // block)
    nfft = 2 * block
    sign = np.where(np.arange(block + 1) % 2 == 0, 1.0, -1.0)[:, None]  # exp(-j pi f): shift by one block
    # real products of the spectra (real and imaginary parts side by side): [0] of each block
    # with itself, [1] with the next; no conjugated or summed copies of the batch spectra
    P = np.zeros((2, block + 1, 2 * r, 2 * r))
    # blocks per FFT batch: ~1 MB per batch array.  Larger batches are slower, not faster: each
    # fresh multi-megabyte temporary costs page faults, small ones are reused from the
    # allocator's free lists and stay in cache (figures: benchmarks/RESULTS-subspace.md)
    chunk = min(n_blocks, max(1, (1 << 17) // (nfft * max(r, 1))))
    seg = np.zeros((chunk + 1, nfft, r))  # zero-padded blocks, reused by every batch
    start = 0
    # Spectra are computed batch by batch; the first spectrum of the next batch is needed
    # for the last block of the current one, so batches overlap by one block.
    while start < n_blocks:
        stop = min(n_blocks, start + chunk)
        k = stop - start + 1
        src.fill(seg[:k, :block], start * block)
        F = _real_view(np.fft.rfft(seg[:k], axis=1))  # (k, block+1, 2r)
        Fa = F[:-1].transpose(1, 2, 0)
        P[0] += np.matmul(Fa, F[:-1].transpose(1, 0, 2))
        P[1] += np.matmul(Fa, F[1:].transpose(1, 0, 2))
        start = stop
    # S[f] = sum_k conj(F_k)^T (F_k + sign F_(k+1))
    C = spectral_products(P, conjugate=True)
    S = C[0] + sign[:, :, None] * C[1]
    R = np.fft.irfft(S, n=nfft, axis=0)[: max_lag + 1]
    return np.ascontiguousarray(R)


def spectral_products(P: np.ndarray, conjugate: bool) -> np.ndarray:
    """``sum_k conj(a_k)^T b_k`` (or ``sum_k a_k^T b_k``) of complex vectors from the real products
    ``P = sum_k [ar ai]^T [br bi]`` of their real and imaginary parts side by side (interleaved,
    as ``ndarray.view(float)`` of a complex array lays them out), over any leading axes.

    ``conj(a) b = (ar br + ai bi) + j (ar bi - ai br)`` and ``a b = (ar br - ai bi) + j (ar bi + ai br)``:
    real matrix products of views, no conjugated copies of the spectra.
    """
    rr, ii, ri, ir = P[..., 0::2, 0::2], P[..., 1::2, 1::2], P[..., 0::2, 1::2], P[..., 1::2, 0::2]
    if conjugate:
        return rr + ii + 1j * (ri - ir)
    return rr - ii + 1j * (ri + ir)


def _real_view(F: np.ndarray) -> np.ndarray:
    """A complex array as real numbers, the real and imaginary part of each entry side by side
    (a copy only when its last axis is not contiguous: FFTs follow their input's layout)."""
    return np.ascontiguousarray(F).view(float)


def straddling_lags(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Lag products of the sample pairs that straddle joints, summed over the joints.

    Joint ``j`` has the ``M`` samples ``before[j]`` just before it and ``after[j]`` from it on;
    with ``s = [before[j]; after[j]]`` the result is ``X[c] = sum_j sum_{M-c <= t < M} s(t) s(t+c)^T``
    for ``c = 0 .. M`` (``X[0] = 0``): what the lag correlations of a record hold beyond the sum
    of those of its pieces cut at the joints, when every piece is longer than ``M``.  A
    convolution of the reversed ``before`` with ``after`` (zero-padded FFTs of ``>= 2 M`` points).

    Parameters
    ----------
    before, after : ndarray of shape (n_joints, M, r)

    Returns
    -------
    ndarray of shape (M + 1, r, r)

    Examples
    --------
    >>> import numpy as np
    >>> z = np.random.default_rng(0).standard_normal((40, 2))
    >>> X = straddling_lags(z[None, 17:20], z[None, 20:23])
    >>> bool(np.allclose(X[2], z[18:20].T @ z[20:22]))
    True
    """
    n_joints, M, r = before.shape
    nfft = 1 << int(np.ceil(np.log2(2 * M)))  # >= 2 M - 1: no wrap; a power of two: fast
    A = _real_view(np.fft.rfft(before[:, ::-1], n=nfft, axis=1))  # (n_joints, nfft / 2 + 1, 2r)
    B = _real_view(np.fft.rfft(after, n=nfft, axis=1))
    # sum_(t' = 0)^(c-1) before(M-1-t') after(c-1-t')^T is the convolution's term c - 1
    conv = np.fft.irfft(spectral_products(np.matmul(A.transpose(1, 2, 0), B.transpose(1, 0, 2)), False), nfft, 0)
    out = np.zeros((M + 1, r, r))
    out[1:] = conv[:M]
    return out


class RecordRows:
    """The rows of ``[u y]`` (column blocks side by side) over sample ranges joined by zero
    gaps, read batch by batch (:meth:`fill`) without forming the joined array: the record is
    never copied whole (see the batch size in :func:`lag_correlations`)."""

    def __init__(self, blocks: list[np.ndarray], ranges: list[tuple[int, int]] | None = None, gap: int = 0):
        self.blocks = blocks
        self.r = sum(b.shape[1] for b in blocks)
        self.pieces: list[tuple[int, int, int]] = []  # (virtual start, a, b)
        v = 0
        for i, (a, b) in enumerate(ranges if ranges is not None else [(0, blocks[0].shape[0])]):
            v += gap if i else 0
            self.pieces.append((v, a, b))
            v += b - a
        self.n = v

    def fill(self, out: np.ndarray, lo: int) -> None:
        """Rows ``lo ..`` into ``out`` of shape (n_frames, block, r), frame after frame (the data
        halves of the zero-padded FFT frames, written in place), zero in the gaps and past the end."""
        n_frames, block, _ = out.shape
        hi = lo + n_frames * block
        done = 0  # rows of `out` written so far
        for v, a, b in self.pieces:
            s, e = max(lo, v), min(hi, v + b - a)
            if s >= e:
                continue
            _put_rows(out, done, s - lo, None)
            c = 0
            for blk in self.blocks:
                w = blk.shape[1]
                _put_rows(out[:, :, c : c + w], s - lo, e - lo, blk[a + s - v : a + e - v])
                c += w
            done = e - lo
        _put_rows(out, done, n_frames * block, None)


def _put_rows(out: np.ndarray, s: int, e: int, rows: np.ndarray | None) -> None:
    """``rows`` (zeros when None) into rows ``s .. e-1`` of ``out`` of shape (n_frames, block, w)
    read frame after frame: at most three assignments (a partial frame, whole frames, a partial frame)."""
    if s >= e:
        return
    block = out.shape[1]
    j0, o0 = divmod(s, block)
    j1, o1 = divmod(e, block)
    if j0 == j1:
        out[j0, o0:o1] = 0.0 if rows is None else rows
        return
    first = block - o0
    out[j0, o0:] = 0.0 if rows is None else rows[:first]
    if j1 > j0 + 1:
        n = (j1 - j0 - 1) * block
        out[j0 + 1 : j1] = 0.0 if rows is None else rows[first : first + n].reshape(j1 - j0 - 1, block, -1)
    if o1:
        out[j1, :o1] = 0.0 if rows is None else rows[e - s - o1 :]


def range_ends(
    u: np.ndarray, y: np.ndarray, ranges: list[tuple[int, int]], length: int
) -> tuple[np.ndarray, np.ndarray]:
    """The first and the last ``length`` samples of ``z = [u y]`` in every sample range:
    two arrays of shape (n_ranges, length, n_inputs + n_outputs)."""
    heads = np.stack([np.hstack([u[a : a + length], y[a : a + length]]) for a, _ in ranges])
    tails = np.stack([np.hstack([u[b - length : b], y[b - length : b]]) for _, b in ranges])
    return heads, tails


def window_gram_python(z: np.ndarray, R: np.ndarray, horizon: int) -> np.ndarray:
    """Reference of :func:`window_gram` (plain numpy)."""
    n, r = z.shape
    L = 2 * horizon
    K = n - L + 1  # number of windows
    W = np.zeros((L, L, r, r))
    for c in range(L):
        # W[0, c] = R[c] - tail terms t = K .. n-1-c
        first = R[c] - z[K : n - c].T @ z[K + c : n]
        count = L - c  # entries W[a, a+c], a = 0 .. L-1-c
        vals = np.empty((count, r, r))
        vals[0] = first
        for a in range(1, count):
            # W[a, a+c] = W[a-1, a-1+c] - z(a-1) z(a-1+c)^T + z(a-1+K) z(a-1+c+K)^T
            vals[a] = vals[a - 1] - np.outer(z[a - 1], z[a - 1 + c]) + np.outer(z[a - 1 + K], z[a - 1 + c + K])
        idx = np.arange(count)
        W[idx, idx + c] = vals
        if c:
            W[idx + c, idx] = vals.transpose(0, 2, 1)
    return W.transpose(0, 2, 1, 3).reshape(L * r, L * r)


def gram_from_lags(R: np.ndarray, heads: np.ndarray, tails: np.ndarray) -> np.ndarray:
    """Exact window Gram matrix summed over segments, from their summed lag correlations.

    For one segment ``s`` of ``n_s`` samples with ``K = n_s - L + 1`` windows of length
    ``L``, block ``(a, b)`` (``b >= a``, ``c = b - a``) of ``sum_k w(k) w(k)^T`` is

        R[c] - sum_{t < a} s(t) s(t+c)^T - sum_{t = K+a}^{n_s-1-c} s(t) s(t+c)^T,

    i.e. the lag correlation minus products of the first and of the last ``L`` samples
    only.  Along a block diagonal, block ``(a, a+c)`` differs from ``(a-1, a-1+c)`` by the
    window that leaves and the one that enters, ``f(a) f(a+c)^T - h(a-1) h(a-1+c)^T`` with
    ``h`` the heads and ``f`` the tails (summed over the segments): block ``(a, a+c)`` of
    ``N = F^T F - H'^T H'``, ``H'`` the heads delayed by one sample.  So each block row is the
    previous one plus a block row of ``N``, from a virtual block row ``-1`` of
    ``R[c] - sum_t f(t) f(t+c)^T``: one pass down the block rows of a view that starts every
    block row at its diagonal block (:func:`diagonal_rows`), ``N`` formed a band of block rows
    at a time, for any number of segments at ``O(L^2 r^2 n_segments)``.  The upper block
    triangle so formed is then mirrored.

    Parameters
    ----------
    R : ndarray of shape (L, r, r)
        Lag correlations (lags 0 .. L-1) summed over the segments.
    heads, tails : ndarray of shape (n_segments, L, r)
        The first and the last ``L`` samples of each segment.

    Returns
    -------
    ndarray of shape (L r, L r)
    """
    L, r, _ = R.shape
    Lr = L * r
    n_seg = heads.shape[0]
    tails = np.asarray(tails, dtype=float)
    # the tails' own lag sums (zero-padded FFT: no wrap), for the virtual block row -1
    X = _real_view(np.fft.rfft(tails, n=2 * L, axis=1))  # (n_seg, L + 1, 2r)
    P = np.matmul(X.transpose(1, 2, 0), X.transpose(1, 0, 2))
    own = np.fft.irfft(spectral_products(P, conjugate=True), 2 * L, 0)
    prev = (R - own[:L]).transpose(1, 0, 2).reshape(r, Lr)  # row (-1, i) from its diagonal block on
    # N = G^T G2: G the delayed heads and the tails, G2 the same with the tails negated
    G2 = np.zeros((2 * n_seg, L, r))
    G2[:n_seg, 1:] = heads[:, : L - 1]
    G2[n_seg:] = tails
    G = np.ascontiguousarray(G2.reshape(2 * n_seg, Lr).T)
    G2[:n_seg] *= -1.0
    G2 = G2.reshape(2 * n_seg, Lr)
    # one spare row for the diagonal views (the parts of them used stay in the upper blocks)
    buf = np.empty((Lr + 1, Lr))
    W_diag = diagonal_rows(buf, L, r)
    # N is formed a band of block rows at a time (~0.5 MB): a whole (L r)^2 temporary costs
    # more in first-touch page faults and cache misses than the extra products
    n_band = max(1, min(L, (1 << 16) // (r * Lr)))
    band = np.empty((n_band * r + 1) * Lr)  # one spare row: the view of the last row runs past
    for a0 in range(0, L, n_band):
        a1 = min(L, a0 + n_band)
        N_diag = _band_diagonal_rows(band, G, G2, a0, a1, r)
        for a in range(a0, a1):
            # W[a, a + c] = W[a-1, a-1+c] + f(a) f(a+c)^T - h(a-1) h(a-1+c)^T, c < L - a
            prev = np.add(prev[:, : Lr - a * r], N_diag[a - a0, :, : Lr - a * r], out=W_diag[a, :, : Lr - a * r])
    W = buf[:Lr]
    for a in range(1, L):  # the diagonal views wrote only the upper blocks correctly
        W[a * r : (a + 1) * r, : a * r] = W[: a * r, a * r : (a + 1) * r].T
    return W


def diagonal_rows(buf: np.ndarray, L: int, r: int) -> np.ndarray:
    """View ``V[a, i, c r + j] = buf[a r + i, (a + c) r + j]`` of an ``(L r + 1, L r)`` buffer.

    Block row ``a`` of the ``(L r) x (L r)`` matrix in ``buf[:L r]`` from its diagonal block
    on, so ``V[a, :, c r : (c+1) r]`` is block ``(a, a + c)`` and the recursion along the block
    diagonals becomes a sum over ``a``.  Columns ``c >= L - a`` wrap into the strictly lower
    blocks of the following rows (the last row into the spare row): they are not blocks
    ``(a, a + c)``.
    """
    s = buf.itemsize
    Lr = L * r
    return as_strided(buf, shape=(L, r, Lr), strides=((r * Lr + r) * s, Lr * s, s))


def _band_diagonal_rows(band: np.ndarray, G: np.ndarray, G2: np.ndarray, a0: int, a1: int, r: int) -> np.ndarray:
    """Block rows ``a0 .. a1-1`` of ``N = G G2`` from block column ``a0`` on, in ``band`` (flat
    scratch), as the diagonal rows of :func:`diagonal_rows`: ``V[k - a0, i, c r + j] =
    N[k r + i, (k + c) r + j]``.

    Only the entries ``c < L - k`` are blocks of ``N`` (the rest of a view row runs into the
    next row of the band).
    """
    w = G2.shape[1] - a0 * r  # the band's width: no block left of the diagonal block is needed
    rows = (a1 - a0) * r
    np.matmul(G[a0 * r : a1 * r], G2[:, a0 * r :], out=band[: rows * w].reshape(rows, w))
    s = band.itemsize
    return as_strided(band, shape=(a1 - a0, r, w), strides=((r * w + r) * s, w * s, s))


def window_gram(z: np.ndarray, R: np.ndarray, horizon: int) -> np.ndarray:
    """Exact ``sum_k w(k) w(k)^T`` of one record from its lag correlations ``R`` (lags 0 .. 2p-1)."""
    L = 2 * int(horizon)
    return gram_from_lags(R[:L], z[None, :L], z[None, z.shape[0] - L :])


def input_periodogram(u: np.ndarray, n_bins: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """Periodogram of each (mean-removed) input summed into ``n_bins`` equal bins over
    ``[0, 1/2]`` cycles per sample, so records of any length can be added.

    Returns ``(power of shape (n_bins, n_inputs), bin centres in cycles per sample)``.
    """
    n = u.shape[0]
    f = np.fft.rfftfreq(n)
    idx = np.minimum((f * 2 * n_bins).astype(int), n_bins - 1)
    power = np.empty((n_bins, u.shape[1]))
    for j in range(u.shape[1]):  # column by column: no record-sized complex temporaries
        X = np.fft.rfft(u[:, j] - u[:, j].mean())
        power[:, j] = np.bincount(idx, weights=X.real**2 + X.imag**2, minlength=n_bins)
    centres = (np.arange(n_bins) + 0.5) / (2 * n_bins)
    return power, centres
