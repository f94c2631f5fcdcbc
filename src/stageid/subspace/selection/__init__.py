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
``__init__`` (here)          ``select_horizon``, order selection, ``SelectionTable``,
                             ``held_out_segments``
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
from ..statistics.correlations import RecordRows, input_periodogram, lag_correlations, range_ends, straddling_lags
from ..statistics.hankel_toeplitz import (
    WindowStatistics,
    lag_statistics,
    record_statistics,
    row_residuals,
    segments_statistics,
)
from ..statistics.window_covariance import WindowLags
from .nested_horizons import lead_parts, nested_lead_parts

__all__ = [
    "SelectionTable",
    "prediction_error",
    "default_horizons",
    "horizon_candidates",
    "simulation_error",
    "held_out_segments",
    "split_statistics",
    "central_statistics",
    "pooled_split",
    "select_horizon",
    "select_order",
    "order_by_rule",
]

#: Shortest held-out segment, in samples: records are cut into at most ``n / (8 MIN_SEGMENT)`` segments.
MIN_SEGMENT = 20


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


def held_out_segments(n: int, validation_fraction: float) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Training and held-out sample ranges of one record of ``n`` samples (interleaved).

    ``k = n // (8 MIN_SEGMENT)`` equal segments, at least 4 and at most 32, of which
    ``round(validation_fraction k)`` spread evenly over the record are held out; adjacent
    segments of one kind are merged into one range.
    """
    k = int(max(4, min(32, n // max(8 * MIN_SEGMENT, 1))))
    n_val = max(1, int(round(validation_fraction * k)))
    val_idx = sorted({int(np.floor((i + 0.5) * k / n_val)) % k for i in range(n_val)})
    edges = [int(round(i * n / k)) for i in range(k + 1)]
    train, val = [], []
    for i in range(k):
        rng = (edges[i], edges[i + 1])
        target = val if i in val_idx else train
        if target and target[-1][1] == rng[0]:
            target[-1] = (target[-1][0], rng[1])
        else:
            target.append(rng)
    return train, val


def _leading(stats: WindowStatistics, horizon: int) -> WindowStatistics:
    """Statistics of horizon ``horizon`` from those of a larger one (windows of the larger one)."""
    if horizon == stats.horizon:
        return stats
    k = 2 * horizon * (stats.n_inputs + stats.n_outputs)
    return WindowStatistics(
        stats.W[:k, :k], stats.n_windows, horizon, stats.n_inputs, stats.n_outputs, None, None, stats.count
    )


def central_statistics(stats: WindowStatistics, horizon: int) -> WindowStatistics:
    """Statistics of horizon ``horizon`` from those of a larger one ``P``: its central block, the
    window positions ``P - horizon .. P + horizon - 1`` (the larger one's windows, predicting
    from the same point, so that the candidates' regressions are nested: :mod:`.nested_horizons`)."""
    if horizon == stats.horizon:
        return stats
    r = stats.n_inputs + stats.n_outputs
    a, b = (stats.horizon - horizon) * r, (stats.horizon + horizon) * r
    return WindowStatistics(
        stats.W[a:b, a:b], stats.n_windows, horizon, stats.n_inputs, stats.n_outputs, None, None, stats.count
    )


def split_statistics(
    records: Sequence[tuple[np.ndarray, np.ndarray]],
    cands: list[int],
    forgetting: float,
    validation_fraction: float,
    whole: WindowLags | None = None,
) -> tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]]:
    """Eq. 9 statistics of the training and of the held-out segments, per candidate horizon.

    One Gram matrix per segment at its largest usable horizon, summed per horizon; smaller
    horizons use its leading block (exact statistics over a slightly smaller window set).
    The training windows are weighted by ``forgetting`` (each range as a record of its own).
    Given the whole records' lag correlations (``whole``, at a horizon of at least the largest
    candidate), when every range holds the largest candidate and there is no forgetting, the
    training segments' lag correlations are the whole records' less the held-out segments'
    and the products straddling the range boundaries (:func:`_split_from_whole`): no FFT pass
    over the training segments.
    """
    train: dict[int, WindowStatistics] = {}
    val: dict[int, WindowStatistics] = {}
    top = max(cands)
    splits = [held_out_segments(u.shape[0], validation_fraction) for u, _ in records]
    every_range_holds_top = all(b - a >= 2 * top + 1 for tr, va in splits for a, b in tr + va)
    if whole is not None and forgetting == 1.0 and whole.horizon >= top and every_range_holds_top:
        t, v = _split_from_whole(records, splits, top, whole)
        tops: tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]] = ({top: t}, {top: v})
    else:
        tops = _split_tops(records, splits, cands, forgetting)
    for acc, target in zip(tops, (train, val)):
        for p in cands:
            for ph, stats in acc.items():
                if ph >= p:
                    sp = _leading(stats, p)
                    target[p] = sp if p not in target else target[p] + sp
    return train, val


