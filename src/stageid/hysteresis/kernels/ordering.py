"""The argsorts of the kernels: operators by band width (banded sums), events by position.

numba's own ``np.argsort`` brings a generic quick or merge sort whose first compile costs a
good part of the calling kernel's (``benchmarks/RESULTS-cold-start.md``).  These are the same
algorithms written for a 1-D float array, a few loops that compile in a fraction of that time,
and they give the same order exactly, ties included (tests against ``np.argsort``), so the
kernels' sums are unchanged to the bit:

- :func:`stable_argsort`: a bottom-up merge sort, ``np.argsort(kind="stable")``'s order;
- :func:`quick_argsort`: numba's quicksort (``numba.misc.quicksort``: median-of-three
  partitions, insertion sort below ``SMALL``), whose order of equal keys the event sums'
  rounding depends on.  Keys must not be NaN.
"""

from __future__ import annotations

import numpy as np

from .loops import jit_exact

__all__ = ["stable_argsort", "quick_argsort", "RUN", "SMALL"]

RUN = 8  #: runs sorted by insertion before the merges (fewer passes over short arrays)
SMALL = 15  #: numba's quicksort sorts shorter partitions by insertion
_MAX_STACK = 100  #: numba's quicksort's stack of pending partitions


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


@jit_exact
def _insertion(keys, R, low, high):  # pragma: no cover - compiled
    """Insertion sort of ``R[low:high + 1]`` by ``keys`` (inclusive bounds, as numba's)."""
    for i in range(low + 1, high + 1):
        k = R[i]
        v = keys[k]
        j = i
        while j > low and v < keys[R[j - 1]]:
            R[j] = R[j - 1]
            j -= 1
        R[j] = k


@jit_exact
def _partition(keys, R, low, high):  # pragma: no cover - compiled
    """numba's partition of ``R[low:high + 1]`` around the median of three; the pivot's index."""
    mid = (low + high) >> 1
    if keys[R[mid]] < keys[R[low]]:
        R[low], R[mid] = R[mid], R[low]
    if keys[R[high]] < keys[R[mid]]:
        R[high], R[mid] = R[mid], R[high]
    if keys[R[mid]] < keys[R[low]]:
        R[low], R[mid] = R[mid], R[low]
    pivot = keys[R[mid]]
    R[high], R[mid] = R[mid], R[high]
    i = low
    j = high - 1
    while True:
        while i < high and keys[R[i]] < pivot:
            i += 1
        while j >= low and pivot < keys[R[j]]:
            j -= 1
        if i >= j:
            break
        R[i], R[j] = R[j], R[i]
        i += 1
        j -= 1
    R[i], R[high] = R[high], R[i]
    return i


@jit_exact
def quick_argsort(keys):  # pragma: no cover - compiled
    """Indices that sort ``keys`` ascending in the order of numba's ``np.argsort`` (quicksort)."""
    n = keys.shape[0]
    R = np.arange(n)
    if n < 2:
        return R
    lows = np.zeros(_MAX_STACK, np.int64)
    highs = np.zeros(_MAX_STACK, np.int64)
    highs[0] = n - 1
    depth = 1
    while depth > 0:
        depth -= 1
        low = lows[depth]
        high = highs[depth]
        while high - low >= SMALL:
            i = _partition(keys, R, low, high)
            if high - i > i - low:  # the larger side waits on the stack
                if high > i:
                    lows[depth] = i + 1
                    highs[depth] = high
                    depth += 1
                high = i - 1
            else:
                if i > low:
                    lows[depth] = low
                    highs[depth] = i - 1
                    depth += 1
                low = i + 1
        _insertion(keys, R, low, high)
    return R
