"""The LPM regressions of ``LANES`` neighbouring interior lines at once, lines along the last axis.

Every array here ends in a lane axis of ``LANES`` consecutive DFT lines, so each scalar step of
the per-line algorithm (moments, normal equations, complex Cholesky, triangular solves,
``diag((K^H K)^-1)``, residuals) is one loop over the lanes that LLVM vectorises; complex
numbers are kept as real and imaginary arrays.  Interior lines only (their windows are the
line's neighbours ``k - n .. k + n``, the offsets ``r`` are the same for every lane); the
lines near DC and Nyquist go through :func:`~stageid.frf.lpm_kernels.lpm_lines_kernel`.
The product layout ``Z[e, s, line]`` is that of ``stageid.frf.lpm_kernels``.

The lanes are ``GROUPS`` four-wide vectors (:mod:`stageid.runtime.simd`), one accumulator each:
loops over the groups and register lists, written out by :mod:`stageid.runtime.unroll`.
"""

from __future__ import annotations

import numba
import numpy as np

from ..runtime.simd import LANES as WIDTH
from ..runtime.simd import vbcast, vfma, vfnma, vload, vmul, vstore, vzero
from ..runtime.unroll import written_out

__all__ = ["LANES", "lanes_block", "lane_work"]

#: Lines solved side by side.
LANES = 16
#: Four-wide vectors per lane block: independent accumulators enough to hide the FMA latency.
GROUPS = LANES // WIDTH

_jit = numba.njit(cache=True, nogil=True, fastmath=True)
# small steps inlined in numba IR where called: their vectors stay in the caller's registers
_step = numba.njit(cache=True, nogil=True, fastmath=True, inline="always")


def _written_out(jit):
    """``jit`` of a kernel with its loops over the groups and its register lists written out."""
    return lambda fn: jit(written_out(fn, {"GROUPS": GROUPS}))


@_step
def _minus_product(r, i, ar, ai, br, bi, o):  # pragma: no cover - compiled
    """``(r + i i) - a b`` for the vectors of ``a`` and ``b`` at lane offset ``o``."""
    a_r, a_i, b_r, b_i = vload(ar, o), vload(ai, o), vload(br, o), vload(bi, o)
    return vfma(a_i, b_i, vfnma(a_r, b_r, r)), vfnma(a_i, b_r, vfnma(a_r, b_i, i))


@_step
def _minus_conj_product(r, i, ar, ai, br, bi, o):  # pragma: no cover - compiled
    """``(r + i i) - a conj(b)`` for the vectors of ``a`` and ``b`` at lane offset ``o``."""
    a_r, a_i, b_r, b_i = vload(ar, o), vload(ai, o), vload(br, o), vload(bi, o)
    return vfnma(a_i, b_i, vfnma(a_r, b_r, r)), vfma(a_r, b_i, vfnma(a_i, b_r, i))


@_step
def _minus_conj_times(r, i, ar, ai, br, bi, o):  # pragma: no cover - compiled
    """``(r + i i) - conj(a) b`` for the vectors of ``a`` and ``b`` at lane offset ``o``."""
    a_r, a_i, b_r, b_i = vload(ar, o), vload(ai, o), vload(br, o), vload(bi, o)
    return vfnma(a_i, b_i, vfnma(a_r, b_r, r)), vfma(a_i, b_r, vfnma(a_r, b_i, i))


@_step
def _store_scaled(xr, xi, d, r, i, o):  # pragma: no cover - compiled
    """``x = (r + i i) * d`` at lane offset ``o``."""
    vstore(xr, o, vmul(r, vload(d, o)))
    vstore(xi, o, vmul(i, vload(d, o)))


