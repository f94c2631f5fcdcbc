"""Compiled kernel of the local polynomial method (eq. 11, 16, 18 of Pintelon et al. 2010).

:func:`lpm_lines_kernel` solves the local regressions of many DFT lines in one call, per line
in registers-sized work arrays instead of numpy's one LAPACK call per 12x12 matrix.  The Gram
matrix ``K^H K`` of a window is formed from moments: every entry is a sum over the window of
``r^(p+s)`` times a product of two line values (``conj(U_a) U_b``, ``conj(U_a)`` or 1), so
the ``2R + 1`` moments of each product give all of them; ``K^H Y`` likewise from the moments
``sum r^p conj(U_a) Y_c`` and ``sum r^p Y_c``.  The system is solved by a complex Cholesky
factorisation, ``diag((K^H K)^-1)`` from forward solves with unit vectors, and the residuals
(eq. 16) are formed explicitly from the fitted polynomials (no ``Y^H Y - theta^H K^H Y``
cancellation).  Lines the factorisation cannot vouch for (a pivot below ``PIVOT_FLOOR`` of
its diagonal, ``diag(M) diag(M^-1)`` above ``FALLBACK_CONDITION``, anything not finite) are
flagged for the numpy twin :func:`~stageid.frf.lpm.solve_lines_python`, which makes the
final decision on them.
"""

from __future__ import annotations

import numba
import numpy as np

from .lpm_lanes import LANES, lane_work, lanes_block

__all__ = ["lpm_lines_kernel", "sized_entry", "FALLBACK_CONDITION", "PIVOT_FLOOR", "SPECIALISE_LINES"]

#: ``max diag(M) diag(M^-1)`` above which a line is handed to the numpy twin.
FALLBACK_CONDITION = 1e8
#: Cholesky pivot, relative to the diagonal entry it came from, below which the line is handed over.
PIVOT_FLOOR = 1e-12
#: Lines per block of precomputed line products.
CHUNK = 4096
#: Lines from which :func:`lpm_lines_kernel` runs a kernel compiled for the record's sizes: about
#: a fifth faster, at ~13 s of compiling per new (records, inputs, outputs, degree) on first use
#: (then cached on disk), so only where the lines are many.
SPECIALISE_LINES = 100_000

_jit = numba.njit(cache=True, nogil=True, fastmath=True)


@_jit
def _products(Ur, Ui, Y, lo, hi, Z):  # pragma: no cover - compiled
    """The line products of lines ``lo .. hi - 1``, real and imaginary parts side by side in
    ``Z[e, :, line - lo]``: ``conj(U_a) U_b`` (a <= b), ``conj(U_a)``, ``conj(U_a) Y_c``, ``Y_c``, ``|Y_c|^2``."""
    ne, _, m = Ur.shape
    q = Y.shape[2]
    for e in range(ne):
        for i in range(lo, hi):
            z = Z[e, :, i - lo]
            s = 0
            for a in range(m):
                ar = Ur[e, i, a]
                ai = Ui[e, i, a]
                for b in range(a, m):
                    z[s] = ar * Ur[e, i, b] + ai * Ui[e, i, b]
                    z[s + 1] = ar * Ui[e, i, b] - ai * Ur[e, i, b]
                    s += 2
                z[s] = ar
                z[s + 1] = -ai
                s += 2
                for c in range(q):
                    y = Y[e, i, c]
                    z[s] = ar * y.real + ai * y.imag
                    z[s + 1] = ar * y.imag - ai * y.real
                    s += 2
            for c in range(q):
                y = Y[e, i, c]
                z[s] = y.real
                z[s + 1] = y.imag
                z[s + 2] = y.real * y.real + y.imag * y.imag
                s += 3


@_jit
def _moments(Z, j0, pw, S):  # pragma: no cover - compiled
    """``S[e, p, s] = sum_j r_j^p Z[e, s, j0 + j]`` over the window."""
    ne, ns, _ = Z.shape
    rows, P = pw.shape
    S[:] = 0.0
    for e in range(ne):
        for j in range(rows):
            z = Z[e, :, j0 + j]
            for p in range(P):
                w = pw[j, p]
                Sp = S[e, p]
                for s in range(ns):
                    Sp[s] += w * z[s]


