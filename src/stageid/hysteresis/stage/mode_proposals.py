"""Which disturbance modes the stage identification puts to the held-out test.

A mode that a broadband disturbance rings is in every record's output whatever the fit, but
whether it stands above the model error in a *residual* depends on the fit the residual is
taken from: the model error near the mode changes with the dynamics.  On the dSPACE FORC
records at 40 and 100 Hz the fit the selection chose (order 4, creep 0.05 s, a pure delay on
all records) leaves the ~745 Hz ring 4-5x above a floor of model error, below the rule's
``PEAK_RATIO``, while the order-1 fit on the 100 Hz record alone leaves it 13.8x above
(``studies/hysteresis/RESULTS.md``, section 4j).

The detection (:func:`~.disturbance_modes.disturbance_modes`) only *proposes* modes: whether
one is kept is decided by held-out one-step prediction evidence (:mod:`.selection`).  So a
fit that hides the ring should not veto it.  :func:`proposed_modes` searches the residual of
the chosen fit first (as before: what it finds is the proposal); when that shows no mode, the
residuals of the fits the order selection compares -- every order it tries, at the chosen
creep, each fitted with one record left out (the held-out folds) -- propose instead.  Modes
found in several of those residuals are one mode when within ``SEPARATION`` half-power
half-widths of each other; of each such group the detection with the highest peak ratio is
proposed, strongest first, at most ``MAX_MODES``.  Each of these residuals is searched with
the rule of :mod:`.disturbance_modes` unchanged (its floor never below numerical precision,
so clean records propose nothing).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .disturbance_modes import MAX_MODES, SEPARATION, DisturbanceMode, disturbance_modes

__all__ = ["proposed_modes", "fold_residuals", "strongest_distinct"]


def proposed_modes(
    problem: Any, model: Any, offsets: np.ndarray, orders: tuple[int, ...], taus: tuple[float, ...]
) -> tuple[DisturbanceMode, ...]:
    """The modes to test: those in the chosen fit's residual, else those in the residuals of the
    held-out fits of every order in ``orders`` at creep ``taus`` (see the module's notes).

    Parameters
    ----------
    problem : StageProblem
        The step-2 problem, without a prefilter (no modes in place).
    model, offsets
        The chosen fit on all records and its offsets.
    orders : tuple of int
        The dynamics orders the selection compared.
    taus : tuple of float
        The chosen creep time constants.
    """
    drives = [u for u, _ in problem.recs]
    poles = None if model.dynamics is None else model.dynamics.poles()
    scale = max(float(np.max(np.abs(y))) for _, y in problem.recs)
    found = disturbance_modes(problem.residuals(model, offsets), drives, problem.dt, poles, scale)
    if found:
        return found
    seen: list[DisturbanceMode] = []
    for order in orders:
        for residuals in fold_residuals(problem.held_out_residuals(order, taus)):
            seen += disturbance_modes(residuals, drives, problem.dt, poles, scale)
    return tuple(sorted(strongest_distinct(seen), key=lambda m: m.frequency_hz))


def fold_residuals(folds: list | None) -> list[list[np.ndarray]]:
    """Per held-out fold, every record's whole residual in record order (the fold's fitted
    records and the one left out; a single record's fitted and held-out parts joined).

    ``folds`` as :meth:`~.problem.StageProblem.held_out_residuals` gives them (None: no fold).
    """
    out = []
    for k, (train, tests) in enumerate(folds or []):
        held = [e for e, _ in tests]
        if len(train) == 1 and len(held) == 1 and len(folds) == 1:
            out.append([np.r_[train[0], held[0]]])
        else:
            out.append([*train[:k], *held, *train[k:]])
    return out


def strongest_distinct(modes: list[DisturbanceMode]) -> list[DisturbanceMode]:
    """Of modes within ``SEPARATION`` half-power half-widths of a stronger one, only the stronger;
    at most ``MAX_MODES``, strongest (highest peak ratio) first."""
    kept: list[DisturbanceMode] = []
    for m in sorted(modes, key=lambda m: -m.peak_ratio):
        width = SEPARATION * m.frequency_hz
        if any(abs(m.frequency_hz - k.frequency_hz) <= width * max(m.damping, k.damping) for k in kept):
            continue
        if len(kept) < MAX_MODES:
            kept.append(m)
    return kept
