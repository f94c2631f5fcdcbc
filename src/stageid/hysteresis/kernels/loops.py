"""Operator banks and weighted sums that update every operator at every sample (eq. 1-4).

The plain-Python twins are :func:`stageid.hysteresis.operators.play_reference` and
:func:`~stageid.hysteresis.operators.coupled_play_reference`.  The loops over operators have
no branches (``min``/``max`` only), so LLVM vectorises them.  Also :func:`gram`, the normal
equations of the weight least squares, :func:`cp_rows`, the operator outputs of the
least-squares rows only with their column statistics, and :func:`cp_gram`, the normal equations
of those rows without the rows.
"""

from __future__ import annotations

import numba
import numpy as np

#: Fast-math flags of the loop kernels: no NaN/inf (inputs are checked finite first), no signed
#: zeros, and reassociation for the weighted sums (~1e-16 relative, far inside the tests' 1e-12).
FASTMATH = {"nnan", "ninf", "nsz", "reassoc", "contract"}
jit = numba.njit(cache=True, nogil=True, fastmath=FASTMATH)
jit_exact = numba.njit(cache=True, nogil=True)


@jit
def play_bank(x, r, z0):  # pragma: no cover - compiled
    """Play outputs, shape (n_samples, n_operators), and the final outputs."""
    n = x.shape[0]
    m = r.shape[0]
    out = np.empty((n, m))
    z = z0.copy()
    for k in range(n):
        xk = x[k]
        for i in range(m):
            lo = xk - r[i]
            hi = xk + r[i]
            v = min(hi, z[i])
            v = max(lo, v)
            z[i] = v
            out[k, i] = v
    return out, z


@jit
def cp_bank(x, r, rc, ra, rb, z0):  # pragma: no cover - compiled
    """Coupled-play outputs, shape (n_samples, n_operators), and the final outputs."""
    n = x.shape[0]
    m = r.shape[0]
    out = np.empty((n, m))
    z = z0.copy()
    for k in range(n):
        xk = x[k]
        for i in range(m):
            up = max(xk - r[i], min(xk - rc[i], 0.0))
            down = min(xk + ra[i], max(xk + rb[i], 0.0))
            v = max(up, min(down, z[i]))
            z[i] = v
            out[k, i] = v
    return out, z


@jit
def play_sum(x, r, w, z0):  # pragma: no cover - compiled
    """Weighted sum of plays ``y(k) = sum_i w_i z_i(k)`` and the final outputs."""
    n = x.shape[0]
    m = r.shape[0]
    y = np.empty(n)
    z = z0.copy()
    for k in range(n):
        xk = x[k]
        acc = 0.0
        for i in range(m):
            v = max(xk - r[i], min(xk + r[i], z[i]))
            z[i] = v
            acc += w[i] * v
        y[k] = acc
    return y, z


@jit
def cp_sum(x, r, rc, ra, rb, w, z0):  # pragma: no cover - compiled
    """Weighted sum of CP operators (eq. 4) and the final outputs; every operator, every sample.

    Needs ``0 <= rc <= r`` and ``0 <= rb <= ra`` (what :func:`operators.check_cp_thresholds`
    guarantees).  Written in the clamp form ``gamma_up(x) = x + clamp(-x, -r, -rc)``,
    ``gamma_down(x) = x + clamp(-x, rb, ra)``: the same floating-point values as
    ``max(x - r, min(x - rc, 0))`` / ``min(x + ra, max(x + rb, 0))`` (each branch is one
    rounded addition of the same two numbers, the flat part is ``x + (-x) = 0``) with 9
    instead of 11 operations per operator; the operators are padded to a multiple of 8 with
    inert ones (zero weight) so the vectorised loop has no scalar remainder.
    """
    n = x.shape[0]
    m = r.shape[0]
    mp = (m + 7) // 8 * 8
    nr = np.zeros(mp)
    nrc = np.zeros(mp)
    RA = np.zeros(mp)
    RB = np.zeros(mp)
    W = np.zeros(mp)
    z = np.zeros(mp)
    for i in range(m):
        nr[i] = -r[i]
        nrc[i] = -rc[i]
        RA[i] = ra[i]
        RB[i] = rb[i]
        W[i] = w[i]
        z[i] = z0[i]
    y = np.empty(n)
    for k in range(n):
        xk = x[k]
        t = -xk
        acc = 0.0
        for i in range(mp):
            up = xk + max(nr[i], min(nrc[i], t))
            down = xk + max(RB[i], min(RA[i], t))
            v = max(up, min(down, z[i]))
            z[i] = v
            acc += W[i] * v
        y[k] = acc
    return y, z[:m].copy()


@jit_exact
def gram(Z, y):  # pragma: no cover - compiled
    """``Z'Z``, ``Z'y`` and the column sums of Z, single-threaded: a BLAS thread pool on a busy
    machine slows the many small weight fits of the identification down instead of up."""
    n, m = Z.shape
    G = np.zeros((m, m))
    g = np.zeros(m)
    s = np.zeros(m)
    for k in range(n):
        yk = y[k]
        for i in range(m):
            zi = Z[k, i]
            s[i] += zi
            g[i] += zi * yk
            for j in range(i + 1):
                G[i, j] += zi * Z[k, j]
    for i in range(m):
        for j in range(i):
            G[j, i] = G[i, j]
    return G, g, s


