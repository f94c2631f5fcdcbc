"""The LPM regressions of ``LANES`` neighbouring interior lines at once, lines along the last axis.

Every array here ends in a lane axis of ``LANES`` consecutive DFT lines, so each scalar step of
the per-line algorithm (moments, normal equations, complex Cholesky, triangular solves,
``diag((K^H K)^-1)``, residuals) is one loop over the lanes that LLVM vectorises; complex
numbers are kept as real and imaginary arrays.  Interior lines only (their windows are the
line's neighbours ``k - n .. k + n``, the offsets ``r`` are the same for every lane); the
lines near DC and Nyquist go through :func:`~stageid.frf.lpm_kernels.lpm_lines_kernel`.
The product layout ``Z[e, s, line]`` is that of ``stageid.frf.lpm_kernels``.
"""

from __future__ import annotations

import numba
import numpy as np

from ..simd import vbcast, vfma, vfnma, vload, vmul, vstore, vzero

__all__ = ["LANES", "lanes_block", "lane_work"]

#: Lines solved side by side (four four-wide vectors in :func:`_lane_moments`).
LANES = 16

_jit = numba.njit(cache=True, nogil=True, fastmath=True)


@_jit
def _lane_moments(Z, off, pw, n_pow, S):  # pragma: no cover - compiled
    """``S[e, p, s, l] = sum_j r_j^p Z[e, s, off + l + j]`` for ``p < n_pow[s]`` (four
    four-wide accumulators held in registers over the window)."""
    ne, ns, _ = Z.shape
    rows, _ = pw.shape
    for e in range(ne):
        for s in range(ns):
            z = Z[e, s]
            for p in range(n_pow[s]):
                a0 = vzero()
                a1 = vzero()
                a2 = vzero()
                a3 = vzero()
                for j in range(rows):
                    w = vbcast(pw[j, p])
                    o = off + j
                    a0 = vfma(w, vload(z, o), a0)
                    a1 = vfma(w, vload(z, o + 4), a1)
                    a2 = vfma(w, vload(z, o + 8), a2)
                    a3 = vfma(w, vload(z, o + 12), a3)
                out = S[e, p, s]
                vstore(out, 0, a0)
                vstore(out, 4, a1)
                vstore(out, 8, a2)
                vstore(out, 12, a3)


@_jit
def _lane_normal_equations(S, Sr, m, q, R1, Mr, Mi, Br, Bi, ypow):  # pragma: no cover - compiled
    """``M = K^H K``, ``B = K^H Y`` and ``sum |Y_c|^2`` per lane (slot order of the products)."""
    ne = S.shape[0]
    Mr[:] = 0.0
    Mi[:] = 0.0
    Br[:] = 0.0
    Bi[:] = 0.0
    ypow[:] = 0.0
    for e in range(ne):
        t0 = m * R1 + e * R1
        s = 0
        for a in range(m):
            for b in range(a, m):
                for p in range(R1):
                    for t in range(R1):
                        i, j = a * R1 + p, b * R1 + t
                        for l in range(LANES):
                            Mr[i, j, l] += S[e, p + t, s, l]
                            Mi[i, j, l] += S[e, p + t, s + 1, l]
                        if b != a:
                            for l in range(LANES):
                                Mr[j, i, l] += S[e, p + t, s, l]
                                Mi[j, i, l] -= S[e, p + t, s + 1, l]
                s += 2
            for p in range(R1):
                for t in range(R1):
                    i, j = a * R1 + p, t0 + t
                    for l in range(LANES):
                        Mr[i, j, l] = S[e, p + t, s, l]
                        Mi[i, j, l] = S[e, p + t, s + 1, l]
                        Mr[j, i, l] = S[e, p + t, s, l]
                        Mi[j, i, l] = -S[e, p + t, s + 1, l]
            s += 2
            for c in range(q):
                for p in range(R1):
                    for l in range(LANES):
                        Br[a * R1 + p, c, l] += S[e, p, s, l]
                        Bi[a * R1 + p, c, l] += S[e, p, s + 1, l]
                s += 2
        for c in range(q):
            for p in range(R1):
                for l in range(LANES):
                    Br[t0 + p, c, l] = S[e, p, s, l]
                    Bi[t0 + p, c, l] = S[e, p, s + 1, l]
            for l in range(LANES):
                ypow[c, l] += S[e, 0, s + 2, l]
            s += 3
        for p in range(R1):
            for t in range(R1):
                Mr[t0 + p, t0 + t, :] = Sr[p + t]


