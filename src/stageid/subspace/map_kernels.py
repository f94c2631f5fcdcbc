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

import numpy as np

from ..simd import vbcast, vfma, vfnma, vload, vmul, vstore, vsum, vzero

__all__ = ["DELAY", "one_window_kernel", "delayed_kernel", "aligned_zeros"]


def _recursive_kernel(z, p, m, q, theta, P, lam):  # pragma: no cover - compiled by numba
    """Fused eq. 17-18: one memory pass over theta and one over P per window, each pass also
    forming ``theta x`` and ``P x`` for the next window (P stays symmetric: g is P x / s)."""
    d = 2 * p * m + p * q
    rows = p * q
    x = np.empty(d)
    xn = np.empty(d)
    yv = np.empty(rows)
    yn = np.empty(rows)
    Px = np.zeros(d)
    Pxn = np.zeros(d)
    tx = np.zeros(rows)
    txn = np.zeros(rows)
    g = np.empty(d)
    n_windows = z.shape[0] - 2 * p + 1
    if n_windows <= 0:
        return theta, P
    for i in range(p):
        for j in range(m):
            x[i * m + j] = z[i, j]
            x[p * m + p * q + i * m + j] = z[p + i, j]
        for j in range(q):
            x[p * m + i * q + j] = z[i, m + j]
            yv[i * q + j] = z[p + i, m + j]
    for a in range(d):
        acc = 0.0
        for b in range(d):
            acc += P[a, b] * x[b]
        Px[a] = acc
    for r in range(rows):
        acc = 0.0
        for b in range(d):
            acc += theta[r, b] * x[b]
        tx[r] = acc
    il = 1.0 / lam
    for k in range(n_windows):
        last = k == n_windows - 1
        if not last:
            for i in range(p):
                for j in range(m):
                    xn[i * m + j] = z[k + 1 + i, j]
                    xn[p * m + p * q + i * m + j] = z[k + 1 + p + i, j]
                for j in range(q):
                    xn[p * m + i * q + j] = z[k + 1 + i, m + j]
                    yn[i * q + j] = z[k + 1 + p + i, m + j]
        else:
            for a in range(d):
                xn[a] = 0.0
        s = lam
        for a in range(d):
            s += x[a] * Px[a]
        inv = 1.0 / s
        for a in range(d):
            g[a] = Px[a] * inv
        # theta += e g^T and theta x_next, one pass
        for r in range(rows):
            e = yv[r] - tx[r]
            acc = 0.0
            for b in range(d):
                v = theta[r, b] + e * g[b]
                theta[r, b] = v
                acc += v * xn[b]
            txn[r] = acc
        # P = (P - g Px^T) / lam and P x_next, one pass over P (rows are contiguous)
        for a in range(d):
            ga = g[a] * il
            acc = 0.0
            for b in range(d):
                v = P[a, b] * il - ga * Px[b]
                P[a, b] = v
                acc += v * xn[b]
            Pxn[a] = acc
        for a in range(d):
            x[a] = xn[a]
            Px[a] = Pxn[a]
        for r in range(rows):
            yv[r] = yn[r]
            tx[r] = txn[r]
    return theta, P


_KERNEL = None


def one_window_kernel():
    """The compiled :func:`_recursive_kernel` (compiled, or loaded from numba's cache, on first use)."""
    global _KERNEL
    if _KERNEL is None:
        import numba

        _KERNEL = numba.njit(cache=True, nogil=True, fastmath=True)(_recursive_kernel)
    return _KERNEL


#: Windows per delayed update of :func:`_delayed_kernel`.
DELAY = 4