@_written_out(_jit)
def _lane_moments(Z, off, pw, n_pow, S):  # pragma: no cover - compiled
    """``S[e, p, s, l] = sum_j r_j^p Z[e, s, off + l + j]`` for ``p < n_pow[s]``.

    The window is symmetric (``r_(n+i) = -r_(n-i)``), so the even powers are sums over
    ``Z(+i) + Z(-i)`` and the odd ones over ``Z(+i) - Z(-i)``: half the multiplications.
    Powers go in pairs (one even, one odd) over the lane groups: twice ``GROUPS`` independent
    accumulators."""
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
                    a = [vload(z, c + WIDTH * g) for g in range(GROUPS)]
                else:
                    a = [vzero() for g in range(GROUPS)]
                b = [vzero() for g in range(GROUPS)]
                odd = p + 1 < n_pow[s]
                for i in range(1, n + 1):
                    we = vbcast(pw[n + i, p])
                    zp = [vload(z, c + i + WIDTH * g) for g in range(GROUPS)]
                    zm = [vload(z, c - i + WIDTH * g) for g in range(GROUPS)]
                    for g in range(GROUPS):
                        a[g] = vfma(we, vfma(one, zp[g], zm[g]), a[g])
                    if odd:
                        wo = vbcast(pw[n + i, p + 1])
                        for g in range(GROUPS):
                            b[g] = vfma(wo, vfnma(one, zm[g], zp[g]), b[g])
                for g in range(GROUPS):
                    vstore(S[e, p, s], WIDTH * g, a[g])
                if odd:
                    for g in range(GROUPS):
                        vstore(S[e, p + 1, s], WIDTH * g, b[g])


@_jit
def _input_rows(S, e, a, s, m, q, R1, Mr, Mi, Br, Bi):  # pragma: no cover - compiled
    """Input ``a``'s rows of ``M`` and ``B`` from record ``e``'s moments, from slot ``s`` on
    (the first record assigns, the others add); returns the next slot."""
    first = e == 0
    t0 = m * R1 + e * R1
    for b in range(a, m):
        for p in range(R1):
            for t in range(R1 if b > a else p + 1):
                # lower entry (b, t), (a, p): conj of the moment for b > a; on the diagonal
                # block the moment itself (its imaginary part is rounding)
                i, j = (b * R1 + t, a * R1 + p) if b > a else (a * R1 + p, a * R1 + t)
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
    return s


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
        t0 = nG + e * R1
        s = 0
        for a in range(m):
            s = _input_rows(S, e, a, s, m, q, R1, Mr, Mi, Br, Bi)
        for c in range(q):
            for p in range(R1):
                for l in range(LANES):
                    Br[t0 + p, c, l] = S[e, p, s, l]
                    Bi[t0 + p, c, l] = S[e, p, s + 1, l]
            if e == 0:
                ypow[c] = S[e, 0, s + 2]
            else:
                for l in range(LANES):
                    ypow[c, l] += S[e, 0, s + 2, l]
            s += 3
        for p in range(R1):
            for t in range(p + 1):
                Mr[t0 + p, t0 + t, :] = Sr[p + t]
                Mi[t0 + p, t0 + t, :] = 0.0


@_step
def _pivots(dj, diag, floor, ok):  # pragma: no cover - compiled
    """``dj`` (a column's ``d - sum |L|^2``) to ``1 / L_jj``, and ``diag`` to ``L_jj``; a lane
    whose pivot falls below ``floor`` of its diagonal entry is not ok and gets the pivot 1."""
    for l in range(LANES):
        good = dj[l] > floor * diag[l]
        ok[l] = ok[l] and good
        dj[l] = dj[l] if good else 1.0
    for l in range(LANES):  # one-array loops: vector sqrt and division
        dj[l] = np.sqrt(dj[l])
    diag[:] = dj
    for l in range(LANES):
        dj[l] = 1.0 / dj[l]


