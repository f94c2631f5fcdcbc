"""Held-out evidence for the stage model's dynamics order, creep and disturbance modes.

Every choice that adds parameters to a stage model must lower the error on data the fit did
not see (:meth:`~.stage_problem.StageProblem.held_out_score`: each record left out in turn,
or the last 40 % of a single record):

- ``auto`` order and creep: the simplest candidate within ``AUTO_TOLERANCE`` of the best
  held-out error (:func:`choose_candidate`);
- a fixed order ``N``: kept only when its held-out error is below that of no dynamics with
  the same creep, so ``dynamics=N`` is never worse held out than none (:func:`fixed_order`);
- disturbance modes: kept only when the held-out error with them in the dynamics is below the
  held-out error of the same choice without them (:func:`modes_improve`).
"""

from __future__ import annotations

from typing import Any

__all__ = ["AUTO_TOLERANCE", "SCORE_RESOLUTION", "choose_candidate", "fixed_order", "modes_improve"]

#: Relative margin within which ``auto`` prefers the candidate with fewer parameters.
AUTO_TOLERANCE = 0.02
#: Held-out errors [% of range] closer than this are equal: a gain below it is rounding, not
#: evidence (a record the simpler model holds exactly scores ~1e-12 either way).
SCORE_RESOLUTION = 1e-6


def choose_candidate(problem: Any, orders: tuple[int, ...], creeps: tuple) -> tuple[int, tuple, list]:
    """``(order, creep time constants, held-out scores)``: the simplest candidate within
    ``AUTO_TOLERANCE`` of the best held-out error, or the only candidate (no scores)."""
    if len(orders) * len(creeps) == 1:
        return orders[0], creeps[0], []
    held_out = [(n, taus, problem.held_out_score(n, taus)) for taus in creeps for n in orders]
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
