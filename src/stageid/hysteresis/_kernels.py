"""Compiled inner loops of the hysteresis operators (numba, ``cache=True``, ``nogil=True``).

Every kernel has a plain-Python twin in :mod:`stageid.hysteresis.operators`
(``play_reference``, ``coupled_play_reference``) or below (``cp_invert_reference``) that the
tests compare it with.  The loops over operators are written so LLVM vectorises them (no
branches, ``min``/``max`` only); the only fast-math flags used are ``nnan``/``ninf``/``nsz``
(the inputs are checked finite before they get here) and ``reassoc`` for the weighted sum,
which changes its rounding by ~1e-16 relative, far inside the 1e-12 the tests ask for.

This module imports numba; it is imported lazily by the operators and models.
"""

from __future__ import annotations

import numba
import numpy as np

_FM = {"nnan", "ninf", "nsz", "reassoc", "contract"}
_jit = numba.njit(cache=True, nogil=True, fastmath=_FM)
_jit_exact = numba.njit(cache=True, nogil=True)


@_jit
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


@_jit
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


@_jit
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


@_jit
def cp_sum(x, r, rc, ra, rb, w, z0):  # pragma: no cover - compiled
    """Weighted sum of CP operators (eq. 4) and the final outputs."""
    n = x.shape[0]
    m = r.shape[0]
    y = np.empty(n)
    z = z0.copy()
    for k in range(n):
        xk = x[k]
        acc = 0.0
        for i in range(m):
            up = max(xk - r[i], min(xk - rc[i], 0.0))
            down = min(xk + ra[i], max(xk + rb[i], 0.0))
            v = max(up, min(down, z[i]))
            z[i] = v
            acc += w[i] * v
        y[k] = acc
    return y, z


# ------------------------------------------------------------------ monotone inversion
@_jit_exact
def _eval(x, P, z):  # pragma: no cover - compiled
    """F(x) = sum w_i CP_i(x; z_i) and its slope on the piece to the right (+) and left (-)."""
    m = P.shape[1]
    f = 0.0
    sp = 0.0
    sm = 0.0
    for i in range(m):
        r, rc, ra, rb, w = P[0, i], P[1, i], P[2, i], P[3, i], P[4, i]
        a = x - r
        b = x - rc
        up = a if a > min(b, 0.0) else min(b, 0.0)
        # right/left slopes of gamma_up: 1 where x-r dominates or x-rc < 0 dominates
        up_sp = 1.0 if (a >= 0.0 or b < 0.0) else 0.0
        up_sm = 1.0 if (a > 0.0 or b <= 0.0) else 0.0
        c = x + ra
        d = x + rb
        down = c if c < max(d, 0.0) else max(d, 0.0)
        dn_sp = 1.0 if (c < 0.0 or d >= 0.0) else 0.0
        dn_sm = 1.0 if (c <= 0.0 or d > 0.0) else 0.0
        zi = z[i]
        if down < zi:
            inner = down
            in_sp = dn_sp
            in_sm = dn_sm
        elif down > zi:
            inner = zi
            in_sp = 0.0
            in_sm = 0.0
        else:
            inner = zi
            in_sp = 0.0
            in_sm = dn_sm
        if up > inner:
            v = up
            v_sp = up_sp
            v_sm = up_sm
        elif up < inner:
            v = inner
            v_sp = in_sp
            v_sm = in_sm
        else:
            v = up
            v_sp = max(up_sp, in_sp)
            v_sm = min(up_sm, in_sm)
        f += w * v
        sp += w * v_sp
        sm += w * v_sm
    return f, sp, sm


