"""The order by held-out simulation error of output-error-refined candidates (section 3.2).

With ``output_error`` the identified model is the realisation refined on the records'
simulated output error (:mod:`~stageid.subspace.realisation.output_error`), so the order is
chosen among such models: every candidate is realised from the training posterior, refined on
the training segments of the records (each record simulated over its whole length, its initial
state and offsets fitted there) and scored on the held-out segments.  Scoring unrefined
realisations instead keeps orders the refinement does not need and, worse, misses one it
needs: two lightly damped modes closer than the horizon resolves are merged by every
realisation, and only the refined model of the right order separates them.

The candidates are scanned in increasing order and the order is picked by the rule every
``order="auto"`` shares (:mod:`stageid.validation.order_choice`).  The scan stops after
``PATIENCE`` orders without a gain of more than ``ORDER_TOLERANCE`` (rule 2's tolerance):
refined models past the system's order keep lowering the held-out error by fractions of a per
cent as they fit noise, which the shared scan (any gain) would follow to ``max_order``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..._errors import IdentificationError
from ...models.statespace import StateSpaceModel
from ...validation.order_choice import ORDER_TOLERANCE, PATIENCE, ROUNDING
from ..realisation.output_error import OutputErrorProblem, fit_output_error
from .split import held_out_segments

__all__ = ["select_refined_order", "SELECTION_MAX_ITER", "SELECTION_TOL"]

#: Refinement steps per candidate, at most (the final model's refinement runs to its cost's stop).
SELECTION_MAX_ITER = 30
#: A candidate's refinement stops when a step lowers its cost by less than this fraction: the
#: held-out error, compared between orders to 1 % (``ORDER_TOLERANCE``), no longer moves.
SELECTION_TOL = 1e-4


def select_refined_order(
    realised: Callable[[int], StateSpaceModel],
    max_order: int,
    records: Sequence[tuple[np.ndarray, np.ndarray]],
    validation_fraction: float,
    weights: np.ndarray,
    feedthrough: bool,
) -> tuple[list[int], list[float]]:
    """Orders ``1, 2, ...`` as far as the scan goes, and their held-out errors: each candidate
    ``realised(n)`` (from the training posterior), refined on the training segments' output error
    with the outputs weighted by ``weights``; its weighted error energy over the held-out segments
    over their weighted variation energy (``inf`` when it cannot be realised or refines to an
    unstable model)."""
    segments = [held_out_segments(u.shape[0], validation_fraction) for u, _ in records]
    train = OutputErrorProblem(tuple(records), weights, feedthrough, tuple(s[0] for s in segments))
    held = OutputErrorProblem(tuple(records), weights, feedthrough, tuple(s[1] for s in segments))
    energy = _held_out_energy(records, held.ranges, weights)

    def score(n: int) -> float:
        try:
            mdl = realised(n)
        except (IdentificationError, np.linalg.LinAlgError):
            return float("inf")
        fit = fit_output_error(mdl.A, mdl.B, mdl.C, mdl.D, train, SELECTION_MAX_ITER, SELECTION_TOL)
        if fit is None or np.any(np.abs(fit.model.lam) >= 1.0):
            return float("inf")
        err = fit.cost_on(held) / energy
        return err if np.isfinite(err) else float("inf")

    return _scan(max_order, score)


def _scan(max_order: int, score) -> tuple[list[int], list[float]]:
    """Orders from 1 up, until ``PATIENCE`` in a row have not lowered the least held-out RMS
    ratio by more than ``ORDER_TOLERANCE``: refined candidates past the system's order keep
    fitting a little more noise, a gain rule 2 does not count either."""
    orders, errors, best, since = [], [], float("inf"), 0
    for n in range(1, max_order + 1):
        e = score(n)
        orders.append(n)
        errors.append(e)
        if np.sqrt(e) < max(np.sqrt(best) * (1.0 - ORDER_TOLERANCE), ROUNDING):
            best, since = e, 0
        else:
            since += 1
        if since >= PATIENCE:
            break
    return orders, errors


def _held_out_energy(records, ranges, w: np.ndarray) -> float:
    """``sum w_i^2 sum (y_i - mean)^2`` over the held-out ranges (each range about its own mean)."""
    total = 0.0
    for (_, y), rs in zip(records, ranges):
        for a, b in rs:
            seg = y[a:b] - y[a:b].mean(axis=0)
            total += float(np.sum((seg * w[None, :]) ** 2))
    return max(total, 1e-300)