@jit
def cp_advance(uk, xc, q, R, r, rc, ra, rb, z):  # pragma: no cover - compiled
    """Every coupled-play output ``z`` (updated in place) one sample on, at the input ``uk``
    centred and warped: ``x = uk - xc + q R w(|uk - xc| / R)``, ``w(t) = t^2`` (t <= 1) else
    ``2t - 1``; the step of :func:`cp_rows` and :func:`cp_gram`."""
    xk = uk - xc
    if q != 0.0:
        t = abs(xk) / R
        xk = xk + q * R * (t * t if t <= 1.0 else 2.0 * t - 1.0)
    for i in range(r.shape[0]):
        up = max(xk - r[i], min(xk - rc[i], 0.0))
        down = min(xk + ra[i], max(xk + rb[i], 0.0))
        z[i] = max(up, min(down, z[i]))


@jit
def cp_rows(u, xc, q, R, r, rc, ra, rb, z0, stride):  # pragma: no cover - compiled
    """Coupled-play outputs at the samples ``0, stride, 2 stride, ...`` only, shape
    (n_rows, n_operators), with each column's sum, least and largest value there; the
    operators run over every sample, as in :func:`cp_bank`, on the centred and warped input
    ``x = u - xc + q R w(|u - xc| / R)``, ``w(t) = t^2`` (t <= 1) else ``2t - 1``."""
    n = u.shape[0]
    m = r.shape[0]
    rows = (n + stride - 1) // stride
    out = np.empty((rows, m))
    s = np.zeros(m)
    low = np.full(m, np.inf)
    high = np.full(m, -np.inf)
    z = z0.copy()
    row = 0
    next_kept = 0  # a counter, not k % stride: an integer division per sample costs more
    for k in range(n):
        if k == 0 or u[k] != u[k - 1]:  # a standing input leaves every operator as it is
            cp_advance(u[k], xc, q, R, r, rc, ra, rb, z)
        if k == next_kept:
            next_kept += stride
            for i in range(m):
                zi = z[i]
                out[row, i] = zi
                s[i] += zi
                low[i] = min(low[i], zi)
                high[i] = max(high[i], zi)
            row += 1
    return out, s, low, high


#: Rows of :func:`cp_gram` held per operator before they join the normal equations: ``Z'Z``
#: of a block is one contiguous dot product per pair of operators, which vectorises, where a
#: rank-one update per row does not (benchmarks/RESULTS-recovery.md, Modified PI).
GRAM_BLOCK = 32


@jit
def fold_rows(block, yb, nb, G, g, s):  # pragma: no cover - compiled
    """The first ``nb`` rows of ``block`` (shape (n_operators, GRAM_BLOCK): one operator's
    outputs contiguous) and their outputs ``yb`` into the lower triangle of ``G``, ``g`` and
    the column sums ``s``."""
    for i in range(block.shape[0]):
        bi = block[i]
        acc_s = 0.0
        acc_g = 0.0
        for k in range(nb):
            acc_s += bi[k]
            acc_g += bi[k] * yb[k]
        s[i] += acc_s
        g[i] += acc_g
        for j in range(i + 1):
            bj = block[j]
            acc = 0.0
            for k in range(nb):
                acc += bi[k] * bj[k]
            G[i, j] += acc


@jit
def cp_gram(u, y, xc, q, R, r, rc, ra, rb, z0, stride):  # pragma: no cover - compiled
    """The normal equations of the rows of :func:`cp_rows` against ``y`` (one value per row,
    the samples ``0, stride, ...``), accumulated as the operators run, without the rows:
    ``Z'Z``, ``Z'y``, the column sums, the number of rows, the sum of ``y``, and each column's
    least and largest value.  One pass, rows folded in blocks of ``GRAM_BLOCK`` (:func:`fold_rows`),
    no row matrix: the weight fits of the threshold search are this kernel's calls."""
    n = u.shape[0]
    m = r.shape[0]
    G = np.zeros((m, m))
    g = np.zeros(m)
    s = np.zeros(m)
    low = np.full(m, np.inf)
    high = np.full(m, -np.inf)
    block = np.empty((m, GRAM_BLOCK))
    yb = np.empty(GRAM_BLOCK)
    z = z0.copy()
    rows = 0
    ysum = 0.0
    next_kept = 0
    nb = 0
    for k in range(n):
        if k == 0 or u[k] != u[k - 1]:
            cp_advance(u[k], xc, q, R, r, rc, ra, rb, z)
        if k == next_kept:
            next_kept += stride
            yk = y[rows]
            ysum += yk
            rows += 1
            yb[nb] = yk
            for i in range(m):
                zi = z[i]
                block[i, nb] = zi
                low[i] = min(low[i], zi)
                high[i] = max(high[i], zi)
            nb += 1
            if nb == GRAM_BLOCK:
                fold_rows(block, yb, nb, G, g, s)
                nb = 0
    fold_rows(block, yb, nb, G, g, s)
    for i in range(m):
        for j in range(i):
            G[j, i] = G[i, j]
    return G, g, s, rows, ysum, low, high