@_jit_exact
def cp_invert_step(P, z, x_prev, target, lo, hi, smin, tol):  # pragma: no cover - compiled
    """One sample of the monotone inversion: the input x with F(x) = target, state updated in place.

    ``P`` rows are r, rc, ra, rb, w; ``z`` the operator outputs (updated); ``lo``/``hi`` drive
    limits; ``smin`` a guaranteed lower bound of the slope of F (> 0); ``tol`` the accepted
    |F(x) - target|.  Returns x.  F is piecewise linear and nondecreasing: safeguarded Newton
    steps inside a bracket land on the exact piece in a few iterations.
    """
    f, sp, sm = _eval(x_prev, P, z)
    x = x_prev
    if abs(f - target) <= tol:
        x = x_prev
    else:
        if target > f:
            a = x_prev
            fa = f
            b = x_prev + (target - f) / smin
            if b > hi:
                b = hi
            fb, _s1, _s2 = _eval(b, P, z)
            if fb <= target:
                x = b
                fa = fb
                a = b
        else:
            b = x_prev
            fb = f
            a = x_prev - (f - target) / smin
            if a < lo:
                a = lo
            fa, _s1, _s2 = _eval(a, P, z)
            if fa >= target:
                x = a
                fb = fa
                b = a
        if a < b:
            # Newton from the side we came from, inside [a, b]
            if target > f:
                xc, fc, sc = a, fa, sp
            else:
                xc, fc, sc = b, fb, sm
            x = xc
            for _it in range(200):
                if sc > 0.0:
                    xn = xc + (target - fc) / sc
                else:
                    xn = 0.5 * (a + b)
                if not (xn > a and xn < b):
                    # regula falsi fallback inside the bracket
                    if fb > fa:
                        xn = a + (target - fa) * (b - a) / (fb - fa)
                    if not (xn > a and xn < b):
                        xn = 0.5 * (a + b)
                fn, snp, snm = _eval(xn, P, z)
                x = xn
                if abs(fn - target) <= tol:
                    break
                if fn < target:
                    a, fa = xn, fn
                    xc, fc, sc = xn, fn, snp
                else:
                    b, fb = xn, fn
                    xc, fc, sc = xn, fn, snm
                if b - a <= 1e-15 * (1.0 + abs(a) + abs(b)):
                    break
    # update the state with the chosen input
    m = P.shape[1]
    for i in range(m):
        r, rc, ra, rb = P[0, i], P[1, i], P[2, i], P[3, i]
        up = max(x - r, min(x - rc, 0.0))
        down = min(x + ra, max(x + rb, 0.0))
        z[i] = max(up, min(down, z[i]))
    return x


@_jit_exact
def cp_invert(target, P, z0, x0, lo, hi, smin, tol):  # pragma: no cover - compiled
    """Batch monotone inversion: inputs for every target sample, final state (x, z)."""
    n = target.shape[0]
    out = np.empty(n)
    z = z0.copy()
    x = x0
    for k in range(n):
        x = cp_invert_step(P, z, x, target[k], lo, hi, smin, tol)
        out[k] = x
    return out, z, x


@_jit_exact
def play_step(P, z, x):  # pragma: no cover - compiled
    """One sample of a weighted play sum (rows of P: r, w); state z updated in place."""
    m = P.shape[1]
    acc = 0.0
    for i in range(m):
        r = P[0, i]
        v = max(x - r, min(x + r, z[i]))
        z[i] = v
        acc += P[1, i] * v
    return acc


@_jit_exact
def play_stream(target, P, z0, lo, hi):  # pragma: no cover - compiled
    """Sample-by-sample inverse-PI feedforward (closed-form inverse as a play sum), clipped."""
    n = target.shape[0]
    out = np.empty(n)
    z = z0.copy()
    for k in range(n):
        out[k] = play_step(P, z, target[k])
    return out, z


# ------------------------------------------------------------------ event-driven play sum
@_jit_exact
def lipschitz_state(r, z):  # pragma: no cover - compiled
    """True when |z_{i+1} - z_i| <= r_{i+1} - r_i (thresholds ascending): every state a play
    bank reaches from the zero state (or any consistent state) has this property."""
    m = r.shape[0]
    for i in range(m - 1):
        dr = r[i + 1] - r[i]
        if dr < 0.0:
            return False
        dz = z[i + 1] - z[i]
        if dz > dr * (1.0 + 1e-12) + 1e-300 or -dz > dr * (1.0 + 1e-12) + 1e-300:
            return False
    return True