def _delayed_kernel(
    uf,
    yf,
    n_samples,
    p,
    m,
    q,
    theta,
    P,
    lam,  # pragma: no cover - numba
    X,
    Y,
    Xn,
    Yn,
    A,
    T,
    An,
    Tn,
    V,
    E,
):
    """Eq. 17-18 window by window with the rank-1 updates of theta and P applied 4 at a time.

    Within a group of four windows ``j = 0..3`` (theta_0, P_0 at the group start, A = P_0 X,
    T = theta_0 X known) the recursion's own quantities follow exactly from

        v_j = P_j x_j = lambda^-j (A_j - sum_{i<j} w_i (v_i . x_j) v_i),   w_i = lambda^i / s_i
        s_j = lambda + x_j . v_j,   g_j = v_j / s_j
        e_j = y_j - theta_j x_j = y_j - T_j - sum_{i<j} (v_i . x_j) / s_i e_i

    (``P_j = lambda^-j (P_0 - sum_{i<j} w_i v_i v_i^T)``,
    ``theta_j = theta_0 + sum_{i<j} e_i g_i^T``); then one pass over theta and one over P
    apply the four updates
    (``theta += sum_j e_j g_j^T``, ``P = lambda^-4 (P - sum_j lambda^j v_j g_j^T)``) and form
    ``theta X'`` and ``P X'`` for the next group.  The arithmetic per window is that of the
    one-window recursion; the matrices are read and written once per four windows instead of
    once per window.  One vector pass per window forms ``v_j`` and its products with all four
    ``x_k``; ``g_j`` is not stored (``1 / s_j`` goes into the rows' weights).  Both matrix
    passes take rows in pairs (each ``v_j`` and ``x'_k`` vector loaded once for two rows) and
    first update a row pair, then form its products while the rows are in L1.  ``P`` is
    symmetric, so its pass updates only the upper triangle (from each row's 4-aligned diagonal
    tile on) and gets ``P X'`` from each stored element twice: in the row's dot product and in
    an axpy into the column's accumulator (a quarter fewer multiply-adds than the full
    matrix); the lower triangle outside the diagonal tiles is mirrored from the upper one at
    the end.  The vector operations are those of :mod:`stageid.simd` (numba's own vectoriser gives
    up on loops touching this many arrays).

    ``theta`` (p q [+ 1], dp) and ``P`` (d [+ 1], dp) have an even number of rows (a zero row
    pads an odd count), rows padded with zeros to ``dp`` (a multiple of 4) and 32-byte
    alignment; the work arrays are (4, dp) and (4, rows of ``theta``), zero beyond ``d`` and
    ``p q``.  Processes ``4 * (n_windows // 4)`` windows of the flattened ``u`` (``uf``,
    n_samples m) and ``y`` (``yf``, n_samples q) and returns that count.  The windows are
    those of :func:`recursive_map_python`, so ``recursive_map`` equals it to rounding.
    """
    d = 2 * p * m + p * q
    rows = p * q
    dp = P.shape[1]
    d2 = P.shape[0]  # d or d + 1: an even number of rows (a zero row pads an odd d)
    rows2 = theta.shape[0]
    pm = p * m
    n_groups = (n_samples - 2 * p + 1) // 4
    if n_groups == 0:
        return 0
    for j in range(4):
        # window j in eq. 9 order: four contiguous copies from the flattened u and y
        for t in range(pm):
            X[j, t] = uf[j * m + t]
            X[j, pm + rows + t] = uf[j * m + pm + t]
        for t in range(rows):
            X[j, pm + t] = yf[j * q + t]
            Y[j, t] = yf[j * q + rows + t]
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
    il4 = 1.0 / (lam * lam * lam * lam)
    il4v = vbcast(il4)
    s = np.empty(4)
    lpow = np.array([1.0, lam, lam * lam, lam * lam * lam])
    lw = il4 * lpow  # weights of the four rank-1 terms of P (ones without forgetting)
    C = np.empty((4, 4))
    si = np.empty(4)
    lws = np.empty(4)
    v0 = V[0]
    v1 = V[1]
    v2 = V[2]
    e0 = E[0]
    e1 = E[1]
    e2 = E[2]
    rows4 = rows - rows % 4
    pm4 = pm - pm % 4
    for grp in range(n_groups):
        # the four windows' gains, residuals and normalisers (eq. 18) from theta_0, P_0: one
        # pass per window forms v_j (the earlier windows' terms with zero weights when i >= j)
        # and its products with all four x_k (C[j, k]; s_j = lambda + C[j, j])
        lj = 1.0
        for j in range(4):
            w0 = 0.0
            w1 = 0.0
            w2 = 0.0
            if j > 0:
                w0 = C[0, j] * lpow[0] / s[0]
            if j > 1:
                w1 = C[1, j] * lpow[1] / s[1]
            if j > 2:
                w2 = C[2, j] * lpow[2] / s[2]
            q0 = vbcast(w0)
            q1 = vbcast(w1)
            q2 = vbcast(w2)
            sc = vbcast(1.0 / lj)
            aj = A[j]
            vj = V[j]
            a0 = vzero()
            a1 = vzero()
            a2 = vzero()
            a3 = vzero()
            for t in range(0, dp, 4):
                v = vfnma(q0, vload(v0, t), vload(aj, t))
                v = vfnma(q1, vload(v1, t), v)
                v = vmul(sc, vfnma(q2, vload(v2, t), v))
                vstore(vj, t, v)
                a0 = vfma(v, vload(X[0], t), a0)
                a1 = vfma(v, vload(X[1], t), a1)
                a2 = vfma(v, vload(X[2], t), a2)
                a3 = vfma(v, vload(X[3], t), a3)
            C[j, 0] = vsum(a0)
            C[j, 1] = vsum(a1)
            C[j, 2] = vsum(a2)
            C[j, 3] = vsum(a3)
            s[j] = lam + C[j, j]
            # e_j = y_j - T_j - sum_{i<j} (C[i, j] / s_i) e_i (zero weights again for i >= j)
            w0 = 0.0
            w1 = 0.0
            w2 = 0.0
            if j > 0:
                w0 = C[0, j] / s[0]
            if j > 1:
                w1 = C[1, j] / s[1]
            if j > 2:
                w2 = C[2, j] / s[2]
            q0 = vbcast(w0)
            q1 = vbcast(w1)
            q2 = vbcast(w2)
            ej = E[j]
            yj = Y[j]
            tj = T[j]
            for r in range(0, rows4, 4):
                e = vfnma(q0, vload(e0, r), vfnma(vbcast(1.0), vload(tj, r), vload(yj, r)))
                vstore(ej, r, vfnma(q2, vload(e2, r), vfnma(q1, vload(e1, r), e)))
            for r in range(rows4, rows):
                ej[r] = yj[r] - tj[r] - w0 * e0[r] - w1 * e1[r] - w2 * e2[r]
            lj *= lam
        for j in range(4):
            si[j] = 1.0 / s[j]
            lws[j] = lw[j] * si[j]
        # the next group's windows (zeros after the last group)
        if grp + 1 < n_groups:
            for j in range(4):
                k = 4 * (grp + 1) + j
                xr = Xn[j]
                yr = Yn[j]
                ku = k * m
                ky = k * q
                for t in range(0, pm4, 4):
                    vstore(xr, t, vload(uf, ku + t))
                    vstore(xr, pm + rows + t, vload(uf, ku + pm + t))
                for t in range(pm4, pm):
                    xr[t] = uf[ku + t]
                    xr[pm + rows + t] = uf[ku + pm + t]
                for t in range(0, rows4, 4):
                    vstore(xr, pm + t, vload(yf, ky + t))
                    vstore(yr, t, vload(yf, ky + rows + t))
                for t in range(rows4, rows):
                    xr[pm + t] = yf[ky + t]
                    yr[t] = yf[ky + rows + t]
        else:
            Xn[:, :] = 0.0
        g0 = V[0]  # g_j = v_j / s_j: the 1 / s_j go into the rows' weights
        g1 = V[1]
        g2 = V[2]
        g3 = V[3]
        x0 = Xn[0]
        x1 = Xn[1]
        x2 = Xn[2]
        x3 = Xn[3]
        # theta += sum_j e_j g_j^T (eq. 17), then theta X', two rows at a time: the update
        # loop loads each gain once for both rows, the product loop (rows now in L1) each x'
        for r in range(0, rows2, 2):
            r0 = theta[r]
            r1 = theta[r + 1]
            f0 = vbcast(E[0, r] * si[0])
            f1 = vbcast(E[1, r] * si[1])
            f2 = vbcast(E[2, r] * si[2])
            f3 = vbcast(E[3, r] * si[3])
            h0 = vbcast(E[0, r + 1] * si[0])
            h1 = vbcast(E[1, r + 1] * si[1])
            h2 = vbcast(E[2, r + 1] * si[2])
            h3 = vbcast(E[3, r + 1] * si[3])
            for t in range(0, dp, 4):
                gv = vload(g0, t)
                v = vfma(f0, gv, vload(r0, t))
                w = vfma(h0, gv, vload(r1, t))
                gv = vload(g1, t)
                v = vfma(f1, gv, v)
                w = vfma(h1, gv, w)
                gv = vload(g2, t)
                v = vfma(f2, gv, v)
                w = vfma(h2, gv, w)
                gv = vload(g3, t)
                vstore(r0, t, vfma(f3, gv, v))
                vstore(r1, t, vfma(h3, gv, w))
            a0 = vzero()
            a1 = vzero()
            a2 = vzero()
            a3 = vzero()
            b0 = vzero()
            b1 = vzero()
            b2 = vzero()
            b3 = vzero()
            for t in range(0, dp, 4):
                v = vload(r0, t)
                w = vload(r1, t)
                xv = vload(x0, t)
                a0 = vfma(v, xv, a0)
                b0 = vfma(w, xv, b0)
                xv = vload(x1, t)
                a1 = vfma(v, xv, a1)
                b1 = vfma(w, xv, b1)
                xv = vload(x2, t)
                a2 = vfma(v, xv, a2)
                b2 = vfma(w, xv, b2)
                xv = vload(x3, t)
                a3 = vfma(v, xv, a3)
                b3 = vfma(w, xv, b3)
            Tn[0, r] = vsum(a0)
            Tn[1, r] = vsum(a1)
            Tn[2, r] = vsum(a2)
            Tn[3, r] = vsum(a3)
            Tn[0, r + 1] = vsum(b0)
            Tn[1, r + 1] = vsum(b1)
            Tn[2, r + 1] = vsum(b2)
            Tn[3, r + 1] = vsum(b3)
        # P = lambda^-4 (P - sum_j lambda^j v_j g_j^T) and P X' on the upper triangle only (P is
        # symmetric), rows a, a + 1 at a time from the 4-aligned column c <= a: update columns
        # c.., then (P X')[a] += P[a, c..] . x' and, right of the diagonal 4x4 tile,
        # (P X')[t] += P[a, t] x'[a] into the L1-resident accumulators An
        n0 = An[0]
        n1 = An[1]
        n2 = An[2]
        n3 = An[3]
        z = vzero()
        for t in range(0, dp, 4):
            vstore(n0, t, z)
            vstore(n1, t, z)
            vstore(n2, t, z)
            vstore(n3, t, z)
        for a in range(0, d2, 2):
            r0 = P[a]
            r1 = P[a + 1]
            c = a - a % 4
            f0 = vbcast(V[0, a] * lws[0])
            f1 = vbcast(V[1, a] * lws[1])
            f2 = vbcast(V[2, a] * lws[2])
            f3 = vbcast(V[3, a] * lws[3])
            h0 = vbcast(V[0, a + 1] * lws[0])
            h1 = vbcast(V[1, a + 1] * lws[1])
            h2 = vbcast(V[2, a + 1] * lws[2])
            h3 = vbcast(V[3, a + 1] * lws[3])
            if lam == 1.0:
                for t in range(c, dp, 4):
                    gv = vload(g0, t)
                    v = vfnma(f0, gv, vload(r0, t))
                    w = vfnma(h0, gv, vload(r1, t))
                    gv = vload(g1, t)
                    v = vfnma(f1, gv, v)
                    w = vfnma(h1, gv, w)
                    gv = vload(g2, t)
                    v = vfnma(f2, gv, v)
                    w = vfnma(h2, gv, w)
                    gv = vload(g3, t)
                    vstore(r0, t, vfnma(f3, gv, v))
                    vstore(r1, t, vfnma(h3, gv, w))
            else:
                for t in range(c, dp, 4):
                    gv = vload(g0, t)
                    v = vfnma(f0, gv, vmul(il4v, vload(r0, t)))
                    w = vfnma(h0, gv, vmul(il4v, vload(r1, t)))
                    gv = vload(g1, t)
                    v = vfnma(f1, gv, v)
                    w = vfnma(h1, gv, w)
                    gv = vload(g2, t)
                    v = vfnma(f2, gv, v)
                    w = vfnma(h2, gv, w)
                    gv = vload(g3, t)
                    vstore(r0, t, vfnma(f3, gv, v))
                    vstore(r1, t, vfnma(h3, gv, w))
            v = vload(r0, c)
            w = vload(r1, c)
            xv = vload(x0, c)
            a0 = vmul(v, xv)
            b0 = vmul(w, xv)
            xv = vload(x1, c)
            a1 = vmul(v, xv)
            b1 = vmul(w, xv)
            xv = vload(x2, c)
            a2 = vmul(v, xv)
            b2 = vmul(w, xv)
            xv = vload(x3, c)
            a3 = vmul(v, xv)
            b3 = vmul(w, xv)
            f0 = vbcast(x0[a])
            f1 = vbcast(x1[a])
            f2 = vbcast(x2[a])
            f3 = vbcast(x3[a])
            h0 = vbcast(x0[a + 1])
            h1 = vbcast(x1[a + 1])
            h2 = vbcast(x2[a + 1])
            h3 = vbcast(x3[a + 1])
            for t in range(c + 4, dp, 4):
                v = vload(r0, t)
                w = vload(r1, t)
                xv = vload(x0, t)
                a0 = vfma(v, xv, a0)
                b0 = vfma(w, xv, b0)
                vstore(n0, t, vfma(f0, v, vfma(h0, w, vload(n0, t))))
                xv = vload(x1, t)
                a1 = vfma(v, xv, a1)
                b1 = vfma(w, xv, b1)
                vstore(n1, t, vfma(f1, v, vfma(h1, w, vload(n1, t))))
                xv = vload(x2, t)
                a2 = vfma(v, xv, a2)
                b2 = vfma(w, xv, b2)
                vstore(n2, t, vfma(f2, v, vfma(h2, w, vload(n2, t))))
                xv = vload(x3, t)
                a3 = vfma(v, xv, a3)
                b3 = vfma(w, xv, b3)
                vstore(n3, t, vfma(f3, v, vfma(h3, w, vload(n3, t))))
            n0[a] += vsum(a0)
            n1[a] += vsum(a1)
            n2[a] += vsum(a2)
            n3[a] += vsum(a3)
            n0[a + 1] += vsum(b0)
            n1[a + 1] += vsum(b1)
            n2[a + 1] += vsum(b2)
            n3[a + 1] += vsum(b3)
        X, Xn = Xn, X
        Y, Yn = Yn, Y
        A, An = An, A
        T, Tn = Tn, T
    # the lower triangle outside the diagonal tiles was not updated: mirror the upper one
    for a in range(d):
        for t in range(a - a % 4):
            P[a, t] = P[t, a]
    return 4 * n_groups


_DELAYED = None


def delayed_kernel():
    """The compiled :func:`_delayed_kernel` (compiled, or loaded from numba's cache, on first use)."""
    global _DELAYED
    if _DELAYED is None:
        import numba

        _DELAYED = numba.njit(cache=True, nogil=True, fastmath=True)(_delayed_kernel)
    return _DELAYED


def aligned_zeros(shape: tuple[int, int]) -> np.ndarray:
    """Zeros of ``shape`` whose first element is 64-byte aligned (rows of a multiple of 4
    doubles then start on 32-byte boundaries: no split vector loads in the kernels)."""
    n = shape[0] * shape[1]
    buf = np.zeros(n + 8)
    off = (-buf.ctypes.data % 64) // 8
    return buf[off : off + n].reshape(shape)