@_written_out(_jit)
def _lane_cholesky(n, Mr, Mi, dinv, floor, ok):  # pragma: no cover - compiled
    """Lower Cholesky factor in place, ``dinv = 1 / diag(L)``; ``ok`` False where a pivot falls
    below ``floor`` of its diagonal entry (that lane's factor is then garbage).  The lane
    groups go through each dot product together: independent FMA chains."""
    ok[:] = True
    for j in range(n):
        d = [vload(Mr[j, j], WIDTH * g) for g in range(GROUPS)]
        for k in range(j):
            xr = Mr[j, k]
            xi = Mi[j, k]
            for g in range(GROUPS):
                o = WIDTH * g
                d[g] = vfnma(vload(xi, o), vload(xi, o), vfnma(vload(xr, o), vload(xr, o), d[g]))
        dj = dinv[j]
        for g in range(GROUPS):
            vstore(dj, WIDTH * g, d[g])
        _pivots(dj, Mr[j, j], floor, ok)
        Mi[j, j] = 0.0
        for i in range(j + 1, n):
            r = [vload(Mr[i, j], WIDTH * g) for g in range(GROUPS)]
            im = [vload(Mi[i, j], WIDTH * g) for g in range(GROUPS)]
            for k in range(j):  # L[i, k] conj(L[j, k])
                ar, ai, br, bi = Mr[i, k], Mi[i, k], Mr[j, k], Mi[j, k]
                for g in range(GROUPS):
                    r[g], im[g] = _minus_conj_product(r[g], im[g], ar, ai, br, bi, WIDTH * g)
            xr, xi = Mr[i, j], Mi[i, j]
            for g in range(GROUPS):
                _store_scaled(xr, xi, dj, r[g], im[g], WIDTH * g)


@_written_out(_step)
def _substitution(n, q, Lr, Li, dinv, Xr, Xi, Tr, Ti, backwards):  # pragma: no cover - compiled
    """``T = L^-1 X`` per lane, rows in order (``backwards`` None), or ``T = L^-H X``, rows from
    the last (``backwards`` True); numba compiles each form without the other's branches."""
    for step in range(n):
        i = step if backwards is None else n - 1 - step
        lo, hi = (0, i) if backwards is None else (i + 1, n)
        for c in range(q):
            r = [vload(Xr[i, c], WIDTH * g) for g in range(GROUPS)]
            im = [vload(Xi[i, c], WIDTH * g) for g in range(GROUPS)]
            for k in range(lo, hi):
                tr, ti = Tr[k, c], Ti[k, c]
                if backwards is None:  # L[i, k] T[k]
                    lr, li = Lr[i, k], Li[i, k]
                    for g in range(GROUPS):
                        r[g], im[g] = _minus_product(r[g], im[g], lr, li, tr, ti, WIDTH * g)
                else:  # conj(L[k, i]) T[k]
                    lr, li = Lr[k, i], Li[k, i]
                    for g in range(GROUPS):
                        r[g], im[g] = _minus_conj_times(r[g], im[g], lr, li, tr, ti, WIDTH * g)
            xr, xi, d = Tr[i, c], Ti[i, c], dinv[i]
            for g in range(GROUPS):
                _store_scaled(xr, xi, d, r[g], im[g], WIDTH * g)


@_jit
def _lane_solve(n, q, Lr, Li, dinv, Br, Bi, Tr, Ti):  # pragma: no cover - compiled
    """``T = (L L^H)^-1 B`` per lane: forward, then back substitution in place."""
    _substitution(n, q, Lr, Li, dinv, Br, Bi, Tr, Ti, None)
    _substitution(n, q, Lr, Li, dinv, Tr, Ti, Tr, Ti, True)


@_written_out(_jit)
def _lane_inverse_diagonal(n, Lr, Li, dinv, col, xr, xi, acc):  # pragma: no cover - compiled
    """``acc = [(L L^H)^-1]_cc = |L^-1 e_c|^2`` per lane, ``c = col`` (the lane groups at once)."""
    acc[:] = 0.0
    xr[col] = dinv[col]
    xi[col] = 0.0
    for i in range(col + 1, n):
        r = [vzero() for g in range(GROUPS)]
        im = [vzero() for g in range(GROUPS)]
        for k in range(col, i):
            lr, li, pr, pi = Lr[i, k], Li[i, k], xr[k], xi[k]
            for g in range(GROUPS):
                r[g], im[g] = _minus_product(r[g], im[g], lr, li, pr, pi, WIDTH * g)
        yr, yi, d = xr[i], xi[i], dinv[i]
        for g in range(GROUPS):
            _store_scaled(yr, yi, d, r[g], im[g], WIDTH * g)
    for i in range(col, n):  # the squared norm, in the order of the column
        for o in range(0, LANES, WIDTH):
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