@_jit_exact
def play_sum_events(x, r, w, z0, x0):  # pragma: no cover - compiled
    """Weighted play sum in O(1) amortised per sample (thresholds ascending, Lipschitz state).

    While the input keeps moving in one direction the operators that follow it form a prefix
    ``i < p`` (their activation points ``z_i +- r_i`` are monotone in ``i`` for a Lipschitz
    state), so ``y = W_p x - d R_p + sum_{i>=p} w_i z_i`` with prefix sums ``W_p``, ``R_p`` of
    ``w`` and ``w r``; the prefix is written back into ``z`` only at a reversal.  The cost is
    one update per sample plus one per operator activation -- independent of the number of
    operators for inputs that do not reverse every sample.
    """
    n = x.shape[0]
    m = r.shape[0]
    cw = np.zeros(m + 1)
    crw = np.zeros(m + 1)
    for i in range(m):
        cw[i + 1] = cw[i] + w[i]
        crw[i + 1] = crw[i] + w[i] * r[i]
    z = z0.copy()
    tail = 0.0
    for i in range(m):
        tail += w[i] * z[i]
    y = np.empty(n)
    p = 0
    d = 0.0
    xl = x0
    n_rev = 0
    for k in range(n):
        xk = x[k]
        if xk != xl:
            dn = 1.0 if xk > xl else -1.0
            if dn != d:
                if p > 0:
                    for i in range(p):
                        z[i] = xl - d * r[i]
                    n_rev += 1
                    if (n_rev & 1023) == 0:
                        tail = 0.0
                        for i in range(m):
                            tail += w[i] * z[i]
                    else:
                        tail += cw[p] * xl - d * crw[p]
                p = 0
                d = dn
            if d > 0.0:
                while p < m and xk - r[p] > z[p]:
                    tail -= w[p] * z[p]
                    p += 1
            else:
                while p < m and xk + r[p] < z[p]:
                    tail -= w[p] * z[p]
                    p += 1
            xl = xk
        y[k] = cw[p] * xk - d * crw[p] + tail
    for i in range(p):
        z[i] = xl - d * r[i]
    return y, z


def play_sum_auto(x, r, w, z0, x0):
    """Weighted play sum: the event-driven kernel when it is valid (ascending thresholds,
    Lipschitz state), else the vectorised loop.  Both give the same result to rounding
    (~1e-15 relative).  The event kernel is faster on every input we measured (smooth records
    by 4-5x, bounded random walks by 2-4x); its cost per reversal grows with the number of
    operators the last stroke moved, so an input making full-range strokes at every sample
    would be the one case where the loop wins (by < 2x).
    """
    if x.shape[0] > 64 and lipschitz_state(r, z0):
        return play_sum_events(x, r, w, z0, float(x0))
    return play_sum(x, r, w, z0)


# ------------------------------------------------------------------ event-driven CP sum
@_jit_exact
def _cp_advance(x, r, rc, ra, rb, z, d):  # pragma: no cover - compiled
    """Operator outputs after a monotone move (direction d) from state z to input x (in place)."""
    m = r.shape[0]
    for i in range(m):
        if d > 0.0:
            up = max(x - r[i], min(x - rc[i], 0.0))
            z[i] = max(up, z[i])
        else:
            down = min(x + ra[i], max(x + rb[i], 0.0))
            z[i] = min(down, z[i])


@_jit_exact
def _cp_events(r, rc, ra, rb, w, z, d, pos, dslope):  # pragma: no cover - compiled
    """Slope-change events of sum_i w_i CP_i along a monotone move in direction d; returns count."""
    m = r.shape[0]
    e = 0
    for i in range(m):
        zi = z[i]
        if d > 0.0:
            if zi < 0.0:
                pos[e] = zi + rc[i]; dslope[e] = w[i]; e += 1
                pos[e] = rc[i]; dslope[e] = -w[i]; e += 1
                pos[e] = r[i]; dslope[e] = w[i]; e += 1
            else:
                pos[e] = zi + r[i]; dslope[e] = w[i]; e += 1
        else:
            if zi > 0.0:
                pos[e] = zi - rb[i]; dslope[e] = w[i]; e += 1
                pos[e] = -rb[i]; dslope[e] = -w[i]; e += 1
                pos[e] = -ra[i]; dslope[e] = w[i]; e += 1
            else:
                pos[e] = zi - ra[i]; dslope[e] = w[i]; e += 1
    return e


