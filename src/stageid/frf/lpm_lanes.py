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

from ..runtime.simd import vbcast, vfma, vfnma, vload, vmul, vstore, vzero

__all__ = ["LANES", "lanes_block", "lane_work"]

#: Lines solved side by side (four four-wide vectors in :func:`_lane_moments`).
LANES = 16

_jit = numba.njit(cache=True, nogil=True, fastmath=True)


@_jit
def _lane_moments(Z, off, pw, n_pow, S):  # pragma: no cover - compiled
    """``S[e, p, s, l] = sum_j r_j^p Z[e, s, off + l + j]`` for ``p < n_pow[s]``.

    The window is symmetric (``r_(n+i) = -r_(n-i)``), so the even powers are sums over
    ``Z(+i) + Z(-i)`` and the odd ones over ``Z(+i) - Z(-i)``: half the multiplications.
    Powers go in pairs (one even, one odd) over four four-wide lane groups: eight
    independent accumulators, enough to hide the FMA latency."""
    ne, ns, _ = Z.shape
    rows, _ = pw.shape
    n = rows // 2
    one = vbcast(1.0)
    c = off + n  # the window's centre column of lane 0
    for e in range(ne):
        for s in range(ns):
            z = Z[e, s]
            for p in range(0, n_pow[s], 2):
                if p == 0:  # r^0 = 1 at the centre; r^p = 0 there for p > 0
                    a0 = vload(z, c)
                    a1 = vload(z, c + 4)
                    a2 = vload(z, c + 8)
                    a3 = vload(z, c + 12)
                else:
                    a0 = vzero()
                    a1 = vzero()
                    a2 = vzero()
                    a3 = vzero()
                b0 = vzero()
                b1 = vzero()
                b2 = vzero()
                b3 = vzero()
                odd = p + 1 < n_pow[s]
                for i in range(1, n + 1):
                    we = vbcast(pw[n + i, p])
                    zp0 = vload(z, c + i)
                    zm0 = vload(z, c - i)
                    zp1 = vload(z, c + i + 4)
                    zm1 = vload(z, c - i + 4)
                    zp2 = vload(z, c + i + 8)
                    zm2 = vload(z, c - i + 8)
                    zp3 = vload(z, c + i + 12)
                    zm3 = vload(z, c - i + 12)
                    a0 = vfma(we, vfma(one, zp0, zm0), a0)
                    a1 = vfma(we, vfma(one, zp1, zm1), a1)
                    a2 = vfma(we, vfma(one, zp2, zm2), a2)
                    a3 = vfma(we, vfma(one, zp3, zm3), a3)
                    if odd:
                        wo = vbcast(pw[n + i, p + 1])
                        b0 = vfma(wo, vfnma(one, zm0, zp0), b0)
                        b1 = vfma(wo, vfnma(one, zm1, zp1), b1)
                        b2 = vfma(wo, vfnma(one, zm2, zp2), b2)
                        b3 = vfma(wo, vfnma(one, zm3, zp3), b3)
                out = S[e, p, s]
                vstore(out, 0, a0)
                vstore(out, 4, a1)
                vstore(out, 8, a2)
                vstore(out, 12, a3)
                if odd:
                    out = S[e, p + 1, s]
                    vstore(out, 0, b0)
                    vstore(out, 4, b1)
                    vstore(out, 8, b2)
                    vstore(out, 12, b3)


