"""Continuous-cell Preisach model: the memory as a stack of dominant extrema (numba).

The Preisach plane ``lo <= beta <= alpha <= hi`` is cut into cells of side ``h`` (``n`` per
axis); cell ``(i, j)``, ``i > j``, carries its weight spread uniformly over the square, and the
diagonal cell ``i`` carries it along the segment ``alpha = beta`` (the reversible part).  The
Everett function ``E(alpha, beta)`` (weight of the triangle ``beta <= b <= a <= alpha``) is then
exactly the bilinear interpolation of its node values ``En`` in the squares and
``wd[i] (alpha - beta) / h`` in the diagonal cells, so the output is continuous and
piecewise linear in the input between the nodes.

State: ``P[0] = lo`` and the reversal points ``P[1..top]`` (odd: maxima, decreasing; even:
minima, increasing; the wiping-out property removes the dominated ones), ``cum[k]`` the output
when the input sat at ``P[k]``, and the current input ``cur``; the current segment rises from
``P[top]`` when ``top`` is even and falls from it when odd.  The output is ``cum[top] +
E(cur, P[top])`` (rising) or ``cum[top] - E(P[top], cur)`` (falling) (Mayergoyz eq. 1.52),
so a sample costs O(1) amortised, whatever the grid size.  Arrays ``P`` and ``cum`` need
room for one more point per sample.

The plain-Python twin, :func:`cells_reference`, integrates the up part of every cell from the
raw input history instead (no stack, no Everett function).
"""

from __future__ import annotations

import numba
import numpy as np

jit = numba.njit(cache=True, nogil=True)


@jit
def everett_at(En, wd, lo, h, alpha, beta):  # pragma: no cover - compiled
    """``E(alpha, beta)`` for ``lo <= beta <= alpha <= lo + n h`` (0 when ``alpha <= beta``)."""
    if alpha <= beta:
        return 0.0
    n = wd.shape[0]
    s = (alpha - lo) / h
    t = (beta - lo) / h
    a = min(int(s), n - 1)
    b = min(int(t), n - 1)
    fa = s - a
    fb = t - b
    if a == b:
        return wd[a] * (fa - fb)
    return (1.0 - fa) * ((1.0 - fb) * En[a, b] + fb * En[a, b + 1]) + fa * (
        (1.0 - fb) * En[a + 1, b] + fb * En[a + 1, b + 1]
    )


@jit
def preisach_move(x, En, wd, lo, h, P, cum, top, cur):  # pragma: no cover - compiled
    """Move the input from ``cur`` to ``x`` (already in ``[lo, hi]``): new ``top``; updates P, cum."""
    if top % 2 == 0:  # rising from the minimum P[top]
        if x < cur:  # cur becomes a maximum
            top += 1
            P[top] = cur
            cum[top] = cum[top - 1] + everett_at(En, wd, lo, h, cur, P[top - 1])
            while top >= 3 and x <= P[top - 1]:
                top -= 2
        else:
            while top >= 2 and x >= P[top - 1]:
                top -= 2
    else:  # falling from the maximum P[top]
        if x > cur:  # cur becomes a minimum
            top += 1
            P[top] = cur
            cum[top] = cum[top - 1] - everett_at(En, wd, lo, h, P[top - 1], cur)
            while top >= 2 and x >= P[top - 1]:
                top -= 2
        else:
            while top >= 3 and x <= P[top - 1]:
                top -= 2
    return top


@jit
def preisach_output(En, wd, lo, h, P, cum, top, cur):  # pragma: no cover - compiled
    """Relay part of the output in the state ``(P, cum, top, cur)``."""
    if top % 2 == 0:
        return cum[top] + everett_at(En, wd, lo, h, cur, P[top])
    return cum[top] - everett_at(En, wd, lo, h, P[top], cur)


@jit
def preisach_run(u, En, wd, lo, h, P, cum, top, cur):  # pragma: no cover - compiled
    """Outputs (without offset) for the inputs ``u``; returns ``(y, top, cur)``, P and cum updated."""
    hi = lo + h * wd.shape[0]
    y = np.empty(u.shape[0])
    last = preisach_output(En, wd, lo, h, P, cum, top, cur)
    for k in range(u.shape[0]):
        x = min(max(u[k], lo), hi)
        if x != cur:  # a standing input changes nothing
            top = preisach_move(x, En, wd, lo, h, P, cum, top, cur)
            cur = x
            last = preisach_output(En, wd, lo, h, P, cum, top, cur)
        y[k] = last
    return y, top, cur