@_jit
def _lane_cholesky(Mr, Mi, dinv, floor, ok):  # pragma: no cover - compiled
    """Lower Cholesky factor in place, ``dinv = 1 / diag(L)``; ``ok`` False where a pivot falls
    below ``floor`` of its diagonal entry (that lane's factor is then garbage)."""
    n = Mr.shape[0]
    ok[:] = True
    for j in range(n):
        for o in range(0, LANES, 4):
            d = vload(Mr[j, j], o)
            for k in range(j):
                lr = vload(Mr[j, k], o)
                li = vload(Mi[j, k], o)
                d = vfnma(li, li, vfnma(lr, lr, d))
            vstore(dinv[j], o, d)
        dj = dinv[j]
        for l in range(LANES):
            good = dj[l] > floor * Mr[j, j, l]
            ok[l] = ok[l] and good
            dj[l] = dj[l] if good else 1.0
        for l in range(LANES):  # one-array loops: vector sqrt and division
            dj[l] = np.sqrt(dj[l])
        Mr[j, j] = dj
        Mi[j, j] = 0.0
        for l in range(LANES):
            dj[l] = 1.0 / dj[l]
        for i in range(j + 1, n):
            for o in range(0, LANES, 4):
                sr = vload(Mr[i, j], o)
                si = vload(Mi[i, j], o)
                for k in range(j):  # L[i, k] conj(L[j, k])
                    ar = vload(Mr[i, k], o)
                    ai = vload(Mi[i, k], o)
                    br = vload(Mr[j, k], o)
                    bi = vload(Mi[j, k], o)
                    sr = vfnma(ai, bi, vfnma(ar, br, sr))
                    si = vfma(ar, bi, vfnma(ai, br, si))
                d = vload(dinv[j], o)
                vstore(Mr[i, j], o, vmul(sr, d))
                vstore(Mi[i, j], o, vmul(si, d))


@_jit
def _lane_solve(Lr, Li, dinv, Br, Bi, Tr, Ti):  # pragma: no cover - compiled
    """``T = (L L^H)^-1 B`` per lane."""
    n, q, _ = Br.shape
    for i in range(n):
        for c in range(q):
            for o in range(0, LANES, 4):
                ar = vload(Br[i, c], o)
                ai = vload(Bi[i, c], o)
                for k in range(i):
                    lr = vload(Lr[i, k], o)
                    li = vload(Li[i, k], o)
                    tr = vload(Tr[k, c], o)
                    ti = vload(Ti[k, c], o)
                    ar = vfma(li, ti, vfnma(lr, tr, ar))
                    ai = vfnma(li, tr, vfnma(lr, ti, ai))
                d = vload(dinv[i], o)
                vstore(Tr[i, c], o, vmul(ar, d))
                vstore(Ti[i, c], o, vmul(ai, d))
    for i in range(n - 1, -1, -1):
        for c in range(q):
            for o in range(0, LANES, 4):
                ar = vload(Tr[i, c], o)
                ai = vload(Ti[i, c], o)
                for k in range(i + 1, n):  # conj(L[k, i]) T[k]
                    lr = vload(Lr[k, i], o)
                    li = vload(Li[k, i], o)
                    tr = vload(Tr[k, c], o)
                    ti = vload(Ti[k, c], o)
                    ar = vfnma(li, ti, vfnma(lr, tr, ar))
                    ai = vfma(li, tr, vfnma(lr, ti, ai))
                d = vload(dinv[i], o)
                vstore(Tr[i, c], o, vmul(ar, d))
                vstore(Ti[i, c], o, vmul(ai, d))


@_jit
def _lane_inverse_diagonal(Lr, Li, dinv, g, xr, xi, acc):  # pragma: no cover - compiled
    """``acc = [(L L^H)^-1]_gg = |L^-1 e_g|^2`` per lane."""
    n = Lr.shape[0]
    for o in range(0, LANES, 4):
        d = vload(dinv[g], o)
        vstore(xr[g], o, d)
        vstore(xi[g], o, vzero())
        total = vmul(d, d)
        for i in range(g + 1, n):
            sr = vzero()
            si = vzero()
            for k in range(g, i):
                lr = vload(Lr[i, k], o)
                li = vload(Li[i, k], o)
                pr = vload(xr[k], o)
                pi = vload(xi[k], o)
                sr = vfma(li, pi, vfnma(lr, pr, sr))
                si = vfnma(li, pr, vfnma(lr, pi, si))
            d = vload(dinv[i], o)
            sr = vmul(sr, d)
            si = vmul(si, d)
            vstore(xr[i], o, sr)
            vstore(xi[i], o, si)
            total = vfma(si, si, vfma(sr, sr, total))
        vstore(acc, o, total)