@_jit
def _lane_normal_equations(S, Sr, ne, m, q, R1, Mr, Mi, Br, Bi, ypow):  # pragma: no cover - compiled
    """``M = K^H K`` (lower triangle: all the factorisation reads), ``B = K^H Y`` and
    ``sum |Y_c|^2`` per lane (slot order of the products); the first record assigns, the
    others add, so nothing is zeroed for one record."""
    nG = m * R1
    if ne > 1:  # blocks between two records' transients stay zero
        for i in range(nG, Mr.shape[0]):
            for j in range(nG, i + 1):
                Mr[i, j] = 0.0
                Mi[i, j] = 0.0
    for e in range(ne):
        first = e == 0
        t0 = nG + e * R1
        s = 0
        for a in range(m):
            for b in range(a, m):
                for p in range(R1):
                    for t in range(R1 if b > a else p + 1):
                        # lower entry (b, t), (a, p): conj of the moment for b > a; on the
                        # diagonal block the moment itself (its imaginary part is rounding)
                        i, j = b * R1 + t, a * R1 + p
                        if b == a:
                            i, j = a * R1 + p, a * R1 + t
                        sgn = -1.0 if b > a else 1.0
                        if first:
                            for l in range(LANES):
                                Mr[i, j, l] = S[e, p + t, s, l]
                                Mi[i, j, l] = sgn * S[e, p + t, s + 1, l]
                        else:
                            for l in range(LANES):
                                Mr[i, j, l] += S[e, p + t, s, l]
                                Mi[i, j, l] += sgn * S[e, p + t, s + 1, l]
                s += 2
            for p in range(R1):
                for t in range(R1):
                    i, j = a * R1 + p, t0 + t
                    for l in range(LANES):
                        Mr[j, i, l] = S[e, p + t, s, l]
                        Mi[j, i, l] = -S[e, p + t, s + 1, l]
            s += 2
            for c in range(q):
                for p in range(R1):
                    if first:
                        for l in range(LANES):
                            Br[a * R1 + p, c, l] = S[e, p, s, l]
                            Bi[a * R1 + p, c, l] = S[e, p, s + 1, l]
                    else:
                        for l in range(LANES):
                            Br[a * R1 + p, c, l] += S[e, p, s, l]
                            Bi[a * R1 + p, c, l] += S[e, p, s + 1, l]
                s += 2
        for c in range(q):
            for p in range(R1):
                for l in range(LANES):
                    Br[t0 + p, c, l] = S[e, p, s, l]
                    Bi[t0 + p, c, l] = S[e, p, s + 1, l]
            if first:
                ypow[c] = S[e, 0, s + 2]
            else:
                for l in range(LANES):
                    ypow[c, l] += S[e, 0, s + 2, l]
            s += 3
        for p in range(R1):
            for t in range(p + 1):
                Mr[t0 + p, t0 + t, :] = Sr[p + t]
                Mi[t0 + p, t0 + t, :] = 0.0


