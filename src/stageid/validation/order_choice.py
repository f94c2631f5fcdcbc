"""The one rule by which every ``order="auto"`` picks a model order, and its warning.

Each estimator scores its candidate orders ``1, 2, ...`` by its own validation error, an RMS
ratio (:class:`~stageid.subspace.HankelMAP`: the square root of the held-out simulation
error's energy ratio; :class:`~stageid.frf.FRDIdentification`: the weighted RMS error at
held-out frequency lines).  Then, for both:

1. the scan ends once ``PATIENCE`` orders in a row have not lowered the least error so far
   (past the system's order the error only scatters about the noise level; an estimator
   whose candidates are costly stops scoring there, one that scores all at once gets the
   same table cut at the same place);
2. the order is the smallest one whose error is within a tolerance of the least error of the
   scan: a larger model must predict the held-out data that much better to be kept.  The
   tolerance is one standard error of an RMS taken over ``n_scored`` values,
   ``1 / sqrt(2 n_scored)``, and at least ``ORDER_TOLERANCE`` (long records, whose errors
   are precise, still do not grow the model for a gain within rounding of the fit).  Errors
   below ``ROUNDING`` (noise-free data) all tie.

When even the chosen model is poor by the estimator's own measure, :func:`poor_order_message`
gives the warning, in one shape for every estimator.

Examples
--------
>>> chosen_order(range(1, 10), [0.9, 0.5, 0.1, 0.0995, 0.1, 0.0999, 0.1, 0.1002, 0.0501])  # 5-8: no gain
3
>>> chosen_order(range(1, 8), [0.9, 0.5, 0.1, 0.0995, 0.0999, 0.0997, 0.0501])  # 7 halves it
7
>>> chosen_order(range(1, 8), [0.9, 0.5, 0.1, 0.0995, 0.0999, 0.0997, 0.094], n_scored=50)  # 10 % is noise
3
>>> scan_orders(range(1, 21), lambda n: max(1.0 / n, 0.2))
[(1, 1.0), (2, 0.5), (3, 0.3333333333333333), (4, 0.25), (5, 0.2), (6, 0.2), (7, 0.2), (8, 0.2), (9, 0.2)]
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np

__all__ = [
    "ORDER_TOLERANCE",
    "PATIENCE",
    "ROUNDING",
    "scan_orders",
    "chosen_order",
    "scanned_length",
    "poor_order_message",
]

#: The least tolerance of rule 2: a larger order must lower the validation error (an RMS
#: ratio) by more than this fraction.
ORDER_TOLERANCE = 0.01
#: Orders in a row without a lower error that end the scan.
PATIENCE = 4
#: Errors below this RMS ratio are rounding (noise-free data): they all tie.
ROUNDING = 1e-8


def _stop(errors: Sequence[float]) -> int | None:
    """Index of the entry that ends the scan (rule 1), or None when it has not ended."""
    best, since = float("inf"), 0
    for k, e in enumerate(errors):
        if float(e) < best and best > ROUNDING:
            best, since = float(e), 0
        else:
            best, since = min(best, float(e)), since + 1
        if since >= PATIENCE:
            return k
    return None


def scanned_length(errors: Sequence[float]) -> int:
    """How many leading entries of ``errors`` (orders in increasing order) the scan looks at:
    up to the order after which ``PATIENCE`` orders in a row bring no gain (rule 1)."""
    stop = _stop(errors)
    return len(errors) if stop is None else stop + 1


def scan_orders(orders: Iterable[int], score: Callable[[int], float]) -> list[tuple[int, float]]:
    """``[(order, score(order)), ...]`` in increasing order, stopping as rule 1 says (the
    candidates after the stop are not scored)."""
    table: list[tuple[int, float]] = []
    for n in orders:
        table.append((int(n), float(score(n))))
        if _stop([e for _, e in table]) is not None:
            break
    return table


def order_tolerance(n_scored: int | None = None) -> float:
    """The tolerance of rule 2: ``max(ORDER_TOLERANCE, 1 / sqrt(2 n_scored))``."""
    if not n_scored:
        return ORDER_TOLERANCE
    return max(ORDER_TOLERANCE, 1.0 / np.sqrt(2.0 * n_scored))


def chosen_order(orders: Sequence[int], errors: Sequence[float], n_scored: int | None = None) -> int:
    """The order of rule 2 among the scanned part of ``(orders, errors)`` (rule 1); ``n_scored``:
    how many values each error is the RMS of (None: many).  Infinite errors (candidates that
    failed) never win.  Raises ValueError when every error is infinite."""
    k = scanned_length(errors)
    err = np.asarray(list(errors)[:k], dtype=float)
    if not np.any(np.isfinite(err)):
        raise ValueError("no candidate order has a finite validation error.")
    best = float(np.min(err[np.isfinite(err)]))
    bound = max(best * (1.0 + order_tolerance(n_scored)), ROUNDING)
    return int(next(n for n, e in zip(list(orders)[:k], err) if e <= bound))


def poor_order_message(who: str, order: int, tried: Sequence[int], measure: str, expected: str, advice: str) -> str:
    """The warning for a model that is poor by its estimator's measure, one shape for all.

    ``tried``: the candidate orders of ``order="auto"`` (empty when the order was given);
    ``measure``: what was found, e.g. ``"misses the response by up to 21.3 % of a column's
    peak"``; ``expected``: e.g. ``"at most 10 %"``; ``advice``: what to try.
    """
    how = f"chosen by order='auto' from orders {min(tried)}-{max(tried)}" if tried else "as given"
    return f"{who}: the order-{order} model ({how}) {measure} (expected {expected}); {advice}"