@_jit
def _lane_residuals(Z, off, pw, m, q, R1, Tr, Ti, res):  # pragma: no cover - compiled
    """``res[c] = sum |Y_c - K theta_c|^2`` per lane; ``U_a`` and ``Y_c`` are read from the
    product slots ``conj(U_a)`` and ``Y_c``."""
    ne = Z.shape[0]
    rows = pw.shape[0]
    one = vbcast(1.0)
    for c in range(q):
        for o in range(0, LANES, 4):
            total = vzero()
            for e in range(ne):
                t0 = m * R1 + e * R1
                for j in range(rows):
                    fr = vzero()
                    fi = vzero()
                    for p in range(R1):
                        w = vbcast(pw[j, p])
                        fr = vfma(w, vload(Tr[t0 + p, c], o), fr)
                        fi = vfma(w, vload(Ti[t0 + p, c], o), fi)
                    s = 0
                    for a in range(m):
                        s += 2 * (m - a)  # the conj(U_a) slot: (Re U_a, -Im U_a)
                        gr = vzero()
                        gi = vzero()
                        for p in range(R1):
                            w = vbcast(pw[j, p])
                            gr = vfma(w, vload(Tr[a * R1 + p, c], o), gr)
                            gi = vfma(w, vload(Ti[a * R1 + p, c], o), gi)
                        ur = vload(Z[e, s], off + j + o)
                        zi = vload(Z[e, s + 1], off + j + o)
                        fr = vfma(zi, gi, vfma(ur, gr, fr))
                        fi = vfnma(zi, gr, vfma(ur, gi, fi))
                        s += 2 + 2 * q
                    ys = s + 3 * c
                    dr = vfnma(one, fr, vload(Z[e, ys], off + j + o))
                    di = vfnma(one, fi, vload(Z[e, ys + 1], off + j + o))
                    total = vfma(di, di, vfma(dr, dr, total))
            vstore(res[c], o, total)


@_jit
def lanes_block(Z, off, pw, Sr, n_pow, m, q, R1, floor, excited_power, work, G, var, coh, status):  # pragma: no cover
    """Solve ``LANES`` interior lines whose windows start at product column ``off``; write
    ``G``, ``var``, ``coh`` (lines first) and ``status`` as the per-line kernel does, except that
    the fallback test ``diag(M) diag(M^-1) <= FALLBACK_CONDITION`` is left to the caller
    (``work[-1]`` returns that product's maximum per lane)."""
    ne = Z.shape[0]
    rows = pw.shape[0]
    nth = (m + ne) * R1
    S, Mr, Mi, Br, Bi, Tr, Ti, dinv, xr, xi, ypow, res, acc, worst = work
    if Mr.shape[0] != nth:
        raise ValueError("work arrays of the wrong size")
    _lane_moments(Z, off, pw, n_pow, S)
    _lane_normal_equations(S, Sr, m, q, R1, Mr, Mi, Br, Bi, ypow)
    excited = np.ones(LANES, np.bool_)
    gram_diag = np.empty((m, LANES))
    for a in range(m):
        for l in range(LANES):
            gram_diag[a, l] = Mr[a * R1, a * R1, l]
            excited[l] = excited[l] and gram_diag[a, l] >= excited_power * ne * rows
    ok = np.empty(LANES, np.bool_)
    _lane_cholesky(Mr, Mi, dinv, floor, ok)
    _lane_solve(Mr, Mi, dinv, Br, Bi, Tr, Ti)
    worst[:] = 0.0
    for a in range(m):
        _lane_inverse_diagonal(Mr, Mi, dinv, a * R1, xr, xi, acc)
        for l in range(LANES):
            worst[l] = max(worst[l], acc[l] * gram_diag[a, l])
            for c in range(q):
                var[l, c, a] = acc[l]
                G[l, c, a] = complex(Tr[a * R1, c, l], Ti[a * R1, c, l])
    _lane_residuals(Z, off, pw, m, q, R1, Tr, Ti, res)
    dof = ne * rows - nth
    for l in range(LANES):
        finite = True
        for c in range(q):
            sigma2 = res[c, l] / dof
            for a in range(m):
                var[l, c, a] *= sigma2
                finite = finite and np.isfinite(var[l, c, a]) and np.isfinite(G[l, c, a].real)
                finite = finite and np.isfinite(G[l, c, a].imag)
            power = ypow[c, l] / (ne * rows)
            coh[l, c] = min(max(1.0 - sigma2 / power, 0.0), 1.0) if power > 0 else 0.0
        if not excited[l]:
            status[l] = 1
            G[l] = 0.0
            var[l] = 0.0
            coh[l] = 0.0
        else:
            status[l] = 0 if ok[l] and finite else 2


@_jit
def lane_work(ne, m, q, R1, ns):  # pragma: no cover - compiled
    """The work arrays of :func:`lanes_block`."""
    P = 2 * R1 - 1
    nth = (m + ne) * R1
    return (
        np.empty((ne, P, ns, LANES)),
        np.empty((nth, nth, LANES)),
        np.empty((nth, nth, LANES)),
        np.empty((nth, q, LANES)),
        np.empty((nth, q, LANES)),
        np.empty((nth, q, LANES)),
        np.empty((nth, q, LANES)),
        np.empty((nth, LANES)),
        np.empty((nth, LANES)),
        np.empty((nth, LANES)),
        np.empty((q, LANES)),
        np.empty((q, LANES)),
        np.empty(LANES),
        np.empty(LANES),
    )
