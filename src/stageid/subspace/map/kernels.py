"""Compiled kernels of the recursion of eq. 17-18 (Cao & Chen 2013, section 2.3).

Two numba kernels run what :func:`~stageid.subspace.recursion.recursive_map` asks for:
:func:`one_window_kernel` (eq. 17-18 one window at a time, one memory pass over ``theta`` and
one over ``P`` per window) and :func:`delayed_kernel` (the same recursion with the rank-1
updates applied ``DELAY`` windows at a time, one pass per ``DELAY`` windows).  The plain-numpy
twin the tests compare them with is :func:`~stageid.subspace.recursion.recursive_map_python`.
The vector operations come from :mod:`stageid.simd`.  numba caches each kernel keyed on this
file: after editing ``stageid.simd``, delete this module's ``__pycache__/*.nbi``/``*.nbc``.
"""

from __future__ import annotations

import numba
import numpy as np

from ...runtime.simd import vbcast, vfma, vfnma, vload, vmul, vstore, vsum, vzero
from ...runtime.unroll import written_out

__all__ = ["DELAY", "one_window_kernel", "delayed_kernel", "aligned_zeros"]

# compiled on first call (or loaded from numba's cache)
_jit = numba.njit(cache=True, nogil=True, fastmath=True)


def _jit_written_out(fn):
    """``_jit`` of ``fn`` with its loops over the ``DELAY`` windows and its register lists
    written out (:func:`~stageid.subspace.unroll.written_out`): the rolled form keeps its
    accumulators in memory and is a quarter slower (``benchmarks/RESULTS-subspace.md``)."""
    return _jit(written_out(fn, {"DELAY": DELAY, "LANES": LANES}))


@_jit
def _load_window(z, k, p, m, q, x, y):  # pragma: no cover - compiled by numba
    """Window ``k`` in eq. 9 order: ``x = [u_p(k); y_p(k); u_p(k+p)]`` and ``y = y_p(k+p)``."""
    for i in range(p):
        for j in range(m):
            x[i * m + j] = z[k + i, j]
            x[p * m + p * q + i * m + j] = z[k + p + i, j]
        for j in range(q):
            x[p * m + i * q + j] = z[k + i, m + j]
            y[i * q + j] = z[k + p + i, m + j]


@_jit
def _mat_vec(M, x, out):  # pragma: no cover - compiled by numba
    """``out = M x`` for the rows of ``out``."""
    for a in range(out.shape[0]):
        acc = 0.0
        for b in range(x.shape[0]):
            acc += M[a, b] * x[b]
        out[a] = acc


@_jit
def _theta_step(theta, y, tx, g, xn, txn):  # pragma: no cover - compiled by numba
    """Eq. 17, ``theta += e g^T`` with ``e = y - theta x`` (eq. 18), and ``theta x_next``: one pass."""
    for r in range(theta.shape[0]):
        e = y[r] - tx[r]
        acc = 0.0
        for b in range(g.shape[0]):
            v = theta[r, b] + e * g[b]
            theta[r, b] = v
            acc += v * xn[b]
        txn[r] = acc


@_jit
def _p_step(P, g, Px, il, xn, Pxn):  # pragma: no cover - compiled by numba
    """``P = (P - g (P x)^T) / lambda`` and ``P x_next``: one pass over P (rows are contiguous)."""
    for a in range(P.shape[0]):
        ga = g[a] * il
        acc = 0.0
        for b in range(P.shape[0]):
            v = P[a, b] * il - ga * Px[b]
            P[a, b] = v
            acc += v * xn[b]
        Pxn[a] = acc


@_jit
def _recursive_kernel(z, p, m, q, theta, P, lam):  # pragma: no cover - compiled by numba
    """Fused eq. 17-18: one memory pass over theta and one over P per window, each pass also
    forming ``theta x`` and ``P x`` for the next window (P stays symmetric: g is P x / s)."""
    d = 2 * p * m + p * q
    rows = p * q
    x, xn, g = np.empty(d), np.empty(d), np.empty(d)
    yv, yn = np.empty(rows), np.empty(rows)
    Px, Pxn = np.zeros(d), np.zeros(d)
    tx, txn = np.zeros(rows), np.zeros(rows)
    n_windows = z.shape[0] - 2 * p + 1
    if n_windows <= 0:
        return theta, P
    _load_window(z, 0, p, m, q, x, yv)
    _mat_vec(P, x, Px)
    _mat_vec(theta, x, tx)
    il = 1.0 / lam
    for k in range(n_windows):
        if k < n_windows - 1:
            _load_window(z, k + 1, p, m, q, xn, yn)
        else:
            xn[:] = 0.0
        s = lam
        for a in range(d):
            s += x[a] * Px[a]
        inv = 1.0 / s
        for a in range(d):
            g[a] = Px[a] * inv
        _theta_step(theta, yv, tx, g, xn, txn)
        _p_step(P, g, Px, il, xn, Pxn)
        x, xn = xn, x
        Px, Pxn = Pxn, Px
        yv, yn = yn, yv
        tx, txn = txn, tx
    return theta, P