@_jit
def _lane_cholesky(n, Mr, Mi, dinv, floor, ok):  # pragma: no cover - compiled
    """Lower Cholesky factor in place, ``dinv = 1 / diag(L)``; ``ok`` False where a pivot falls
    below ``floor`` of its diagonal entry (that lane's factor is then garbage).  The four lane
    groups go through each dot product together: eight independent FMA chains."""
    ok[:] = True
    for j in range(n):
        d0 = vload(Mr[j, j], 0)
        d1 = vload(Mr[j, j], 4)
        d2 = vload(Mr[j, j], 8)
        d3 = vload(Mr[j, j], 12)
        for k in range(j):
            xr = Mr[j, k]
            xi = Mi[j, k]
            d0 = vfnma(vload(xi, 0), vload(xi, 0), vfnma(vload(xr, 0), vload(xr, 0), d0))
            d1 = vfnma(vload(xi, 4), vload(xi, 4), vfnma(vload(xr, 4), vload(xr, 4), d1))
            d2 = vfnma(vload(xi, 8), vload(xi, 8), vfnma(vload(xr, 8), vload(xr, 8), d2))
            d3 = vfnma(vload(xi, 12), vload(xi, 12), vfnma(vload(xr, 12), vload(xr, 12), d3))
        dj = dinv[j]
        vstore(dj, 0, d0)
        vstore(dj, 4, d1)
        vstore(dj, 8, d2)
        vstore(dj, 12, d3)
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
            r0 = vload(Mr[i, j], 0)
            r1 = vload(Mr[i, j], 4)
            r2 = vload(Mr[i, j], 8)
            r3 = vload(Mr[i, j], 12)
            i0 = vload(Mi[i, j], 0)
            i1 = vload(Mi[i, j], 4)
            i2 = vload(Mi[i, j], 8)
            i3 = vload(Mi[i, j], 12)
            for k in range(j):  # L[i, k] conj(L[j, k])
                ar = Mr[i, k]
                ai = Mi[i, k]
                br = Mr[j, k]
                bi = Mi[j, k]
                a_r, a_i, b_r, b_i = vload(ar, 0), vload(ai, 0), vload(br, 0), vload(bi, 0)
                r0 = vfnma(a_i, b_i, vfnma(a_r, b_r, r0))
                i0 = vfma(a_r, b_i, vfnma(a_i, b_r, i0))
                a_r, a_i, b_r, b_i = vload(ar, 4), vload(ai, 4), vload(br, 4), vload(bi, 4)
                r1 = vfnma(a_i, b_i, vfnma(a_r, b_r, r1))
                i1 = vfma(a_r, b_i, vfnma(a_i, b_r, i1))
                a_r, a_i, b_r, b_i = vload(ar, 8), vload(ai, 8), vload(br, 8), vload(bi, 8)
                r2 = vfnma(a_i, b_i, vfnma(a_r, b_r, r2))
                i2 = vfma(a_r, b_i, vfnma(a_i, b_r, i2))
                a_r, a_i, b_r, b_i = vload(ar, 12), vload(ai, 12), vload(br, 12), vload(bi, 12)
                r3 = vfnma(a_i, b_i, vfnma(a_r, b_r, r3))
                i3 = vfma(a_r, b_i, vfnma(a_i, b_r, i3))
            xr = Mr[i, j]
            xi = Mi[i, j]
            vstore(xr, 0, vmul(r0, vload(dj, 0)))
            vstore(xr, 4, vmul(r1, vload(dj, 4)))
            vstore(xr, 8, vmul(r2, vload(dj, 8)))
            vstore(xr, 12, vmul(r3, vload(dj, 12)))
            vstore(xi, 0, vmul(i0, vload(dj, 0)))
            vstore(xi, 4, vmul(i1, vload(dj, 4)))
            vstore(xi, 8, vmul(i2, vload(dj, 8)))
            vstore(xi, 12, vmul(i3, vload(dj, 12)))


