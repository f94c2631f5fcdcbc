"""Discrete Preisach model: the relay plane as a staircase, one count per row (numba).

Row ``i`` of the triangular grid holds the relays ``(alpha_i, beta_j)``, ``j <= i``, with
``alpha_i = beta_i = levels[i]``.  A relay switches up when ``u >= alpha`` and down when
``u < beta``, so the up relays of every row are its first ``counts[i]`` (lowest ``beta``):
the state is the staircase ``counts`` and one sample costs O(n_levels), not O(n_levels^2).
The plain-Python twin, relay by relay, is :func:`relays_reference`.
"""

from __future__ import annotations

import numba
import numpy as np

jit = numba.njit(cache=True, nogil=True)


@jit
def n_below(levels, u):  # pragma: no cover - compiled
    """Number of levels ``<= u`` (levels uniform and ascending)."""
    n = levels.shape[0]
    h = levels[1] - levels[0] if n > 1 else 1.0
    a = int(np.floor((u - levels[0]) / h)) + 1
    a = min(max(a, 0), n)
    while a < n and levels[a] <= u:
        a += 1
    while a > 0 and levels[a - 1] > u:
        a -= 1
    return a


@jit
def preisach_run(u, levels, cumw, counts0):  # pragma: no cover - compiled
    """Relay sums ``y(k) = sum_i cumw[i, counts_k[i]]`` and the final staircase."""
    n = levels.shape[0]
    counts = counts0.copy()
    y = np.empty(u.shape[0])
    a_prev = -1
    for k in range(u.shape[0]):
        a = n_below(levels, u[k])
        if a == a_prev:  # the update is idempotent: same level count, same staircase
            y[k] = y[k - 1]
            continue
        a_prev = a
        s = 0.0
        for i in range(n):
            c = i + 1 if i < a else min(counts[i], a)
            counts[i] = c
            s += cumw[i, c]
        y[k] = s
    return y, counts


@jit
def preisach_counts(u, levels, counts0):  # pragma: no cover - compiled
    """The staircase after every sample, shape (n_samples, n_levels) (for the regressors)."""
    n = levels.shape[0]
    counts = counts0.copy()
    out = np.empty((u.shape[0], n), dtype=np.int64)
    for k in range(u.shape[0]):
        a = n_below(levels, u[k])
        for i in range(n):
            c = i + 1 if i < a else min(counts[i], a)
            counts[i] = c
            out[k, i] = c
    return out


def relays_reference(u: np.ndarray, levels: np.ndarray, weights: np.ndarray, up0: np.ndarray) -> np.ndarray:
    """Plain-Python twin: every relay ``(i, j)`` (flat row-major triangle) switched by itself."""
    up = np.array(up0, dtype=bool, copy=True)
    cells = [(i, j) for i in range(len(levels)) for j in range(i + 1)]
    y = np.empty(len(u))
    for k, x in enumerate(u):
        for m, (i, j) in enumerate(cells):
            if x >= levels[i]:
                up[m] = True
            elif x < levels[j]:
                up[m] = False
        y[k] = float(np.dot(weights, up))
    return y
