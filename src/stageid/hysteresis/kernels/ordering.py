"""A stable argsort for the kernels that order operators or events (banded and event sums).

numba's own ``np.argsort`` brings a generic quick or merge sort whose first compile costs more
than the kernel that calls it (``benchmarks/RESULTS-cold-start.md``); this bottom-up merge sort
is a few loops that compile in a fraction of that, and gives ``np.argsort(kind="stable")``'s
order exactly (its plain-Python twin in the tests).
"""

from __future__ import annotations

import numpy as np

from .loops import jit_exact

__all__ = ["stable_argsort", "RUN"]

RUN = 8  #: runs sorted by insertion before the merges (fewer passes over short arrays)


@jit_exact
def stable_argsort(keys):  # pragma: no cover - compiled
    """Indices that sort ``keys`` ascending, equal keys in their original order."""
    n = keys.shape[0]
    a = np.arange(n)
    b = np.empty(n, np.int64)
    width = RUN
    for lo in range(0, n, RUN):  # short runs by insertion, then merged pairwise
        for k in range(lo + 1, min(lo + RUN, n)):
            v = a[k]
            i = k - 1
            while i >= lo and keys[v] < keys[a[i]]:
                a[i + 1] = a[i]
                i -= 1
            a[i + 1] = v
    while width < n:
        for lo in range(0, n, 2 * width):
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i = lo
            j = mid
            for k in range(lo, hi):
                if j < hi and (i >= mid or keys[a[j]] < keys[a[i]]):
                    b[k] = a[j]
                    j += 1
                else:
                    b[k] = a[i]
                    i += 1
        a, b = b, a
        width *= 2
    return a
