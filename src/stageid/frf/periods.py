"""How many periods a periodic record holds, and how many of the first are still transient.

The robust BLA (:mod:`.bla`) averages the steady-state periods of each record; these two
checks find them when the caller does not say: the period from the input's repetition, the
transient from the outputs' distance to their steady state.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["detect_periods", "detect_transient_periods"]


def detect_periods(u: np.ndarray, rtol: float = 1e-3) -> int:
    """The number of whole periods in a record: the largest ``P`` whose period repeats.

    ``P`` divides the record length, each period has at least 4 samples, and
    ``||u[L:] - u[:-L]|| <= rtol ||u||`` with ``L = N / P``; 1 when none does.
    """
    x = np.asarray(u, dtype=float).reshape(len(u), -1)
    n = x.shape[0]
    x = x - x.mean(axis=0)
    scale = float(np.linalg.norm(x))
    for p in range(n // 4, 1, -1):
        if n % p == 0 and np.linalg.norm(x[n // p :] - x[: -(n // p)]) <= rtol * scale:
            return p
    return 1


def detect_transient_periods(y: np.ndarray | Sequence[np.ndarray], periods: int) -> int:
    """Leading periods of ``y`` (an array, or a sequence of 1-D channels) that differ from the
    steady state by more than its noise.

    The steady state is the mean ``r`` of the last ``n`` (half of the) periods; a leading period
    counts as transient while its squared distance from ``r`` exceeds twice what noise alone
    gives, ``(1 + 1/n) s^2`` with ``s^2 = sum_tail |x_p - r|^2 / (n - 1)`` (a sum over a whole
    period, so tightly known), or 1e-20 of the steady state's energy when the record is
    noise-free.  At most ``periods - 2`` are dropped.
    """
    channels = [y] if isinstance(y, np.ndarray) else list(y)
    n = periods - periods // 2
    dist, energy = np.zeros(periods), 0.0
    for c in channels:  # channel by channel: no (samples, channels) copy of a long record
        x = np.asarray(c, dtype=float).reshape(periods, -1)
        ref = x[periods // 2 :].mean(axis=0)
        dist += np.sum((x - ref) ** 2, axis=1)
        energy += float(np.sum(ref**2))
    noise = float(np.sum(dist[periods // 2 :])) / max(n - 1, 1)
    threshold = max(2.0 * (1 + 1 / n) * noise, 1e-20 * energy)
    dropped = 0
    while dropped < periods - 2 and dist[dropped] > threshold:
        dropped += 1
    return dropped
