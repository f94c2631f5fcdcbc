"""The loop's diagonal pairs refitted through a fixed noise prefilter: the outputs' noise is sensitivity-shaped.

A sensor's noise ``n`` (or a disturbance at the outputs) enters the loop it closes: the recorded
output is ``y_m = T r + (I - T) n``, the noise shaped by the sensitivity ``S = I - T``.  Below the
crossover ``S`` is small, so there the records tell ``T`` precisely; an output-error fit weighs
every frequency alike and lets ``T`` drift there by as much as costs nothing against the white
reading, yet those are the frequencies where eq. 18 divides by ``M (I - T)`` and where the
plant's unstable poles (its zeros) lie.

The classical remedy is the prefiltered output-error step, an approximate Box-Jenkins fit
(Ljung 1999, sec. 7.4 and 14.4): with the noise model ``H_i`` of output ``i`` fixed from a first
estimate, the records are filtered by ``L_i = H_i^-1`` and the pair fitted by output error again;
the filtered error is the innovation, so the fit counts each frequency by how precisely the
records give it.  Here ``H_i`` is the monic minimum-phase factor of the current estimate's
``1 - T_ii`` (:func:`sensitivity_filter`).  Each record's output level is solved again under the
same filtered cost, the pair refitted from the current estimate and from the linear start on the
filtered records, and the refit kept when it lowers that cost; passes, each filter built from the
last estimate, until a pass gains less than the estimate's statistical uncertainty is worth
(:func:`~stageid.closedloop.pem.decrement_tol`) or :data:`MAX_PASSES`.  Only the diagonal pairs are refitted: they carry ``1 - T_ii``,
whose zeros below the crossover are the unstable poles; refitting the couplings too moved the
deduced poles away on the draws tried (RESULTS-recovery.md, Closed loop).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.signal as ss

from .._errors import IdentificationError
from ..data import Experiment
from .covariance import model_orders
from .loop_model import PairFit
from .order_selection import criterion_value
from .pem import decrement_tol, pem
from .polynomial import FREE_ORDERS, PolynomialModel, stabilize

#: most prefilters built from the last estimate and refits through them: each filter comes from a
#: pair that drifts less below the crossover (a 3x3 draw's pole 2.0 % off after two passes, 0.4 %
#: after three)
MAX_PASSES = 6

__all__ = ["MAX_PASSES", "sensitivity_filter", "apply_filter", "prefiltered_refit", "whiten_pairs"]


def sensitivity_filter(model: PolynomialModel, max_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """``(num, den)`` in powers of ``q^-1`` of ``L = 1 / H``, ``H`` the monic minimum-phase factor of
    ``1 - T_ii`` for the diagonal pair ``model`` (``T_ii = q^-nk B / (A F)``).

    ``1 - T_ii = (A F - q^-nk B) / (A F)``; its zeros outside the unit circle (the plant's unstable
    poles, among them) are reflected inside, which keeps ``|H|`` up to a constant and makes ``L``
    stable, and every zero is pulled to at most ``max_radius``: the records cannot tell the noise
    spectrum below their frequency resolution, and a zero on the circle would make ``L`` integrate.
    """
    den = np.convolve(model.A, model.F)
    num = np.concatenate([np.zeros(model.nk), model.B])
    n = max(den.size, num.size)
    diff = np.pad(den, (0, n - den.size)) - np.pad(num, (0, n - num.size))
    return den, stabilize(np.trim_zeros(diff, "b"), max_radius)


def apply_filter(filt: tuple[np.ndarray, np.ndarray], x: np.ndarray) -> np.ndarray:
    """``x`` filtered by ``filt = (num, den)`` from rest."""
    return ss.lfilter(filt[0], filt[1], x)


def _levels(model: PolynomialModel, rf, yf, steps) -> np.ndarray:
    """Each record's output level under ``model`` in the filtered cost (the filtered step's weight)."""
    return np.array([
        float(np.dot(s, yk - model.simulate(rk)) / max(np.dot(s, s), 1e-300)) for rk, yk, s in zip(rf, yf, steps)
    ])  # fmt: skip


def prefiltered_refit(
    model: PolynomialModel,
    r: list[np.ndarray],
    y: list[np.ndarray],
    filt,
    max_nfev: int,
    starts: tuple[PolynomialModel, ...] = (),
    select: PairFit | None = None,
) -> tuple[PolynomialModel, np.ndarray]:
    """``model``'s structure and orders fitted again to the records filtered by ``filt``, and each
    record's output level, both minimising the filtered output error.

    The level is solved under ``model`` first, then the pair is fitted from ``model``, from each
    of ``starts`` and from the linear start on the filtered records, and with ``select`` (the
    estimator's order selection) at the order it selects on them; the lowest BIC on the filtered
    records is kept (at one order: the lowest filtered loss) and its levels are solved again.  From an output-error optimum alone the search can stay near its low-frequency drift
    (a 2x2 loop's diagonal pair: ``|dT|`` 4.1e-3 at 1 Hz from there, 3.6e-4 from the linear start).
    Returns the model and the levels; a pair whose refits all fail comes back as it was, level 0.
    """
    rf = [apply_filter(filt, rk) for rk in r]
    yf = [apply_filter(filt, yk) for yk in y]
    steps = [apply_filter(filt, np.ones(rk.size)) for rk in r]
    d = _levels(model, rf, yf, steps)
    target = [yk - dk * s for yk, dk, s in zip(yf, d, steps)]
    orders = {k: v for k, v in model_orders(model).items() if k in FREE_ORDERS[model.structure]}
    fits = []
    for initial in (model, *starts, None):
        try:
            fits.append(pem(rf, target, model.structure, orders, model.nk, model.dt, max_nfev, initial))
        except IdentificationError:  # a start that fails leaves the other
            continue
    if select is not None:
        try:
            fits.append(select(rf, target, model.dt))
        except IdentificationError:
            pass
    if not fits:
        return model, np.zeros(len(r))
    best = min(fits, key=lambda m: criterion_value("bic", m.n_samples, m.loss, m.n_parameters))
    return best, _levels(best, rf, yf, steps)


def whiten_pairs(
    groups: dict[int, list[Experiment]],
    models: dict[tuple[int, int], PolynomialModel],
    max_radius: float,
    max_nfev: int,
    select: PairFit | None = None,
) -> tuple[dict[tuple[int, int], PolynomialModel], dict[int, list[Experiment]]]:
    """Every output-error diagonal pair ``T_ii`` refitted through its output's sensitivity filter.

    Parameters
    ----------
    groups : dict
        ``{j: experiments exciting reference j}``, output levels removed
        (:func:`~stageid.closedloop.loop_model.identify_pairs`).
    models : dict
        ``{(i, j): PolynomialModel}``, the first stage's pairs.
    max_radius : float
        Largest radius of a noise-model zero (:func:`sensitivity_filter`).
    max_nfev : int
        Evaluation limit of each refit.
    select : callable, optional
        The estimator's fit of one pair, ``(r, y, dt) -> PolynomialModel`` with its order
        selection: run on the first filtered records, since an order selected where the output
        error weighs the low frequencies little can be too low once they count (a 2x2 loop's
        diagonal at order 3 put its unstable pole 14.7 % off through the filter).

    Returns
    -------
    (models, groups)
        The pairs and the records with the diagonal pairs' new output levels removed.
    """
    models = dict(models)
    shifted = {j: [e.y.copy() for e in group] for j, group in groups.items()}
    for i in [i for i in groups if models[(i, i)].structure == "oe"]:
        r, first = [e.u[:, i] for e in groups[i]], models[(i, i)]
        for n_pass in range(MAX_PASSES):
            y = [yk[:, i] for yk in shifted[i]]
            filt = sensitivity_filter(models[(i, i)], max_radius)
            # the output-error pair stays a start: a filter from a drifting pair can lead the first
            # refit away from the band the output error fitted well
            starts = (first,) if n_pass else ()
            m, d = prefiltered_refit(models[(i, i)], r, y, filt, max_nfev, starts, None if n_pass else select)
            before, after = _error(filt, models[(i, i)], r, y, np.zeros(len(r))), _error(filt, m, r, y, d)
            if not after < before:  # the pair is replaced only when the refit lowers the cost it minimises
                break
            models[(i, i)] = m
            for yk, dk in zip(shifted[i], d):
                yk[:, i] -= dk
            # a pass worth less than the estimate's statistical uncertainty ends the passes
            if before - after < decrement_tol(m.n_parameters, sum(rk.size for rk in r)) * before:
                break
    new_groups = {j: [replace(e, y=yk) for e, yk in zip(group, shifted[j])] for j, group in groups.items()}
    return models, new_groups


def _error(filt, model: PolynomialModel, r, y, levels) -> float:
    """Summed squared output error of ``model`` with ``levels`` removed, through ``filt``."""
    out = 0.0
    for rk, yk, dk in zip(r, y, levels):
        e = yk - dk - model.simulate(rk)
        out += float(np.sum(apply_filter(filt, e) ** 2))
    return out