@_jit
def _normal_equations(S, Sr, m, q, R1, M, B, ypow):  # pragma: no cover - compiled
    """``M = K^H K``, ``B = K^H Y`` and the window's ``sum |Y_c|^2`` from the moments ``S``
    (parameter order as the numpy twin: ``G`` coefficients ``a (R+1) + p``, then record
    ``e``'s transient ``m (R+1) + e (R+1) + p``)."""
    ne = S.shape[0]
    M[:, :] = 0.0
    B[:, :] = 0.0
    ypow[:] = 0.0
    for e in range(ne):
        t0 = m * R1 + e * R1
        s = 0
        for a in range(m):
            for b in range(a, m):
                for p in range(R1):
                    for t in range(R1):
                        v = complex(S[e, p + t, s], S[e, p + t, s + 1])
                        M[a * R1 + p, b * R1 + t] += v
                        if b != a:
                            M[b * R1 + t, a * R1 + p] += v.conjugate()
                s += 2
            for p in range(R1):
                for t in range(R1):
                    v = complex(S[e, p + t, s], S[e, p + t, s + 1])
                    M[a * R1 + p, t0 + t] = v
                    M[t0 + t, a * R1 + p] = v.conjugate()
            s += 2
            for c in range(q):
                for p in range(R1):
                    B[a * R1 + p, c] += complex(S[e, p, s], S[e, p, s + 1])
                s += 2
        for c in range(q):
            for p in range(R1):
                B[t0 + p, c] = complex(S[e, p, s], S[e, p, s + 1])
            ypow[c] += S[e, 0, s + 2]
            s += 3
        for p in range(R1):
            for t in range(R1):
                M[t0 + p, t0 + t] = Sr[p + t]


@_jit
def _cholesky(M):  # pragma: no cover - compiled
    """Lower Cholesky factor in place; False when a pivot falls below ``PIVOT_FLOOR``."""
    n = M.shape[0]
    for j in range(n):
        d = M[j, j].real
        for k in range(j):
            d -= M[j, k].real * M[j, k].real + M[j, k].imag * M[j, k].imag
        if not d > PIVOT_FLOOR * M[j, j].real:
            return False
        ljj = np.sqrt(d)
        M[j, j] = ljj
        for i in range(j + 1, n):
            s = M[i, j]
            for k in range(j):
                s -= M[i, k] * M[j, k].conjugate()
            M[i, j] = s * (1.0 / ljj)
    return True


@_jit
def _solve(L, B, theta):  # pragma: no cover - compiled
    """``theta = (L L^H)^-1 B`` (all right-hand sides at once, along theta's rows)."""
    n, q = B.shape
    for i in range(n):
        for c in range(q):
            theta[i, c] = B[i, c]
        for k in range(i):
            lik = L[i, k]
            for c in range(q):
                theta[i, c] -= lik * theta[k, c]
        d = 1.0 / L[i, i].real
        for c in range(q):
            theta[i, c] *= d
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            lki = L[k, i].conjugate()
            for c in range(q):
                theta[i, c] -= lki * theta[k, c]
        d = 1.0 / L[i, i].real
        for c in range(q):
            theta[i, c] *= d


@_jit
def _inverse_diagonal(L, g, x):  # pragma: no cover - compiled
    """``[(L L^H)^-1]_gg = |L^-1 e_g|^2``."""
    n = L.shape[0]
    x[g] = 1.0 / L[g, g].real
    acc = x[g].real * x[g].real
    for i in range(g + 1, n):
        s = 0j
        for k in range(g, i):
            s -= L[i, k] * x[k]
        x[i] = s * (1.0 / L[i, i].real)
        acc += x[i].real * x[i].real + x[i].imag * x[i].imag
    return acc


@_jit
def _residual_power(Ur, Ui, Y, e, j0, pw, theta, m, R1, res):  # pragma: no cover - compiled
    """Add ``|Y - K theta|^2`` of record ``e``'s window to ``res`` (per output)."""
    rows = pw.shape[0]
    q = Y.shape[2]
    t0 = m * R1 + e * R1
    for j in range(rows):
        idx = j0 + j
        for c in range(q):
            fit = 0j
            for a in range(m):
                ga = 0j
                for p in range(R1):
                    ga += theta[a * R1 + p, c] * pw[j, p]
                fit += complex(Ur[e, idx, a], Ui[e, idx, a]) * ga
            for p in range(R1):
                fit += theta[t0 + p, c] * pw[j, p]
            d = Y[e, idx, c] - fit
            res[c] += d.real * d.real + d.imag * d.imag