@jit
def cell_everett(e, n, lo, h, alpha, beta):  # pragma: no cover - compiled
    """Fill ``e`` (flat triangle, row by row) with ``E(alpha, beta)`` of every unit-weight cell."""
    for i in range(n):
        vi = lo + i * h
        fa = min(max((alpha - vi) / h, 0.0), 1.0)
        off = i * (i + 1) // 2
        for j in range(i):
            e[off + j] = fa * min(max((lo + (j + 1) * h - beta) / h, 0.0), 1.0)
        e[off + i] = max(min(alpha, vi + h) - max(beta, vi), 0.0) / h


@jit
def preisach_regressors(u, n, lo, h, P, top, cur):  # pragma: no cover - compiled
    """``Phi[k, c]``: up part of cell ``c`` at sample ``k`` (the model is ``y0 + Phi w``).

    The same walk as :func:`preisach_run` with vector-valued ``cum`` (one column per cell).
    """
    m = n * (n + 1) // 2
    hi = lo + h * n
    cap = top + u.shape[0] + 2
    Pv = np.empty(cap)
    Pv[: top + 1] = P[: top + 1]
    cumv = np.zeros((cap, m))
    e = np.empty(m)
    for k in range(1, top + 1):  # cumulative vectors of the starting stack
        if k % 2 == 1:
            cell_everett(e, n, lo, h, Pv[k], Pv[k - 1])
            cumv[k] = cumv[k - 1] + e
        else:
            cell_everett(e, n, lo, h, Pv[k - 1], Pv[k])
            cumv[k] = cumv[k - 1] - e
    Phi = np.empty((u.shape[0], m))
    for k in range(u.shape[0]):
        x = min(max(u[k], lo), hi)
        turn = (top % 2 == 0 and x < cur) or (top % 2 == 1 and x > cur)
        if turn:
            top += 1
            Pv[top] = cur
            if top % 2 == 1:
                cell_everett(e, n, lo, h, cur, Pv[top - 1])
                cumv[top] = cumv[top - 1] + e
            else:
                cell_everett(e, n, lo, h, Pv[top - 1], cur)
                cumv[top] = cumv[top - 1] - e
        if top % 2 == 0:
            while top >= 2 and x >= Pv[top - 1]:
                top -= 2
        else:
            while top >= 3 and x <= Pv[top - 1]:
                top -= 2
        cur = x
        if top % 2 == 0:
            cell_everett(e, n, lo, h, cur, Pv[top])
            Phi[k] = cumv[top] + e
        else:
            cell_everett(e, n, lo, h, Pv[top], cur)
            Phi[k] = cumv[top] - e
    return Phi


def cells_reference(u: np.ndarray, lo: float, h: float, weights: np.ndarray) -> np.ndarray:
    """Plain-Python twin from all relays down: every cell's up part integrated from the history.

    A relay ``(alpha, beta)`` is up at sample ``k`` iff ``beta <= b(alpha)`` with ``b(alpha) =
    min(alpha, min of u after the last sample where u >= alpha)`` (no such sample: down).  ``b``
    is constant or the identity between consecutive distinct input values, so every cell's
    area (and diagonal length) is integrated exactly piece by piece.
    """
    w = np.asarray(weights, dtype=float)
    n = int(round((np.sqrt(8 * w.size + 1) - 1) / 2))
    x = np.clip(np.asarray(u, dtype=float), lo, lo + n * h)
    y = np.empty(len(x))
    for k in range(len(x)):
        hist = x[: k + 1]
        cuts = np.unique(np.r_[hist, lo + h * np.arange(n + 1)])
        total = 0.0
        for a0, a1 in zip(cuts[:-1], cuts[1:]):
            mid = 0.5 * (a0 + a1)
            reached = np.nonzero(hist >= mid)[0]
            if reached.size == 0:
                continue  # the column never switched up
            b = min(mid, float(hist[reached[-1] :].min()))  # constant, or the identity if b == mid
            identity = b == mid
            i = min(int((mid - lo) / h), n - 1)
            for j in range(i + 1):
                vj = lo + j * h
                if j == i:  # diagonal cell: the relay (alpha, alpha) is up iff b = alpha
                    total += w[i * (i + 1) // 2 + i] * (a1 - a0) / h if identity else 0.0
                elif identity:  # b = alpha above this cell's beta range: the whole column is up
                    total += w[i * (i + 1) // 2 + j] * (a1 - a0) / h
                else:
                    total += w[i * (i + 1) // 2 + j] * (a1 - a0) * min(max(b - vj, 0.0), h) / h**2
        y[k] = total
    return y