@_jit_exact
def cp_sum_events(x, r, rc, ra, rb, w, z0, x0):  # pragma: no cover - compiled
    """Weighted CP sum (eq. 4) driven by slope-change events (exact, piecewise linear).

    On a monotone stretch each operator output is ``max(gamma_up(x), z_start)`` (rising) or
    ``min(gamma_down(x), z_start)`` (falling), so the model output is piecewise linear in x
    with at most three slope changes per operator, at positions known at the reversal.  They
    are sorted once per reversal (O(m log m)); every sample then costs O(1) plus the events
    it passes.  At a reversal the operator outputs are recomputed exactly from the stretch's
    start state, so no rounding accumulates across stretches.
    """
    n = x.shape[0]
    m = r.shape[0]
    z = z0.copy()
    y = np.empty(n)
    pos = np.empty(3 * m)
    dsl = np.empty(3 * m)
    sp = np.empty(3 * m + 1)  # sorted event positions, in the direction coordinate d * x
    sd = np.empty(3 * m + 1)
    d = 0.0
    xl = x0
    n_ev = 0
    j = 0
    F = 0.0
    for i in range(m):
        F += w[i] * z[i]
    fx = x0  # position where F was evaluated
    S = 0.0
    nxt = np.inf  # d * position of the next event
    for k in range(n):
        xk = x[k]
        if xk == xl:
            y[k] = F
            continue
        dn = 1.0 if xk > xl else -1.0
        if dn != d:
            if d != 0.0:
                _cp_advance(xl, r, rc, ra, rb, z, d)
            F = 0.0
            for i in range(m):
                F += w[i] * z[i]
            fx = xl
            d = dn
            n_ev = _cp_events(r, rc, ra, rb, w, z, d, pos, dsl)
            for e in range(n_ev):
                pos[e] *= d
            order = np.argsort(pos[:n_ev])
            for e in range(n_ev):
                sp[e] = pos[order[e]]
                sd[e] = dsl[order[e]]
            sp[n_ev] = np.inf
            sd[n_ev] = 0.0
            j = 0
            S = 0.0
            lim = d * xl
            while sp[j] <= lim:  # events at or behind the start are already in effect
                S += sd[j]
                j += 1
            nxt = sp[j]
        q = d * xk
        while nxt <= q:
            p = d * nxt
            F += S * (p - fx)
            fx = p
            S += sd[j]
            j += 1
            nxt = sp[j]
        F += S * (xk - fx)
        fx = xk
        xl = xk
        y[k] = F
    if d != 0.0:
        _cp_advance(xl, r, rc, ra, rb, z, d)
    return y, z


@_jit_exact
def count_reversals(x):  # pragma: no cover - compiled
    """Number of direction changes of x (standing still is not a change)."""
    n = x.shape[0]
    d = 0.0
    c = 0
    for k in range(1, n):
        dx = x[k] - x[k - 1]
        if dx != 0.0:
            dn = 1.0 if dx > 0.0 else -1.0
            if dn != d and d != 0.0:
                c += 1
            d = dn
    return c


def cp_sum_auto(x, r, rc, ra, rb, w, z0, x0):
    """Weighted CP sum: event-driven when the input reverses in < 2 % of the samples, else the loop."""
    n = x.shape[0]
    if n > 64 and count_reversals(x) < 0.02 * n:
        return cp_sum_events(x, r, rc, ra, rb, w, z0, float(x0))
    return cp_sum(x, r, rc, ra, rb, w, z0)


@_jit_exact
def gram(Z, y):  # pragma: no cover - compiled
    """``Z'Z``, ``Z'y`` and the column sums of Z, single-threaded (no BLAS thread pool: on a
    busy machine the threaded BLAS made the identification 20x slower)."""
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