def _split_from_whole(
    records: Sequence[tuple[np.ndarray, np.ndarray]],
    splits: list[tuple[list[tuple[int, int]], list[tuple[int, int]]]],
    horizon: int,
    whole: WindowLags,
) -> tuple[WindowStatistics, WindowStatistics]:
    """Training and held-out statistics at ``horizon``, every range holding it: the held-out
    lag correlations from one pass over the held-out ranges, the training ones as the whole
    records' less those and the products straddling the range boundaries (each such pair
    joins two neighbouring ranges, the ranges being longer than the largest lag); exact to
    rounding."""
    L = 2 * horizon
    m = records[0][0].shape[1]
    R_val = np.zeros((L,) + whole.lags.shape[1:])
    ends: list[list[np.ndarray]] = [[], [], [], []]  # training heads, tails, held-out heads, tails
    joints: list[list[np.ndarray]] = [[], []]  # the L - 1 samples before and after every boundary
    for (u, y), (tr, va) in zip(records, splits):
        R_val += lag_correlations(RecordRows([u, y], va, gap=L), L - 1)
        for i, ranges in enumerate((tr, va)):
            for k, part in enumerate(range_ends(u, y, ranges, L)):
                ends[2 * i + k].append(part)
        cuts = sorted(b for _, b in tr + va)[:-1]
        if cuts:
            for k, part in enumerate(range_ends(u, y, [(c - L + 1, c + L - 1) for c in cuts], L - 1)):
                joints[k].append(part)
    R_train = whole.lags[:L] - R_val
    if joints[0]:
        R_train -= straddling_lags(np.concatenate(joints[0]), np.concatenate(joints[1]))
    out = []
    for i, R in enumerate((R_train, R_val)):
        count = sum(b - a - L + 1 for split in splits for a, b in split[i])
        out.append(lag_statistics(R, np.concatenate(ends[2 * i]), np.concatenate(ends[2 * i + 1]), count, m))
    return out[0], out[1]


def _split_tops(
    records: Sequence[tuple[np.ndarray, np.ndarray]],
    splits: list[tuple[list[tuple[int, int]], list[tuple[int, int]]]],
    cands: list[int],
    forgetting: float,
) -> tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]]:
    """Training and held-out statistics per largest usable horizon of their ranges, one pass
    over each group of ranges (with forgetting, one per range)."""
    tops: tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]] = ({}, {})
    for (u, y), (tr, va) in zip(records, splits):
        for ranges, acc, weight in ((tr, tops[0], forgetting), (va, tops[1], 1.0)):
            groups: dict[int, list[tuple[int, int]]] = {}
            for a, b in ranges:
                usable = [p for p in cands if 2 * p + 1 <= b - a]
                if usable:
                    groups.setdefault(usable[-1], []).append((a, b))
            for ph, rngs in groups.items():
                if weight == 1.0:
                    tops_ = [segments_statistics(u, y, rngs, ph)]
                else:  # forgetting: each range weighted on its own, as a record of its own
                    tops_ = [record_statistics(u[a:b], y[a:b], [ph], weight, with_spectrum=False)[ph] for a, b in rngs]
                for top in tops_:
                    acc[ph] = top if ph not in acc else acc[ph] + top
    return tops


def pooled_split(
    train: dict[int, WindowStatistics],
    val: dict[int, WindowStatistics],
    horizon: int,
    records: Sequence[tuple[np.ndarray, np.ndarray]],
    validation_fraction: float,
    whole: WindowLags | None = None,
) -> WindowStatistics | None:
    """The whole records' eq. 9 statistics (not forgetting), with their input spectrum: from
    their lag correlations ``whole`` when given (at a horizon of at least ``horizon``), else
    completed from the held-out split; None when the split cannot be completed cheaply.

    The split lacks the windows that straddle segment boundaries and, for horizons below a
    range's largest usable one, the last windows of each range (see :func:`split_statistics`);
    those are added from one :func:`segments_statistics` pass over short sample ranges around
    the range ends.  Either way the result equals the statistics of the whole records up to
    rounding and saves a second pass over long records.
    """
    if whole is not None and whole.horizon >= horizon:
        s = whole.statistics(horizon, records[0][0].shape[1])
        return WindowStatistics(s.W, s.n_windows, horizon, s.n_inputs, s.n_outputs, *_periodogram(records), s.count)
    if horizon not in train or horizon not in val:
        return None
    keys = sorted(set(train) | set(val))
    t, v = train[horizon], val[horizon]
    W = t.W + v.W  # a fresh matrix: the missing windows are added in place (no further copies)
    n_windows, count = t.n_windows + v.n_windows, t.count + v.count
    for u, y in records:
        missing = _missing_ranges(u.shape[0], keys, horizon, validation_fraction)
        if missing is None:
            return None
        if missing:
            extra = segments_statistics(u, y, missing, horizon)
            W += extra.W
            n_windows, count = n_windows + extra.n_windows, count + extra.count
    if count != sum(u.shape[0] - 2 * horizon + 1 for u, _ in records):
        return None
    return WindowStatistics(W, n_windows, horizon, t.n_inputs, t.n_outputs, *_periodogram(records), count)


def _periodogram(records: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """The records' input periodograms, summed (:func:`~stageid.subspace.statistics.correlations.input_periodogram`)."""
    power, freqs = input_periodogram(records[0][0])
    for u, _ in records[1:]:
        power = power + input_periodogram(u)[0]
    return power, freqs


def _missing_ranges(n: int, keys: list[int], horizon: int, validation_fraction: float) -> list[tuple[int, int]] | None:
    """Sample ranges holding exactly the horizon-``horizon`` windows of one record that
    :func:`split_statistics` left out; None when they overlap or hold a single window (then
    :func:`segments_statistics` cannot take them)."""
    tr, va = held_out_segments(n, validation_fraction)
    covered = []  # window starts [first, last] each range contributed at its largest usable horizon
    for a, b in sorted(tr + va):
        tops = [k for k in keys if 2 * k + 1 <= b - a]
        if tops and tops[-1] >= horizon:
            covered.append((a, b - 2 * tops[-1]))
    gaps, nxt = [], 0
    for first, last in covered + [(n - 2 * horizon + 1, None)]:
        if first > nxt:
            gaps.append((nxt, first - 1))
        nxt = nxt if last is None else last + 1
    ranges = [(s0, s1 + 2 * horizon) for s0, s1 in gaps]
    if any(s1 == s0 for s0, s1 in gaps) or any(b0 > a1 for (_, b0), (a1, _) in zip(ranges, ranges[1:])):
        return None
    return ranges


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
