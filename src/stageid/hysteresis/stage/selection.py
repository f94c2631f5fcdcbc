"""Held-out evidence for the stage model's dynamics order, creep and disturbance modes.

Every choice that adds parameters to a stage model must lower the error on data the fit did
not see (:meth:`~.stage_problem.StageProblem.held_out_score`: each record left out in turn,
or the last 40 % of a single record):

- ``auto`` order and creep: the simplest candidate within ``AUTO_TOLERANCE`` of the best
  held-out error (:func:`choose_candidate`);
- a fixed order ``N``: kept only when its held-out error is below that of no dynamics with
  the same creep, so ``dynamics=N`` is never worse held out than none (:func:`fixed_order`);
- disturbance modes: kept only when the held-out one-step prediction error with them is below
  that of the choice without them and that of no dynamics (:func:`prediction_score`,
  :func:`modes_improve`).

Why prediction, not simulation, for the modes: a mode that the identification drives hardly
excite changes the simulated output by little, and that little is buried under the slow model
error of the hysteresis, which dominates a simulation error.  The one-step prediction error
whitens the residual by a noise model fitted on the training rows, which weights every
frequency by the inverse of the residual's spectrum (the prediction-error method's frequency
weighting, Ljung, *System Identification*, 2nd ed., section 8.5): the quiet band around a mode,
where the drives' few harmonics and the disturbance's ring are, counts as much as the loud
low-frequency band.  The noise model of a candidate with modes has the modes' poles (the
disturbance enters before the dynamics and shares their denominator, the ARMAX view of
:mod:`.disturbance_modes`) times an autoregressive part; each candidate gets the best
autoregressive order of ``NOISE_ORDERS`` on its held-out records.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = [
    "AUTO_TOLERANCE",
    "SCORE_RESOLUTION",
    "NOISE_ORDERS",
    "choose_candidate",
    "fixed_order",
    "modes_improve",
    "noise_polynomial",
    "prediction_score",
    "simulation_score",
]

#: Relative margin within which ``auto`` prefers the candidate with fewer parameters.
AUTO_TOLERANCE = 0.02
#: Held-out errors [% of range] closer than this are equal: a gain below it is rounding, not
#: evidence (a record the simpler model holds exactly scores ~1e-12 either way).
SCORE_RESOLUTION = 1e-6
#: Orders of the autoregressive part of the noise model of :func:`prediction_score`.
NOISE_ORDERS = (2, 4, 8, 16, 32)


def choose_candidate(
    problem: Any, orders: tuple[int, ...], creeps: tuple, progress: Callable[[int, int], None] | None = None
) -> tuple[int, tuple, list]:
    """``(order, creep time constants, held-out scores)``: the simplest candidate within
    ``AUTO_TOLERANCE`` of the best held-out error, or the only candidate (no scores).

    ``progress(done, total)`` is called before the first candidate and after each one (each
    costs a fit per record left out, so a long search can tell how far it is)."""
    if len(orders) * len(creeps) == 1:
        return orders[0], creeps[0], []
    candidates = [(n, taus) for taus in creeps for n in orders]
    held_out = []
    for n, taus in candidates:
        if progress is not None:
            progress(len(held_out), len(candidates))
        held_out.append((n, taus, problem.held_out_score(n, taus)))
    if progress is not None:
        progress(len(held_out), len(candidates))
    best = min(c[2] for c in held_out)
    simple = sorted(held_out, key=lambda c: (c[0] + len(c[1]), c[0]))
    order, taus, _ = next(c for c in simple if c[2] <= best * (1 + AUTO_TOLERANCE) + 1e-3)
    return order, taus, held_out


def fixed_order(problem: Any, order: int, taus: tuple, known: list = ()) -> tuple[int, list, str]:
    """``(order kept, held-out scores, note)`` for an order the caller fixed: the order when its
    held-out error is below that of no dynamics, else 0 with a note saying why.  ``known``:
    ``(order, taus, score)`` already computed (the creep choice's)."""
    if order == 0:
        return 0, [], ""
    scored = [c[2] for c in known if c[0] == order and tuple(c[1]) == tuple(taus)]
    with_dynamics = scored[0] if scored else problem.held_out_score(order, taus)
    without = problem.held_out_score(0, taus)
    scores = [(order, taus, with_dynamics), (0, taus, without)]
    if with_dynamics < without - SCORE_RESOLUTION:
        return order, scores, ""
    return (
        0,
        scores,
        f"order-{order} dynamics did not lower the held-out error ({with_dynamics:.3f} % against "
        f"{without:.3f} % without): none",
    )


def modes_improve(without: float, with_modes: float) -> bool:
    """Whether the modes lower the held-out error (strictly: a tie keeps the simpler model)."""
    return with_modes < without - SCORE_RESOLUTION


def noise_polynomial(residuals: list[np.ndarray], order: int) -> np.ndarray:
    """Monic ``P = [1, p_1, ..., p_order]`` of the autoregressive noise model ``e = e_t / P``
    fitted by least squares on the residuals (one regression over all records)."""
    rows, target = [], []
    for e in residuals:
        if e.size <= 2 * order:
            continue
        rows.append(np.column_stack([e[order - i - 1 : e.size - i - 1] for i in range(order)]))
        target.append(e[order:])
    if not rows:
        return np.ones(1)
    coef = np.linalg.lstsq(np.vstack(rows), np.concatenate(target), rcond=None)[0]
    return np.r_[1.0, -coef]


def simulation_score(folds: list | None) -> float:
    """Summed RMS (% of range) of the held-out residuals (``folds`` as
    :meth:`~.stage_problem.StageProblem.held_out_residuals` gives them; None: inf)."""
    if folds is None:
        return float("inf")
    return float(sum(100 * np.sqrt(np.mean(e**2)) / span for _, tests in folds for e, span in tests))


def prediction_score(folds: list, denominator: np.ndarray | None = None) -> tuple[float, int]:
    """``(score, noise order)``: summed RMS (% of range) of the one-step prediction errors on the
    held-out rows, with the noise model ``1 / (denominator * P)`` (``P`` from
    :func:`noise_polynomial` on the fold's training residuals filtered by ``denominator``), at
    the best order of ``NOISE_ORDERS``.

    ``folds`` as :meth:`~.stage_problem.StageProblem.held_out_residuals` gives them (None: inf).
    The prediction error is the residual through the whitening filter ``denominator * P`` (FIR),
    its first samples, which lack a past, left out.
    """
    from scipy.signal import lfilter

    if folds is None:
        return float("inf"), 0
    den = np.ones(1) if denominator is None else np.asarray(denominator, float)
    best = (float("inf"), 0)
    for order in NOISE_ORDERS:
        score = 0.0
        for train, tests in folds:
            whiten = np.convolve(den, noise_polynomial([lfilter(den, [1.0], e) for e in train], order))
            for e, span in tests:
                eps = lfilter(whiten, [1.0], e)[whiten.size - 1 :]
                score += float(100 * np.sqrt(np.mean(eps**2)) / span) if eps.size else float("inf")
        best = min(best, (score, order))
    return best