def one_window_kernel():
    """The compiled one-window kernel of eq. 17-18 (:func:`_recursive_kernel`)."""
    return _recursive_kernel


#: Windows per delayed update of :func:`_delayed_kernel`.
DELAY = 4
#: Lanes of a :mod:`stageid.simd` vector: matrix rows are padded to a multiple of it.
LANES = 4


@_jit_written_out
def _group_gains(A, T, Y, V, E, X, C, s, lpow, lam, dp, rows):  # pragma: no cover - numba
    """The ``DELAY`` windows' ``v_j = P_j x_j``, normalisers ``s_j`` and residuals ``e_j`` (eq. 18)
    from ``A = P_0 X`` and ``T = theta_0 X``: one pass per window forms ``v_j`` (the earlier
    windows' terms, with zero weights for ``i >= j``) and its products ``C[j, k]`` with every
    ``x_k``."""
    v_ = [V[i] for i in range(DELAY)]
    x_ = [X[k] for k in range(DELAY)]
    e_ = [E[i] for i in range(DELAY)]
    one = vbcast(1.0)
    rows4 = rows - rows % LANES
    lj = 1.0
    for j in range(DELAY):
        wv = [vbcast(C[i, j] * lpow[i] / s[i] if i < j else 0.0) for i in range(DELAY - 1)]
        sc = vbcast(1.0 / lj)
        acc = [vzero() for k in range(DELAY)]
        for t in range(0, dp, LANES):
            v = vload(A[j], t)
            for i in range(DELAY - 1):
                v = vfnma(wv[i], vload(v_[i], t), v)
            v = vmul(sc, v)
            vstore(v_[j], t, v)
            for k in range(DELAY):
                acc[k] = vfma(v, vload(x_[k], t), acc[k])
        for k in range(DELAY):
            C[j, k] = vsum(acc[k])
        s[j] = lam + C[j, j]
        # e_j = y_j - T_j - sum_{i<j} (C[i, j] / s_i) e_i
        w = [C[i, j] / s[i] if i < j else 0.0 for i in range(DELAY - 1)]
        wv = [vbcast(w[i]) for i in range(DELAY - 1)]
        for r in range(0, rows4, LANES):
            e = vfnma(one, vload(T[j], r), vload(Y[j], r))
            for i in range(DELAY - 1):
                e = vfnma(wv[i], vload(e_[i], r), e)
            vstore(e_[j], r, e)
        for r in range(rows4, rows):
            e = Y[j, r] - T[j, r]
            for i in range(DELAY - 1):
                e -= w[i] * E[i, r]
            E[j, r] = e
        lj *= lam


@_jit
def _load_windows(uf, yf, first, m, q, pm, rows, X, Y):  # pragma: no cover - numba
    """Windows ``first .. first + DELAY - 1`` in eq. 9 order: contiguous copies from the flattened u and y."""
    pm4 = pm - pm % LANES
    rows4 = rows - rows % LANES
    for j in range(DELAY):
        xr = X[j]
        yr = Y[j]
        ku = (first + j) * m
        ky = (first + j) * q
        for t in range(0, pm4, LANES):
            vstore(xr, t, vload(uf, ku + t))
            vstore(xr, pm + rows + t, vload(uf, ku + pm + t))
        for t in range(pm4, pm):
            xr[t] = uf[ku + t]
            xr[pm + rows + t] = uf[ku + pm + t]
        for t in range(0, rows4, LANES):
            vstore(xr, pm + t, vload(yf, ky + t))
            vstore(yr, t, vload(yf, ky + rows + t))
        for t in range(rows4, rows):
            xr[pm + t] = yf[ky + t]
            yr[t] = yf[ky + rows + t]


