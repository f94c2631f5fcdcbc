"""The search for the optimum of the weighted output-error fit of a frequency response.

:class:`~stageid.frf.identification.FRDIdentification` minimises
``sum_k w_k ||G_model(z_k) - G_k||^2`` over all entries of ``A, B, C, D`` (internal discrete
coordinates, columns scaled).  The cost has local minima (a pole pair on noise while a weak
mode goes unfitted; a start far from the data's poles), so :func:`fit_at_order` starts from
several fits that fail in different ways (:func:`fit_starts`: McKelvey, Akcay & Ljung 1996
subspace realisations, their balanced truncations, vector fitting), refines each by
Levenberg-Marquardt until a step lowers the cost by less than ``REFINE_TOL`` of it
(:func:`stageid.subspace.realisation.refinement.refine_frequency_fit`), keeps the lowest, and then tries
mode exchanges (:mod:`.mode_exchange`) while they lower it further.
"""

from __future__ import annotations

import numpy as np

from .._errors import IdentificationError
from ..subspace.realisation.frequency_domain import (
    balanced_start,
    fit_input_matrices,
    frequency_realization,
    reflect_unstable,
)
from ..subspace.realisation.refinement import model_response, refine_frequency_fit
from .mode_exchange import exchanged_modes, residual_peaks
from .vector_fitting import vector_fit_start

__all__ = ["fit_at_order", "fit_starts", "stable_start", "improve_by_exchange", "REFINE_TOL", "REALIZATION_WEIGHT"]

#: Relative cost decrease below which the output-error refinement stops (finer than the
#: subspace default: an FRF has no prior to hide behind, every digit of the fit shows).
REFINE_TOL = 1e-7


#: The (unweighted) subspace step sees only the lines whose weight is at least this fraction
#: of the largest: noise-only lines (outside the excited band) would otherwise dominate it.
REALIZATION_WEIGHT = 1e-4


def stable_start(A, C, G, zs, w) -> tuple[np.ndarray, ...] | None:
    """``(A, B, C, D)`` with unstable poles of ``A`` reflected and ``B``, ``D`` fitted with the
    weights ``w`` on all lines (None when not finite)."""
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(C))):
        return None
    if np.max(np.abs(np.linalg.eigvals(A)), initial=0.0) >= 1.0:
        A = reflect_unstable(A)
    B, D = fit_input_matrices(A, C, G, zs, True, w)
    return (A, B, C, D) if np.all(np.isfinite(B)) and np.all(np.isfinite(D)) else None


def fit_starts(
    G, fz, T, order, w, thorough: bool = True, vector_fit: bool | None = None
) -> tuple[list[tuple[np.ndarray, ...]], np.ndarray]:
    """The starting models of the output-error fit and the singular values of the realisation.

    Five fits, which fail in different ways: the McKelvey realisation on the well-weighted
    lines (noise-only lines left out), the same on all lines each weighted by ``w``
    (frequency-weighted subspace: the lines count as the cost counts them), the balanced
    truncation of a realisation of twice the order, likewise both ways, and vector fitting
    (:mod:`.vector_fitting`, weighted).  Each has its unstable poles reflected and ``B``,
    ``D`` fitted with the weights; the singular values are the first realisation's.
    Not ``thorough`` (the short fits that choose the delay and the order): the first
    realisation and the weighted balanced truncation only, plus vector fitting when
    ``vector_fit`` (default: ``thorough``).
    """
    if vector_fit is None:
        vector_fit = thorough
    zs = np.exp(2j * np.pi * fz * T)
    keep = w >= REALIZATION_WEIGHT * w.max()
    A, _, C, _, sv = frequency_realization(G[keep], fz[keep], T, order)
    candidates = [(A, C)]
    if thorough:
        try:
            Aw, _, Cw, _, _ = frequency_realization(G, fz, T, order, weights=w)
            candidates.append((Aw, Cw))
        except (IdentificationError, np.linalg.LinAlgError):
            pass
    alts = [balanced_start(G[keep], fz[keep], T, order)] if thorough else []
    for alt in [*alts, balanced_start(G, fz, T, order, weights=w)]:
        if alt is not None:
            candidates.append((alt[0], alt[2]))
    try:
        vf = vector_fit_start(G, zs, order, w) if vector_fit else None
    except np.linalg.LinAlgError:
        vf = None
    if vf is not None:
        candidates.append(vf)
    starts = []
    for Ac, Cc in candidates:
        try:
            start = stable_start(Ac, Cc, G, zs, w)
        except np.linalg.LinAlgError:
            start = None
        if start is not None:
            starts.append(start)
    return starts, sv


