"""Held-out choice of the order and the input delay of :class:`~.identification.FRDIdentification`.

Every fourth frequency is held out; each candidate is fitted (shortly refined,
:func:`~.fit_search.fit_at_order`) to the others and scored by its weighted RMS error on the
held-out ones.  The order follows the rule every ``order="auto"`` shares
(:mod:`stageid.validation.order_choice`); the delay is the one whose removal fits best.
"""

from __future__ import annotations

import numpy as np

from .._errors import IdentificationError
from ..models import StateSpaceModel
from ..validation.order_choice import chosen_order, scan_orders
from .fit_search import fit_at_order

__all__ = ["largest_order", "held_out_error", "select_order", "select_delay", "SELECTION_ITER"]


def largest_order(n_freqs: int, q: int, m: int) -> int:
    """The largest order the realisation supports with ``n_freqs`` frequencies (and its 2x start)."""
    return max(1, min((2 * n_freqs * m) // (m + q) - 2 - q, 400))


#: Refinement iterations of each candidate of the order selection.
SELECTION_ITER = 15


def held_out_error(G, fz, T, order, w, max_iter: int = SELECTION_ITER, vector_fit: bool = False) -> float:
    """RMS error at every fourth frequency of a model fitted (shortly refined) to the others."""
    test = np.zeros(fz.size, bool)
    test[2::4] = True
    try:
        A, B, C, D, _ = fit_at_order(G[~test], fz[~test], T, order, w[~test], max_iter, vector_fit=vector_fit)
        Gm = StateSpaceModel(A, B, C, D, dt=T).frequency_response(fz[test])
    except (IdentificationError, np.linalg.LinAlgError, ValueError):
        return float("inf")
    err = float(np.sqrt(np.mean(w[test][:, None, None] * np.abs(Gm - G[test]) ** 2)))
    return err if np.isfinite(err) else float("inf")


def select_order(G: np.ndarray, fz: np.ndarray, T: float, max_order: int, w: np.ndarray) -> tuple[int, tuple]:
    """The order of 1..``max_order`` by the rule every ``order="auto"`` shares
    (:mod:`stageid.validation.order_choice`) on the held-out error of :func:`held_out_error`.

    Each candidate starts from vector fitting besides the two realisations: on a measured
    response whose modes the realisations alone miss (the AFM stage), the short fits of every
    order otherwise stall at the same error, and the scan would stop at a low order.
    """
    limit = max(1, min(max_order, largest_order(int((~(np.arange(fz.size) % 4 == 2)).sum()), G.shape[1], G.shape[2])))
    errors = scan_orders(range(1, limit + 1), lambda n: held_out_error(G, fz, T, n, w, vector_fit=True))
    try:
        scored = int(np.count_nonzero(np.arange(fz.size) % 4 == 2)) * G.shape[1] * G.shape[2]
        order = chosen_order([n for n, _ in errors], [e for _, e in errors], scored)
    except ValueError:
        raise IdentificationError(
            f"no order from 1 to {limit} could be realised from this frequency response."
        ) from None
    return order, tuple(errors)


def select_delay(
    G: np.ndarray, fz: np.ndarray, T: float, zs: np.ndarray, order: int, max_delay: int, w: np.ndarray
) -> tuple[int, tuple]:
    """The input delay (samples) in 0..``max_delay`` whose removal gives the best held-out fit
    of an unrefined realisation (``zs = exp(j 2 pi f dt)``)."""
    errors = tuple((d, held_out_error(G * (zs**d)[:, None, None], fz, T, order, w, 0)) for d in range(max_delay + 1))
    best = min(errors, key=lambda de: de[1])
    if not np.isfinite(best[1]):
        raise IdentificationError(f"no delay from 0 to {max_delay} gave a realisation of order {order}.")
    return best[0], errors