@_jit_written_out
def _theta_pass(theta, V, E, si, Xn, Tn, dp):  # pragma: no cover - numba
    """``theta += sum_j e_j g_j^T`` (eq. 17, ``g_j = v_j / s_j``), then ``theta X'``, two rows at a
    time: the update loads each gain once for both rows, the product (rows now in L1) each x'."""
    g = [V[j] for j in range(DELAY)]
    x = [Xn[j] for j in range(DELAY)]
    for r in range(0, theta.shape[0], 2):
        r0 = theta[r]
        r1 = theta[r + 1]
        f = [vbcast(E[j, r] * si[j]) for j in range(DELAY)]
        h = [vbcast(E[j, r + 1] * si[j]) for j in range(DELAY)]
        for t in range(0, dp, LANES):
            v = vload(r0, t)
            w = vload(r1, t)
            for j in range(DELAY):
                gv = vload(g[j], t)
                v = vfma(f[j], gv, v)
                w = vfma(h[j], gv, w)
            vstore(r0, t, v)
            vstore(r1, t, w)
        a = [vzero() for j in range(DELAY)]
        b = [vzero() for j in range(DELAY)]
        for t in range(0, dp, LANES):
            v = vload(r0, t)
            w = vload(r1, t)
            for j in range(DELAY):
                xv = vload(x[j], t)
                a[j] = vfma(v, xv, a[j])
                b[j] = vfma(w, xv, b[j])
        for j in range(DELAY):
            Tn[j, r] = vsum(a[j])
            Tn[j, r + 1] = vsum(b[j])


@_jit_written_out
def _p_pass(P, V, lws, il4, Xn, An, dp):  # pragma: no cover - numba
    """``P = lambda^-DELAY (P - sum_j lambda^j v_j g_j^T)`` and ``P X'`` on the upper triangle only.

    Rows ``a, a + 1`` at a time from the ``LANES``-aligned column ``c <= a``: update columns
    ``c..``, then ``(P X')[a] += P[a, c..] . x'`` and, right of the diagonal tile,
    ``(P X')[t] += P[a, t] x'[a]`` into the L1-resident accumulators ``An``.
    """
    g = [V[j] for j in range(DELAY)]
    x = [Xn[j] for j in range(DELAY)]
    n = [An[j] for j in range(DELAY)]
    # forgetting shrinks the old P by lambda^-DELAY; without it il4 is None and numba compiles
    # this pass without the scaling (a branch on a None-typed argument is pruned)
    il4v = vbcast(1.0 if il4 is None else il4)
    z = vzero()
    for t in range(0, dp, LANES):
        for j in range(DELAY):
            vstore(n[j], t, z)
    for a in range(0, P.shape[0], 2):
        r0 = P[a]
        r1 = P[a + 1]
        c = a - a % LANES
        f = [vbcast(V[j, a] * lws[j]) for j in range(DELAY)]
        h = [vbcast(V[j, a + 1] * lws[j]) for j in range(DELAY)]
        for t in range(c, dp, LANES):
            v = vload(r0, t)
            w = vload(r1, t)
            if il4 is not None:
                v = vmul(il4v, v)
                w = vmul(il4v, w)
            for j in range(DELAY):
                gv = vload(g[j], t)
                v = vfnma(f[j], gv, v)
                w = vfnma(h[j], gv, w)
            vstore(r0, t, v)
            vstore(r1, t, w)
        v = vload(r0, c)
        w = vload(r1, c)
        pa = [vmul(v, vload(x[j], c)) for j in range(DELAY)]
        pb = [vmul(w, vload(x[j], c)) for j in range(DELAY)]
        f = [vbcast(Xn[j, a]) for j in range(DELAY)]
        h = [vbcast(Xn[j, a + 1]) for j in range(DELAY)]
        for t in range(c + LANES, dp, LANES):
            v = vload(r0, t)
            w = vload(r1, t)
            for j in range(DELAY):
                xv = vload(x[j], t)
                pa[j] = vfma(v, xv, pa[j])
                pb[j] = vfma(w, xv, pb[j])
                vstore(n[j], t, vfma(f[j], v, vfma(h[j], w, vload(n[j], t))))
        for j in range(DELAY):
            n[j][a] += vsum(pa[j])
            n[j][a + 1] += vsum(pb[j])