@_jit
def _lane_solve(n, q, Lr, Li, dinv, Br, Bi, Tr, Ti):  # pragma: no cover - compiled
    """``T = (L L^H)^-1 B`` per lane (forward then back substitution, four lane groups at once)."""
    for i in range(n):
        for c in range(q):
            r0, r1, r2, r3 = vload(Br[i, c], 0), vload(Br[i, c], 4), vload(Br[i, c], 8), vload(Br[i, c], 12)
            i0, i1, i2, i3 = vload(Bi[i, c], 0), vload(Bi[i, c], 4), vload(Bi[i, c], 8), vload(Bi[i, c], 12)
            for k in range(i):  # L[i, k] T[k]
                lr, li, tr, ti = Lr[i, k], Li[i, k], Tr[k, c], Ti[k, c]
                a_r, a_i, t_r, t_i = vload(lr, 0), vload(li, 0), vload(tr, 0), vload(ti, 0)
                r0 = vfma(a_i, t_i, vfnma(a_r, t_r, r0))
                i0 = vfnma(a_i, t_r, vfnma(a_r, t_i, i0))
                a_r, a_i, t_r, t_i = vload(lr, 4), vload(li, 4), vload(tr, 4), vload(ti, 4)
                r1 = vfma(a_i, t_i, vfnma(a_r, t_r, r1))
                i1 = vfnma(a_i, t_r, vfnma(a_r, t_i, i1))
                a_r, a_i, t_r, t_i = vload(lr, 8), vload(li, 8), vload(tr, 8), vload(ti, 8)
                r2 = vfma(a_i, t_i, vfnma(a_r, t_r, r2))
                i2 = vfnma(a_i, t_r, vfnma(a_r, t_i, i2))
                a_r, a_i, t_r, t_i = vload(lr, 12), vload(li, 12), vload(tr, 12), vload(ti, 12)
                r3 = vfma(a_i, t_i, vfnma(a_r, t_r, r3))
                i3 = vfnma(a_i, t_r, vfnma(a_r, t_i, i3))
            _store_scaled(Tr[i, c], Ti[i, c], dinv[i], r0, r1, r2, r3, i0, i1, i2, i3)
    for i in range(n - 1, -1, -1):
        for c in range(q):
            r0, r1, r2, r3 = vload(Tr[i, c], 0), vload(Tr[i, c], 4), vload(Tr[i, c], 8), vload(Tr[i, c], 12)
            i0, i1, i2, i3 = vload(Ti[i, c], 0), vload(Ti[i, c], 4), vload(Ti[i, c], 8), vload(Ti[i, c], 12)
            for k in range(i + 1, n):  # conj(L[k, i]) T[k]
                lr, li, tr, ti = Lr[k, i], Li[k, i], Tr[k, c], Ti[k, c]
                a_r, a_i, t_r, t_i = vload(lr, 0), vload(li, 0), vload(tr, 0), vload(ti, 0)
                r0 = vfnma(a_i, t_i, vfnma(a_r, t_r, r0))
                i0 = vfma(a_i, t_r, vfnma(a_r, t_i, i0))
                a_r, a_i, t_r, t_i = vload(lr, 4), vload(li, 4), vload(tr, 4), vload(ti, 4)
                r1 = vfnma(a_i, t_i, vfnma(a_r, t_r, r1))
                i1 = vfma(a_i, t_r, vfnma(a_r, t_i, i1))
                a_r, a_i, t_r, t_i = vload(lr, 8), vload(li, 8), vload(tr, 8), vload(ti, 8)
                r2 = vfnma(a_i, t_i, vfnma(a_r, t_r, r2))
                i2 = vfma(a_i, t_r, vfnma(a_r, t_i, i2))
                a_r, a_i, t_r, t_i = vload(lr, 12), vload(li, 12), vload(tr, 12), vload(ti, 12)
                r3 = vfnma(a_i, t_i, vfnma(a_r, t_r, r3))
                i3 = vfma(a_i, t_r, vfnma(a_r, t_i, i3))
            _store_scaled(Tr[i, c], Ti[i, c], dinv[i], r0, r1, r2, r3, i0, i1, i2, i3)


@_jit
def _store_scaled(xr, xi, d, r0, r1, r2, r3, i0, i1, i2, i3):  # pragma: no cover - compiled
    """``x = (r + i i) * d`` for the four lane groups."""
    vstore(xr, 0, vmul(r0, vload(d, 0)))
    vstore(xr, 4, vmul(r1, vload(d, 4)))
    vstore(xr, 8, vmul(r2, vload(d, 8)))
    vstore(xr, 12, vmul(r3, vload(d, 12)))
    vstore(xi, 0, vmul(i0, vload(d, 0)))
    vstore(xi, 4, vmul(i1, vload(d, 4)))
    vstore(xi, 8, vmul(i2, vload(d, 8)))
    vstore(xi, 12, vmul(i3, vload(d, 12)))


