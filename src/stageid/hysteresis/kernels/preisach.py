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

Inverse (:func:`preisach_root`, :func:`preisach_invert`): for a fixed memory the output reached
by moving the input from ``cur`` to ``x`` is continuous and monotone in ``x`` (non-decreasing
for non-negative weights): rising it follows ``cum[L] + E(x, P[L])`` until ``x`` reaches the
maximum ``P[L - 1]``, where the output is ``cum[L - 1]`` and the pair is wiped out; falling,
the same with ``cum[L] - E(P[L], x)`` and the minima.  The root walks those memory points
(O(1) each) to the piece holding the desired output, then the grid columns of that piece, in
each of which ``E`` is linear in ``x``: one linear interpolation, exact to rounding.  Where the
output is flat the nearest input is taken (the smallest move).

The plain-Python twin, :func:`cells_reference`, integrates the up part of every cell from the
raw input history instead (no stack, no Everett function).
"""

from __future__ import annotations

import numba
import numpy as np

jit = numba.njit(cache=True, nogil=True)
#: Helpers of the sample loops, inlined into them: as calls, their array arguments cost ~30 ns
#: a sample in reference counting (benchmarks/RESULTS-hysteresis.md).
inline = numba.njit(cache=True, nogil=True, inline="always")


@inline
def everett_at(En, wd, lo, h, alpha, beta):  # pragma: no cover - compiled
    """``E(alpha, beta)`` for ``lo <= beta <= alpha <= lo + n h`` (0 when ``alpha <= beta``)."""
    if alpha <= beta:
        return 0.0
    n = wd.shape[0]
    ih = 1.0 / h  # loop invariant once inlined: one division per loop, not two per call
    s = (alpha - lo) * ih
    t = (beta - lo) * ih
    a = min(int(s), n - 1)
    b = min(int(t), n - 1)
    fa = s - a
    fb = t - b
    if a == b:
        return wd[a] * (fa - fb)
    return (1.0 - fa) * ((1.0 - fb) * En[a, b] + fb * En[a, b + 1]) + fa * (
        (1.0 - fb) * En[a + 1, b] + fb * En[a + 1, b + 1]
    )


@inline
def preisach_output(En, wd, lo, h, P, cum, top, cur):  # pragma: no cover - compiled
    """Relay part of the output in the state ``(P, cum, top, cur)``."""
    if top % 2 == 0:
        return cum[top] + everett_at(En, wd, lo, h, cur, P[top])
    return cum[top] - everett_at(En, wd, lo, h, P[top], cur)


@inline
def rise_to(En, wd, lo, h, p, xs, xe, target):  # pragma: no cover - compiled
    """Smallest ``x`` in ``[xs, xe]`` with ``E(x, p) >= target`` (``xe`` if none)."""
    x0 = xs
    e0 = everett_at(En, wd, lo, h, x0, p)
    if e0 >= target:
        return x0
    a = int((x0 - lo) / h)
    while True:
        a += 1
        x1 = min(max(lo + a * h, x0), xe)
        e1 = everett_at(En, wd, lo, h, x1, p)
        if e1 >= target:
            if e1 > e0:  # E is linear in x between x0 and x1 (one grid column)
                return min(max(x0 + (target - e0) * ((x1 - x0) / (e1 - e0)), x0), x1)
            return x1
        if x1 >= xe:
            return xe
        x0, e0 = x1, e1


@inline
def fall_to(En, wd, lo, h, p, xs, xe, target):  # pragma: no cover - compiled
    """Largest ``x`` in ``[xe, xs]`` with ``E(p, x) >= target`` (``xe`` if none)."""
    x0 = xs
    e0 = everett_at(En, wd, lo, h, p, x0)
    if e0 >= target:
        return x0
    a = int((x0 - lo) / h) + 1
    while True:
        a -= 1
        x1 = max(min(lo + a * h, x0), xe)
        e1 = everett_at(En, wd, lo, h, p, x1)
        if e1 >= target:
            if e1 > e0:
                return max(min(x0 - (target - e0) * ((x0 - x1) / (e1 - e0)), x0), x1)
            return x1
        if x1 <= xe:
            return xe
        x0, e0 = x1, e1


@inline
def preisach_root(r, En, wd, lo, h, P, cum, top, cur):  # pragma: no cover - compiled
    """Input in ``[lo, hi]`` nearest ``cur`` whose output (relay part) is ``r``, or the end
    of the grid that comes closest; the memory is not changed."""
    hi = lo + h * wd.shape[0]
    y = preisach_output(En, wd, lo, h, P, cum, top, cur)
    if r == y:
        return cur
    if r > y:  # rise: from a virtual minimum at cur if the input was falling
        if top % 2 == 1:
            L, p, c = top + 1, cur, y
        else:
            L, p, c = top, P[top], cum[top]
        xs = cur
        while L >= 2 and r > cum[L - 1]:  # beyond the next maximum: wipe it out
            xs = P[L - 1]
            L -= 2
            p, c = P[L], cum[L]
        return rise_to(En, wd, lo, h, p, xs, P[L - 1] if L >= 2 else hi, r - c)
    if top % 2 == 0:  # fall: from a virtual maximum at cur if the input was rising
        L, p, c = top + 1, cur, y
    else:
        L, p, c = top, P[top], cum[top]
    xs = cur
    while L >= 3 and r < cum[L - 1]:
        xs = P[L - 1]
        L -= 2
        p, c = P[L], cum[L]
    return fall_to(En, wd, lo, h, p, xs, P[L - 1] if L >= 3 else lo, c - r)


@jit
def memory_cum(En, wd, lo, h, P, cum, top):  # pragma: no cover - compiled
    """``cum[1..top]``: the output at each reversal point of the memory ``P`` (``cum[0] = 0``)."""
    cum[0] = 0.0
    for k in range(1, top + 1):
        if k % 2 == 1:
            cum[k] = cum[k - 1] + everett_at(En, wd, lo, h, P[k], P[k - 1])
        else:
            cum[k] = cum[k - 1] - everett_at(En, wd, lo, h, P[k - 1], P[k])


@jit
def preisach_walk(values, En, wd, lo, h, P, cum, top, cur, ulo, uhi, invert):  # pragma: no cover - compiled
    """Drive the memory sample by sample; returns ``(out, top, cur)``, P and cum updated.

    Forward (``invert`` False): ``values`` are inputs and ``out`` the outputs (without
    offset).  Inverse: ``values`` are desired outputs (without offset), each input is
    :func:`preisach_root` clipped to ``[ulo, uhi]``, and ``out`` the inputs.  The move is written out here, not in
    a helper: a helper that writes to ``P`` and ``cum`` costs ~20 ns a sample in reference
    counting even when inlined (benchmarks/RESULTS-hysteresis.md).
    """
    hi = lo + h * wd.shape[0]
    out = np.empty(values.shape[0])
    last = preisach_output(En, wd, lo, h, P, cum, top, cur)
    for k in range(values.shape[0]):
        if invert:
            v = min(max(preisach_root(values[k], En, wd, lo, h, P, cum, top, cur), ulo), uhi)
        else:
            v = values[k]
        x = min(max(v, lo), hi)
        if x != cur:  # a standing input changes nothing
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
            cur = x
            last = preisach_output(En, wd, lo, h, P, cum, top, cur)
        out[k] = v if invert else last
    return out, top, cur


@jit
def preisach_run(u, En, wd, lo, h, P, cum, top, cur):  # pragma: no cover - compiled
    """Outputs (without offset) for the inputs ``u``; returns ``(y, top, cur)``, P and cum updated."""
    return preisach_walk(u, En, wd, lo, h, P, cum, top, cur, lo, lo, False)


@jit
def preisach_invert(target, En, wd, lo, h, P, cum, top, cur, ulo, uhi):  # pragma: no cover - compiled
    """Drives for the desired relay outputs ``target``, clipped to ``[ulo, uhi]``; the memory
    follows the clipped drive.  Returns ``(u, top, cur)``; P and cum need room for one point
    per sample."""
    return preisach_walk(target, En, wd, lo, h, P, cum, top, cur, ulo, uhi, True)


@inline
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