def lpm_lines_kernel(Ur, Ui, Y, ks, n, degree, k_last, excited_power, G, var, coh, status, scale=None):
    """The local regressions of the lines ``ks`` (see :func:`~stageid.frf.lpm.solve_lines_python`).

    ``Ur``, ``Ui`` (ne, lines, m): real and imaginary parts of the unit-RMS input spectra; ``Y``
    (ne, lines, q) complex.  Writes ``G`` (B, q, m), ``var`` (B, q, m), ``coh`` (B, q) and
    ``status`` (B): 0 usable, 1 not excited or not usable, 2 for the numpy twin to decide.
    Runs of ``LANES`` consecutive interior lines go through :func:`~stageid.frf.lpm_lanes.lanes_block`,
    the others one at a time; ``ks`` ascending keeps the product blocks small.  From
    ``SPECIALISE_LINES`` lines on, the kernel runs compiled for the record's sizes.  With
    ``scale`` (m,), ``G`` and ``var`` are written divided by ``scale[a]`` and ``scale[a]^2``.
    """
    ne, _, m = Ur.shape
    scale = np.ones(m) if scale is None else np.ascontiguousarray(scale, dtype=float)
    args = (Ur, Ui, Y, ks, n, degree, k_last, excited_power, scale, G, var, coh, status, ne, m, Y.shape[2], degree + 1)
    if ks.size < SPECIALISE_LINES:
        _lines(*args)
    else:
        sized_entry(args)(*args)


def sized_entry(args: tuple) -> object:
    """The entry point of :func:`_lines` compiled with its last four arguments (the sizes) as
    constants: LLVM then unrolls the lanes' small loops (about a fifth off the time).  Found
    by the exact argument types, so the dispatcher's per-call type resolution is skipped."""
    sig = tuple(numba.typeof(a) for a in args[:-4]) + tuple(numba.types.literal(int(d)) for d in args[-4:])
    cres = _lines.overloads.get(sig)
    if cres is None:
        _lines.compile(sig)  # or load it from the on-disk cache
        cres = _lines.overloads[sig]
    return cres.entry_point


@_jit
def _lines(
    Ur, Ui, Y, ks, n, degree, k_last, excited_power, scale, G, var, coh, status, ne, m, q, R1
):  # pragma: no cover
    """:func:`lpm_lines_kernel`; the sizes ``ne, m, q, R1`` are arguments so that they can be
    compiled in as constants (:func:`sized_entry`)."""
    rows = 2 * n + 1
    ns = m * (m + 1) + 2 * m + 2 * m * q + 3 * q
    pw, Sr, n_pow = _interior_powers(n, degree, m, q)
    work = lane_work(ne, m, q, R1, ns)
    Z = np.empty((ne, ns, CHUNK + rows))  # reused: a fresh block per chunk costs page faults
    for c0 in range(0, ks.size, CHUNK):
        c1 = min(c0 + CHUNK, ks.size)
        lo = k_last + 1
        hi = 0
        for i in range(c0, c1):
            j0 = min(max(ks[i], n), k_last - n) - n
            lo = min(lo, j0)
            hi = max(hi, j0 + rows)
        if hi - lo > Z.shape[2]:
            Z = np.empty((ne, ns, hi - lo))
        _products(Ur, Ui, Y, lo, hi, Z)
        i = c0
        while i < c1:
            e = i + LANES - 1
            if e < c1 and ks[e] == ks[i] + LANES - 1 and ks[i] >= n and ks[e] <= k_last - n:
                lanes_block(Z, ks[i] - n - lo, pw, Sr, n_pow, ne, m, q, R1, PIVOT_FLOOR, excited_power, work, scale,
                            G[i : e + 1], var[i : e + 1], coh[i : e + 1], status[i : e + 1])  # fmt: skip
                for l in range(LANES):
                    if status[i + l] == 0 and work[-1][l] > FALLBACK_CONDITION:
                        status[i + l] = 2
                i += LANES
            else:
                _solve_line(
                    Ur, Ui, Y, Z, lo, ks[i], n, degree, k_last, excited_power, scale, G[i], var[i], coh[i:], status[i:]
                )
                i += 1


