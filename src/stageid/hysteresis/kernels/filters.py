"""Many columns through one linear filter at rest: the stage dynamics ``c[0] + G[c - c[0]]`` (numba).

The stage identification filters every operator or Preisach-cell column of a record through
the same ``G = B/A`` on every round of its alternation (:mod:`stageid.hysteresis.stage_problem`);
``scipy.signal.lfilter`` along ``axis=0`` walks the columns one by one with a strided inner
loop.  :func:`unit_gain_columns` runs the samples once and all columns together (contiguous,
vectorised), in the transposed direct form II with ``lfilter``'s arithmetic order, so the
result is the same to the bit (checked in ``tests/test_stage_dynamics_filter.py``).
"""

from __future__ import annotations

import numba
import numpy as np

# no fast-math: the same operations in the same order as lfilter, hence the same bits
jit = numba.njit(cache=True, nogil=True)


@jit
def unit_gain_columns(b, a, c):  # pragma: no cover - compiled
    """``c[0] + lfilter(b, a, c - c[0], axis=0)`` for ``c`` of shape (n_samples, p).

    ``b`` and ``a`` have equal length ``m >= 1`` and ``a[0] == 1`` (the caller pads and normalises).
    """
    n, p = c.shape
    m = b.shape[0]
    out = np.empty((n, p))
    if n == 0:
        return out
    z = np.zeros((max(m - 1, 1), p))
    x = np.empty(p)
    y = np.empty(p)
    for k in range(n):
        for j in range(p):
            x[j] = c[k, j] - c[0, j]
        if m == 1:
            for j in range(p):
                out[k, j] = c[0, j] + x[j] * b[0]
            continue
        for j in range(p):
            y[j] = z[0, j] + b[0] * x[j]
        for i in range(m - 2):
            for j in range(p):
                z[i, j] = z[i + 1, j] + x[j] * b[i + 1] - y[j] * a[i + 1]
        for j in range(p):
            z[m - 2, j] = x[j] * b[m - 1] - y[j] * a[m - 1]
            out[k, j] = c[0, j] + y[j]
    return out
