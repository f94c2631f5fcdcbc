"""Exact per-sample inverse of the continuous-cell Preisach model (numba).

For a fixed memory, the output reached by moving the input from ``cur`` to ``x`` is continuous
and monotone in ``x`` (non-decreasing for non-negative weights): rising from ``cur`` it follows
``cum[L] + E(x, P[L])`` until ``x`` reaches the maximum ``P[L - 1]``, where the output is
``cum[L - 1]`` and the pair is wiped out; falling, the same with ``cum[L] - E(P[L], x)`` and
the minima.  :func:`preisach_root` walks those memory points (O(1) each) to the piece holding
the desired output, then the grid columns of that piece, in each of which ``E`` is linear in
``x``: the root is one linear interpolation, exact to rounding.  Where the output is flat the
nearest input is taken (the smallest move).
"""

from __future__ import annotations

from .preisach import everett_at, jit, preisach_move, preisach_output


@jit
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


@jit
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


@jit
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
def preisach_invert(target, En, wd, lo, h, P, cum, top, cur, ulo, uhi):  # pragma: no cover - compiled
    """Drives for the desired relay outputs ``target``, clipped to ``[ulo, uhi]``; the memory
    follows the clipped drive.  Returns ``(u, top, cur)``; P and cum need room for one point
    per sample."""
    hi = lo + h * wd.shape[0]
    u = target.copy()
    for k in range(target.shape[0]):
        x = min(max(preisach_root(target[k], En, wd, lo, h, P, cum, top, cur), ulo), uhi)
        u[k] = x
        x = min(max(x, lo), hi)
        if x != cur:
            top = preisach_move(x, En, wd, lo, h, P, cum, top, cur)
            cur = x
    return u, top, cur