@_jit
def _interior_powers(n, degree, m, q):  # pragma: no cover - compiled
    """``r^p`` of an interior window, their sums, and how many powers each product slot needs."""
    rows = 2 * n + 1
    P = 2 * degree + 1
    pw = np.empty((rows, P))
    Sr = np.zeros(P)
    for j in range(rows):
        r = (j - n) / n
        pw[j, 0] = 1.0
        for p in range(1, P):
            pw[j, p] = pw[j, p - 1] * r
        for p in range(P):
            Sr[p] += pw[j, p]
    n_pow = np.empty(m * (m + 1) + 2 * m + 2 * m * q + 3 * q, np.int64)
    s = 0
    for a in range(m):
        n_pow[s : s + 2 * (m - a) + 2] = P
        n_pow[s + 1] = 0  # Im |U_a|^2 = 0: no moments (the lanes' work array holds zeros there)
        s += 2 * (m - a) + 2
        n_pow[s : s + 2 * q] = degree + 1
        s += 2 * q
    for _ in range(q):
        n_pow[s : s + 2] = degree + 1
        n_pow[s + 2] = 1
        s += 3
    return pw, Sr, n_pow


@_jit
def _solve_line(Ur, Ui, Y, Z, lo, k, n, degree, k_last, excited_power, scale, G, var, coh, status):  # pragma: no cover
    """One line ``k`` (any window, edges included); ``coh[0]`` and ``status[0]`` are its entries."""
    ne, _, m = Ur.shape
    q = Y.shape[2]
    R1 = degree + 1
    P = 2 * degree + 1
    rows = 2 * n + 1
    nth = (m + ne) * R1
    dof = ne * rows - nth
    pw = np.empty((rows, P))
    S = np.empty((ne, P, Z.shape[1]))
    Sr = np.zeros(P)
    ypow = np.empty(q)
    res = np.zeros(q)
    diag = np.empty(m)
    gram_diag = np.empty(m)
    M = np.empty((nth, nth), np.complex128)
    B = np.empty((nth, q), np.complex128)
    theta = np.empty((nth, q), np.complex128)
    x = np.empty(nth, np.complex128)
    j0 = min(max(k, n), k_last - n) - n
    for j in range(rows):
        r = (j0 + j - k) / n
        pw[j, 0] = 1.0
        for p in range(1, P):
            pw[j, p] = pw[j, p - 1] * r
        for p in range(P):
            Sr[p] += pw[j, p]
    _moments(Z, j0 - lo, pw, S)
    _normal_equations(S, Sr, m, q, R1, M, B, ypow)
    status[0] = 1
    G[:] = 0.0
    var[:] = 0.0
    coh[0] = 0.0
    excited = True
    for a in range(m):
        gram_diag[a] = M[a * R1, a * R1].real
        excited = excited and gram_diag[a] >= excited_power * ne * rows
    if not excited:
        return
    if not _cholesky(M):
        status[0] = 2
        return
    _solve(M, B, theta)
    worst = 0.0
    for a in range(m):
        diag[a] = _inverse_diagonal(M, a * R1, x)
        worst = max(worst, diag[a] * gram_diag[a])
    for e in range(ne):
        _residual_power(Ur, Ui, Y, e, j0, pw, theta, m, R1, res)
    finite = True
    for c in range(q):
        sigma2 = res[c] / dof
        for a in range(m):
            G[c, a] = theta[a * R1, c] / scale[a]
            var[c, a] = sigma2 * diag[a] / (scale[a] * scale[a])
            finite = finite and np.isfinite(var[c, a]) and np.isfinite(G[c, a].real) and np.isfinite(G[c, a].imag)
        power = ypow[c] / (ne * rows)
        coh[0, c] = min(max(1.0 - sigma2 / power, 0.0), 1.0) if power > 0 else 0.0
    status[0] = 0 if finite and worst <= FALLBACK_CONDITION else 2