@_jit
def _lane_inverse_diagonal(n, Lr, Li, dinv, g, xr, xi, acc):  # pragma: no cover - compiled
    """``acc = [(L L^H)^-1]_gg = |L^-1 e_g|^2`` per lane (four lane groups at once)."""
    vstore(acc, 0, vzero())
    vstore(acc, 4, vzero())
    vstore(acc, 8, vzero())
    vstore(acc, 12, vzero())
    xr[g] = dinv[g]
    xi[g] = 0.0
    for i in range(g + 1, n):
        r0 = r1 = r2 = r3 = i0 = i1 = i2 = i3 = vzero()
        for k in range(g, i):
            lr, li, pr, pi = Lr[i, k], Li[i, k], xr[k], xi[k]
            a_r, a_i, p_r, p_i = vload(lr, 0), vload(li, 0), vload(pr, 0), vload(pi, 0)
            r0 = vfma(a_i, p_i, vfnma(a_r, p_r, r0))
            i0 = vfnma(a_i, p_r, vfnma(a_r, p_i, i0))
            a_r, a_i, p_r, p_i = vload(lr, 4), vload(li, 4), vload(pr, 4), vload(pi, 4)
            r1 = vfma(a_i, p_i, vfnma(a_r, p_r, r1))
            i1 = vfnma(a_i, p_r, vfnma(a_r, p_i, i1))
            a_r, a_i, p_r, p_i = vload(lr, 8), vload(li, 8), vload(pr, 8), vload(pi, 8)
            r2 = vfma(a_i, p_i, vfnma(a_r, p_r, r2))
            i2 = vfnma(a_i, p_r, vfnma(a_r, p_i, i2))
            a_r, a_i, p_r, p_i = vload(lr, 12), vload(li, 12), vload(pr, 12), vload(pi, 12)
            r3 = vfma(a_i, p_i, vfnma(a_r, p_r, r3))
            i3 = vfnma(a_i, p_r, vfnma(a_r, p_i, i3))
        _store_scaled(xr[i], xi[i], dinv[i], r0, r1, r2, r3, i0, i1, i2, i3)
    for i in range(g, n):  # the squared norm, in the order of the column
        for o in range(0, LANES, 4):
            sr = vload(xr[i], o)
            si = vload(xi[i], o)
            vstore(acc, o, vfma(si, si, vfma(sr, sr, vload(acc, o))))


@_jit
def _lane_residuals(Z, off, pw, ne, m, q, R1, Tr, Ti, res):  # pragma: no cover - compiled
    """``res[c] = sum |Y_c - K theta_c|^2`` per lane; ``U_a`` and ``Y_c`` are read from the
    product slots ``conj(U_a)`` and ``Y_c``."""
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
def lanes_block(
    Z, off, pw, Sr, n_pow, ne, m, q, R1, floor, excited_power, work, scale, G, var, coh, status
):  # pragma: no cover
    """Solve ``LANES`` interior lines whose windows start at product column ``off``; write
    ``G``, ``var``, ``coh`` (lines first) and ``status`` as the per-line kernel does, except that
    the fallback test ``diag(M) diag(M^-1) <= FALLBACK_CONDITION`` is left to the caller
    (``work[-1]`` returns that product's maximum per lane).  ``G`` and ``var`` are written
    divided by ``scale[a]`` and ``scale[a]^2`` (input ``a``'s units back, no later pass)."""
    rows = pw.shape[0]
    nth = (m + ne) * R1
    S, Mr, Mi, Br, Bi, Tr, Ti, dinv, xr, xi, ypow, res, acc, gram_diag, excited, ok, worst = work
    if Mr.shape[0] != nth:
        raise ValueError("work arrays of the wrong size")
    _lane_moments(Z, off, pw, n_pow, S)
    _lane_normal_equations(S, Sr, ne, m, q, R1, Mr, Mi, Br, Bi, ypow)
    excited[:] = True
    for a in range(m):
        for l in range(LANES):
            gram_diag[a, l] = Mr[a * R1, a * R1, l]
            excited[l] = excited[l] and gram_diag[a, l] >= excited_power * ne * rows
    _lane_cholesky(nth, Mr, Mi, dinv, floor, ok)
    _lane_solve(nth, q, Mr, Mi, dinv, Br, Bi, Tr, Ti)
    worst[:] = 0.0
    for a in range(m):
        _lane_inverse_diagonal(nth, Mr, Mi, dinv, a * R1, xr, xi, acc)
        for l in range(LANES):
            worst[l] = max(worst[l], acc[l] * gram_diag[a, l])
            for c in range(q):
                var[l, c, a] = acc[l] / (scale[a] * scale[a])
                G[l, c, a] = complex(Tr[a * R1, c, l], Ti[a * R1, c, l]) / scale[a]
    _lane_residuals(Z, off, pw, ne, m, q, R1, Tr, Ti, res)
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
        np.zeros((ne, P, ns, LANES)),  # zeros: slots without moments (n_pow 0) read as 0
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
        np.empty((m, LANES)),
        np.empty(LANES, np.bool_),
        np.empty(LANES, np.bool_),
        np.empty(LANES),
    )
