"""Selection of the horizon ``p`` and of the model order by held-out prediction error.

Cao & Chen (2013) choose ``p`` (Fig. 4) and the order (Tables 4-6) by the prediction error
on data not used for the fit.  Here:

* every record of ``n`` samples is cut into ``k = n // 160`` equal segments (at least 4, at
  most 32) and ``round(validation_fraction k)`` of them, spread evenly, are held out
  (:func:`held_out_segments`; with the default 0.25, 1 of 4, ..., 8 of 32): interleaving
  keeps the held-out part representative of chirps, whose frequency changes with time;
* the horizon is chosen by the normalised prediction error of the first block rows of eq. 9
  (the next ``p_min`` samples, ``p_min`` the smallest candidate) on the held-out windows, which
  follows from the held-out :class:`WindowStatistics` alone (no pass over the data per
  candidate); every candidate predicts the same samples from the same point, so one Cholesky
  factor serves all (:mod:`.nested_horizons`);
* the order is chosen by the simulation error on the held-out segments of each candidate
  model realised from the training segments, by the rule every ``order="auto"`` shares
  (:mod:`stageid.validation.order_choice`: the smallest order within 1 % of the best RMS
  on these long records);
* both scores weigh the outputs by the ``weights`` ``HankelMAP`` passes (the inverse noise
  std of each output), so that small noise-dominated coupling outputs do not decide.

This package (section 3.2 of the paper):

===========================  ================================================================
module                       what it holds
===========================  ================================================================
``__init__`` (here)          ``select_horizon``, order selection, ``SelectionTable``
:mod:`.split`                the training / held-out ranges (``held_out_segments``) and the
                             eq. 9 statistics of each (``split_statistics``, ``pooled_split``)
:mod:`.nested_horizons`      held-out scores of every candidate horizon from one Cholesky
                             factor
:mod:`.chunked_order`        ``order="auto"`` on a record larger than memory
===========================  ================================================================
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..._errors import DataError, IdentificationError
from ...validation.order_choice import chosen_order
from ..map.posterior import Posterior, Prior, map_estimate
from ..realisation.era import realize
from ..realisation.weighting import noise_weights, output_weights
from ..statistics.hankel_toeplitz import WindowStatistics, row_residuals
from .nested_horizons import lead_parts, nested_lead_parts
from .split import MIN_SEGMENT, central_statistics, held_out_segments, pooled_split, split_statistics

__all__ = [
    "SelectionTable",
    "prediction_error",
    "default_horizons",
    "horizon_candidates",
    "simulation_error",
    "MIN_SEGMENT",
    "held_out_segments",
    "split_statistics",
    "central_statistics",
    "pooled_split",
    "select_horizon",
    "select_order",
    "order_by_rule",
]


@dataclass(frozen=True)
class SelectionTable:
    """Error versus a hyper-parameter (``kind`` = "horizon" or "order").

    ``values[i]`` was scored ``errors[i]`` (normalised: error energy / output energy, mean
    over outputs, or with output weights the ratio of the weighted sums; ``inf`` for unusable
    candidates); ``chosen`` is the selected value.
    """

    kind: str
    values: tuple[int, ...]
    errors: tuple[float, ...]
    chosen: int

    def to_text(self) -> str:
        """A two-column text table."""
        lines = [f"{self.kind:>8}  held-out error"]
        for v, e in zip(self.values, self.errors):
            mark = "  <- chosen" if v == self.chosen else ""
            lines.append(f"{v:>8d}  {e:.6g}{mark}")
        return "\n".join(lines)


def default_horizons(n_inputs: int, n_outputs: int, n_windows: int, max_regressors: int = 700) -> list[int]:
    """Candidate horizons: 8 .. 80, keeping ``d = p (2m + q) <= max_regressors`` and ``d <= n_windows / 10``."""
    per = 2 * n_inputs + n_outputs
    cands = [8, 12, 16, 20, 25, 30, 40, 50, 60, 80]
    ok = [p for p in cands if p * per <= max_regressors and p * per * 10 <= n_windows]
    if not ok:
        ok = [max(1, min(8, max_regressors // per, n_windows // (10 * per)))]
    return ok


def prediction_error(theta: np.ndarray, stats: WindowStatistics, weights: np.ndarray | None = None) -> float:
    """Normalised held-out multi-step prediction error of eq. 9.

    ``sum ||y_p - theta x||^2 / sum ||y_p||^2`` per output channel (over all ``p`` block rows),
    averaged over the output channels; with ``weights`` (one per output, e.g. the inverse noise
    std) the ratio of the weighted sums ``sum_i w_i^2 err_i / sum_i w_i^2 energy_i`` instead
    (the same when ``w_i^2`` is proportional to ``1 / energy_i``).
    """
    YY = stats.blocks()[2]
    q = stats.n_outputs
    res_c = row_residuals(theta, stats).reshape(stats.horizon, q).sum(axis=0)
    energy = np.diag(YY).reshape(stats.horizon, q).sum(axis=0)
    energy = np.where(energy > 0, energy, 1.0)
    return _normalised(np.clip(res_c, 0.0, None), energy, weights)


def _normalised(err: np.ndarray, energy: np.ndarray, weights: np.ndarray | None) -> float:
    """``mean(err / energy)``, or ``sum(w^2 err) / sum(w^2 energy)`` with weights."""
    if weights is None:
        return float(np.mean(err / energy))
    w2 = np.asarray(weights, dtype=float) ** 2
    return float(np.sum(w2 * err) / max(float(np.sum(w2 * energy)), 1e-300))


def simulation_error(
    model, experiments: Sequence, scored: Sequence[Sequence[tuple[int, int]]], weights: np.ndarray | None = None
) -> float:
    """Normalised simulation error of ``model`` on the held-out ranges of each (mean-removed) record.

    Each record is simulated from rest over its full length (so every held-out range starts
    from a consistent state) and only the samples in ``scored[i]`` (``(start, stop)`` pairs)
    count; the error energy over the variation energy, averaged over the outputs (with
    ``weights``, the ratio of the weighted sums as in :func:`prediction_error`).
    """
    if not model.is_stable():
        return float("inf")
    num = den = 0.0
    for (u, y), ranges in zip(experiments, scored):
        yh = model.simulate(u)
        for a, b in ranges:
            e = y[a:b] - yh[a:b]
            yy = y[a:b] - y[a:b].mean(axis=0)
            num = num + np.sum(e**2, axis=0)
            den = den + np.sum(yy**2, axis=0)
    den = np.where(np.asarray(den) > 0, den, 1.0)
    val = _normalised(np.asarray(num), den, weights)
    return val if np.isfinite(val) else float("inf")


def horizon_candidates(n_inputs: int, n_outputs: int, lengths: Sequence[int]) -> list[int]:
    """:func:`default_horizons` for records of ``lengths`` samples, keeping those whose
    windows fit in every held-out segment (or the smallest when none does)."""
    cands = default_horizons(n_inputs, n_outputs, sum(lengths))
    return [p for p in cands if all(n / 32 > 2 * p + 1 for n in lengths)] or cands[:1]


def select_horizon(
    train: dict[int, WindowStatistics],
    val: dict[int, WindowStatistics],
    cands: list[int],
    prior_of: Callable[[WindowStatistics], Prior | None],
) -> tuple[int, SelectionTable]:
    """The horizon of least held-out prediction error of the first block rows of eq. 9.

    Every candidate with training and held-out windows is scored on the same targets: the
    first ``leads`` block rows of ``y_p`` (``leads`` the smallest candidate), predicted from the
    same point by the MAP estimate of eq. 16 under the fit's prior (``prior_of`` gives it for
    training statistics).  When every range holds the largest candidate (one Gram matrix per
    split, :func:`split_statistics`), the candidates use the central blocks of its windows
    (:func:`central_statistics`); otherwise their own statistics.  The errors weigh the
    outputs by the noise of the largest candidate's training residual on those rows (see
    :mod:`~stageid.subspace.realisation.weighting`).  Unlike the multi-step error over all ``p`` block rows, which scores
    each horizon on its own rows, this compares the candidates on the same samples, and it
    keeps preferring larger horizons while they remove truncation bias
    (``benchmarks/RESULTS-subspace.md``).  The normal equations of the candidates
    are then nested, so one Cholesky factor serves all (:mod:`.nested_horizons`); when they are
    not (records or segments too short for the largest candidate, priors of another kind,
    singular flat-prior equations), each candidate is solved on its own.

    Raises
    ------
    DataError
        When no candidate has both training and held-out windows.
    """
    scored = [p for p in sorted(cands) if p in train and p in val]
    if not scored:
        raise DataError(
            "the records are too short to hold out data for choosing the horizon; give `horizon` explicitly."
        )
    leads, top = scored[0], scored[-1]
    # one Gram matrix per split: every candidate's windows are the largest one's
    nested = all(train[p].count == train[top].count and val[p].count == val[top].count for p in scored)
    parts = nested_lead_parts(train[top], val[top], scored, leads, prior_of(train[top])) if nested else None
    if parts is None:
        if nested:
            train = {p: central_statistics(train[top], p) for p in scored}
            val = {p: central_statistics(val[top], p) for p in scored}
        parts = _candidate_lead_parts(train, val, scored, leads, prior_of)
    held_out, energy, train_rows, yy_rows = parts
    t, q = train[top], train[top].n_outputs
    d = top * (2 * t.n_inputs + q)
    noise_var = train_rows.reshape(leads, q).mean(axis=0) / max(t.n_windows - d, 1.0)
    weights = noise_weights(noise_var, yy_rows.reshape(leads, q).mean(axis=0) / max(t.n_windows, 1.0))
    errors = {}
    for p in scored:
        per_output = energy[p].reshape(leads, q).sum(axis=0)
        per_output = np.where(per_output > 0, per_output, 1.0)
        err = _normalised(np.clip(held_out[p].reshape(leads, q).sum(axis=0), 0.0, None), per_output, weights)
        errors[p] = err if np.isfinite(err) else float("inf")
    if not np.isfinite(min(errors.values())):
        raise DataError(
            "the records are too short to hold out data for choosing the horizon; give `horizon` explicitly."
        )
    best = min(errors, key=errors.get)
    return best, SelectionTable("horizon", tuple(errors), tuple(errors.values()), best)


def _candidate_lead_parts(
    train: dict[int, WindowStatistics],
    val: dict[int, WindowStatistics],
    scored: list[int],
    leads: int,
    prior_of: Callable[[WindowStatistics], Prior | None],
) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray], np.ndarray, np.ndarray]:
    """What :func:`~.nested_horizons.nested_lead_parts` gives, one candidate at a time."""
    held_out, energy = {}, {}
    rows = leads * train[scored[0]].n_outputs
    for p in scored:
        theta = map_estimate(*train[p].blocks()[:2], prior_of(train[p]))[0][:rows]
        XX, YX, YY = val[p].blocks()
        energy[p] = np.diag(YY)[:rows]
        held_out[p] = lead_parts(theta, XX, YX[:rows], energy[p])
    XX, YX, YY = train[scored[-1]].blocks()
    yy = np.diag(YY)[:rows]
    return held_out, energy, lead_parts(theta, XX, YX[:rows], yy), yy


def select_order(
    post: Posterior,
    max_order: int,
    freqs: np.ndarray,
    dt: float,
    records: Sequence[tuple[np.ndarray, np.ndarray]],
    validation_fraction: float,
    **realize_settings,
) -> tuple[int, SelectionTable]:
    """The order by held-out simulation error (:func:`order_by_rule`), over orders
    ``1 .. max_order`` realised from the training posterior ``post`` with
    ``realize_settings`` (at most 8 refinement steps each).

    Raises
    ------
    IdentificationError
        When no candidate order gives a stable model.
    """
    cands = list(range(1, max_order + 1))
    weights = output_weights(post)
    scored = [held_out_segments(u.shape[0], validation_fraction)[1] for u, _ in records]
    errors = []
    for n in cands:
        try:
            mdl, _ = realize(post, n, freqs, dt, max_iter=8, **realize_settings)
        except (IdentificationError, np.linalg.LinAlgError):
            errors.append(float("inf"))
            continue
        errors.append(simulation_error(mdl, records, scored, weights))
    chosen = order_by_rule(cands, errors)
    return chosen, SelectionTable("order", tuple(cands), tuple(errors), chosen)


def order_by_rule(cands: Sequence[int], errors: Sequence[float]) -> int:
    """The order the rule every ``order="auto"`` shares (:mod:`stageid.validation.order_choice`)
    picks from held-out simulation errors, which are energy ratios: compared as RMS ratios.

    Raises :class:`IdentificationError` when no candidate gave a stable model.
    """
    try:
        return chosen_order(list(cands), np.sqrt(np.asarray(errors, dtype=float)).tolist())
    except ValueError:
        raise IdentificationError("no candidate order gave a stable model; give `order` explicitly.") from None