def fit_at_order(G, fz, T, order, w, max_iter, thorough=False, vector_fit=None):
    """Every start of :func:`fit_starts` refined (weighted output error); the lowest cost kept,
    then (``thorough``) improved by :func:`improve_by_exchange`.  Not ``thorough``: two starts
    (three with ``vector_fit``) and no exchange (the short fits that choose the delay and the order)."""
    zs = np.exp(2j * np.pi * fz * T)
    starts, sv = fit_starts(G, fz, T, order, w, thorough, vector_fit)
    if not starts:
        raise IdentificationError(f"no realisation of order {order} could be formed from this frequency response.")
    best, seen = None, []
    for start in starts:
        response = model_response(start, zs)  # its cost here, and the refinement's first step
        if response is None:
            continue
        cost = float(np.sum(w[:, None, None] * np.abs(response[1] - G) ** 2))
        if not np.isfinite(cost) or any(abs(cost - c) <= 1e-12 * c for c in seen):
            continue  # the same start again (equal weights make the weighted fits the plain ones)
        seen.append(cost)
        if max_iter == 0:
            out = (*start, {"cost": cost})
        else:
            out = refine_frequency_fit(*start, G, zs, weights=w, max_iter=max_iter, tol=REFINE_TOL, response=response)
        if best is None or out[4]["cost"] < best[4]["cost"]:
            best = out
    if best is None:
        raise IdentificationError(f"no start of order {order} has a finite response.")
    if thorough and max_iter > 0:
        best = improve_by_exchange(best, G, zs, w, max_iter)
    A, B, C, D, _ = best
    if not all(np.all(np.isfinite(x)) for x in (A, B, C, D)):
        raise IdentificationError(f"the fit of order {order} is not finite.")
    if np.max(np.abs(np.linalg.eigvals(A)), initial=0.0) >= 1.0:
        raise IdentificationError(f"no stable model of order {order} was found.")
    return A, B, C, D, sv


#: An exchange is kept when it lowers the cost by more than this fraction (less is refinement noise).
EXCHANGE_GAIN = 1e-6


def improve_by_exchange(best: tuple, G, zs, w, max_iter: int) -> tuple:
    """Mode exchanges (:mod:`stageid.frf.mode_exchange`) at each of the largest residual peaks,
    refined; the best kept while it lowers the weighted cost, at most one round per pole pair."""
    for _ in range(best[0].shape[0] // 2):
        A, B, C, D, info = best
        response = model_response((A, B, C, D), zs)
        if response is None:
            break
        residual = response[1] - G
        found = None
        for peak in residual_peaks(residual, w):
            try:
                proposal = exchanged_modes(A, B, C, residual, zs, w, peak)
                start = None if proposal is None else stable_start(*proposal, G, zs, w)
            except np.linalg.LinAlgError:
                start = None
            if start is None:
                continue
            out = refine_frequency_fit(*start, G, zs, weights=w, max_iter=max_iter, tol=REFINE_TOL)
            if out[4]["cost"] < info["cost"] * (1.0 - EXCHANGE_GAIN) and (
                found is None or out[4]["cost"] < found[4]["cost"]
            ):
                found = out
        if found is None:
            break
        best = found
    return best
