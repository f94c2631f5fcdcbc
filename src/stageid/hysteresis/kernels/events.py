"""Event-driven play and CP sums: O(1) per sample between reversals (smooth records).

On a monotone stretch the model output is piecewise linear in the input, with slope changes
at positions known at the reversal, so each sample costs O(1) plus the events it passes.
Operator outputs agree with the references of :mod:`stageid.hysteresis.operators` to 1e-12
of the input range (``tests/test_hysteresis_kernels_speedpath.py``).
"""

from __future__ import annotations

import numpy as np

from .loops import jit_exact
from .ordering import quick_argsort


@jit_exact
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


@jit_exact
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


@jit_exact
def cp_advance(x, r, rc, ra, rb, z, d):  # pragma: no cover - compiled
    """Operator outputs after a monotone move (direction d) from state z to input x (in place)."""
    m = r.shape[0]
    for i in range(m):
        if d > 0.0:
            up = max(x - r[i], min(x - rc[i], 0.0))
            z[i] = max(up, z[i])
        else:
            down = min(x + ra[i], max(x + rb[i], 0.0))
            z[i] = min(down, z[i])


@jit_exact
def cp_events(r, rc, ra, rb, w, z, d, pos, dslope):  # pragma: no cover - compiled
    """Slope-change events of sum_i w_i CP_i along a monotone move in direction d; returns count."""
    m = r.shape[0]
    e = 0
    for i in range(m):
        zi = z[i]
        if d > 0.0:
            if zi < 0.0:
                pos[e] = zi + rc[i]
                dslope[e] = w[i]
                e += 1
                pos[e] = rc[i]
                dslope[e] = -w[i]
                e += 1
                pos[e] = r[i]
                dslope[e] = w[i]
                e += 1
            else:
                pos[e] = zi + r[i]
                dslope[e] = w[i]
                e += 1
        else:
            if zi > 0.0:
                pos[e] = zi - rb[i]
                dslope[e] = w[i]
                e += 1
                pos[e] = -rb[i]
                dslope[e] = -w[i]
                e += 1
                pos[e] = -ra[i]
                dslope[e] = w[i]
                e += 1
            else:
                pos[e] = zi - ra[i]
                dslope[e] = w[i]
                e += 1
    return e


@jit_exact
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
                cp_advance(xl, r, rc, ra, rb, z, d)
            F = 0.0
            for i in range(m):
                F += w[i] * z[i]
            fx = xl
            d = dn
            n_ev = cp_events(r, rc, ra, rb, w, z, d, pos, dsl)
            for e in range(n_ev):
                pos[e] *= d
            order = quick_argsort(pos[:n_ev])
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
        cp_advance(xl, r, rc, ra, rb, z, d)
    return y, z


@jit_exact
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