@_jit
def _delayed_kernel(uf, yf, n_samples, p, m, q, theta, P, lam, X, Y, Xn, Yn, A, T, An, Tn, V, E):  # pragma: no cover
    """Eq. 17-18 window by window with the rank-1 updates of theta and P applied ``DELAY`` at a time.

    Within a group of windows ``j = 0 .. DELAY - 1`` (theta_0, P_0 at the group start,
    ``A = P_0 X``, ``T = theta_0 X`` known) the recursion's own quantities follow exactly from

        v_j = P_j x_j = lambda^-j (A_j - sum_{i<j} w_i (v_i . x_j) v_i),   w_i = lambda^i / s_i
        s_j = lambda + x_j . v_j,   g_j = v_j / s_j
        e_j = y_j - theta_j x_j = y_j - T_j - sum_{i<j} (v_i . x_j) / s_i e_i

    (``P_j = lambda^-j (P_0 - sum_{i<j} w_i v_i v_i^T)``, ``theta_j = theta_0 + sum_{i<j} e_i g_i^T``,
    :func:`_group_gains`); then one pass over theta (:func:`_theta_pass`) and one over P
    (:func:`_p_pass`) apply the updates and form ``theta X'`` and ``P X'`` for the next group.
    The arithmetic per window is that of the one-window recursion; the matrices are read and
    written once per ``DELAY`` windows instead of once per window.  Both passes take rows in
    pairs and keep the per-window factors and accumulators in registers (register lists,
    :mod:`.unroll`).  ``P`` is symmetric: its pass updates only the upper triangle, which is
    mirrored to the lower one at the end.  The vector operations are those of
    :mod:`stageid.simd` (numba's own vectoriser gives up on loops touching this many arrays).

    ``theta`` (p q [+ 1], dp) and ``P`` (d [+ 1], dp) have an even number of rows (a zero row
    pads an odd count), rows padded with zeros to ``dp`` (a multiple of ``LANES``) and 32-byte
    alignment; the work arrays are (DELAY, dp) and (DELAY, rows of ``theta``), zero beyond
    ``d`` and ``p q``.  Processes ``DELAY * (n_windows // DELAY)`` windows of the flattened
    ``u`` (``uf``, n_samples m) and ``y`` (``yf``, n_samples q) and returns that count.  The
    windows are those of :func:`~stageid.subspace.recursion.recursive_map_python`, so
    ``recursive_map`` equals it to rounding.
    """
    d = 2 * p * m + p * q
    rows = p * q
    dp = P.shape[1]
    n_groups = (n_samples - 2 * p + 1) // DELAY
    if n_groups == 0:
        return 0
    _load_windows(uf, yf, 0, m, q, p * m, rows, X, Y)
    for j in range(DELAY):
        for a in range(d):
            acc = 0.0
            for t in range(dp):
                acc += P[a, t] * X[j, t]
            A[j, a] = acc
        for r in range(rows):
            acc = 0.0
            for t in range(dp):
                acc += theta[r, t] * X[j, t]
            T[j, r] = acc
    lpow = np.empty(DELAY)  # lambda^j
    lpow[0] = 1.0
    for j in range(1, DELAY):
        lpow[j] = lpow[j - 1] * lam
    il4 = 1.0 / (lpow[DELAY - 1] * lam)
    C = np.empty((DELAY, DELAY))
    s = np.empty(DELAY)
    si = np.empty(DELAY)
    lws = np.empty(DELAY)  # weights of the rank-1 terms of P (ones without forgetting)
    for grp in range(n_groups):
        _group_gains(A, T, Y, V, E, X, C, s, lpow, lam, dp, rows)
        for j in range(DELAY):
            si[j] = 1.0 / s[j]
            lws[j] = il4 * lpow[j] * si[j]
        if grp + 1 < n_groups:  # the next group's windows (zeros after the last group)
            _load_windows(uf, yf, DELAY * (grp + 1), m, q, p * m, rows, Xn, Yn)
        else:
            Xn[:, :] = 0.0
        _theta_pass(theta, V, E, si, Xn, Tn, dp)
        if lam == 1.0:
            _p_pass(P, V, lws, None, Xn, An, dp)
        else:
            _p_pass(P, V, lws, il4, Xn, An, dp)
        X, Xn = Xn, X
        Y, Yn = Yn, Y
        A, An = An, A
        T, Tn = Tn, T
    # the lower triangle outside the diagonal tiles was not updated: mirror the upper one
    for a in range(d):
        for t in range(a - a % LANES):
            P[a, t] = P[t, a]
    return DELAY * n_groups


def delayed_kernel():
    """The compiled delayed-update kernel of eq. 17-18 (:func:`_delayed_kernel`)."""
    return _delayed_kernel


def aligned_zeros(shape: tuple[int, int]) -> np.ndarray:
    """Zeros of ``shape`` whose first element is 64-byte aligned (rows of a multiple of 4
    doubles then start on 32-byte boundaries: no split vector loads in the kernels)."""
    n = shape[0] * shape[1]
    buf = np.zeros(n + 8)
    off = (-buf.ctypes.data % 64) // 8
    return buf[off : off + n].reshape(shape)
