"""One channel's fit of :class:`~.estimator.HankelMAP`, step by step in the paper's order.

:func:`fit_channel` takes a record source (:mod:`.sources`: records in memory, or one record
larger than memory, :mod:`.chunked_source`) of channels scaled to unit RMS, one input group of
eq. 19, through

0. the memory check of the steps below (ResourceError before any work);
1. the held-out split and the horizon (section 3.2, :mod:`.selection`), when ``"auto"``;
2. the eq. 9 statistics of the whole records (:mod:`.statistics`), from the same lag pass as
   the split when there is no forgetting;
3. the MAP posterior (eq. 16-18, :mod:`.map`), continuing the previous one for an update;
4. the order by held-out simulation error (section 3.2), when ``"auto"``;
5. the realisation (eq. 10-15 or the frequency route, :mod:`.realisation`), refined on the
   records' simulated output error (``output_error``, :mod:`.realisation.output_error`), back in
   the data's units,

and returns the frozen :class:`~.result.ChannelFit`; its warnings go to ``notes`` (the result's
diagnostics) as well.  ``settings`` is the estimator whose parameters the steps read
(``horizon``, ``method``, ``prior``, ``forgetting``, ...).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from .._errors import DataError, ExcitationWarning
from ..models.statespace import StateSpaceModel
from ..runtime.resources import require_memory
from ..validation.order_choice import poor_order_message
from .map.posterior import LS_RIDGE_STRENGTH, LS_SINGULAR_PIVOT, METHODS, Posterior, map_posterior, singular_pivot
from .realisation.era import realize
from .realisation.output_error import OE_MAX_WORK, output_error_bytes, output_error_work, refine_output_error
from .realisation.refinement import refinement_bytes
from .realisation.weighting import output_weights
from .records import excited_band, excited_lines
from .result import ChannelFit
from .selection import SelectionTable, horizon_candidates, select_horizon
from .sources import HeldOutSplit, check_lengths
from .statistics.hankel_toeplitz import WindowStatistics, statistics_bytes
from .statistics.theta_response import response_bytes

__all__ = ["fit_channel", "realize_settings", "require_channel_memory"]


def fit_channel(
    settings: Any,
    source: Any,
    cols: list[int],
    order: int | str,
    prev: ChannelFit | None,
    notes: list[str],
    su: np.ndarray,
    sy: np.ndarray,
) -> ChannelFit:
    """One (sub-)model from a record source of channels scaled to unit RMS (``su``, ``sy`` undo
    it; :mod:`.sources`): eq. 9 -> 16-18 -> 10-15."""
    m, q, dt = len(cols), len(source.output_names), source.dt
    in_names = tuple(source.input_names[c] for c in cols)
    horizon, order = (prev.horizon, prev.order) if prev is not None else (settings.horizon, order)
    require_channel_memory(settings, source.lengths, m, q, horizon, order)
    cands = horizon_candidates(m, q, source.lengths) if horizon == "auto" else [horizon]
    pooled = prev is None and settings.forgetting == 1.0
    forgetting, fraction = float(settings.forgetting), settings.validation_fraction
    split = source.held_out_split(cands, "auto" in (horizon, order), forgetting, fraction, pooled)
    horizon_table = None
    if horizon == "auto":  # section 3.2: the horizon by held-out prediction error
        horizon, horizon_table = select_horizon(split.train, split.val, split.candidates, _prior_of(settings, su, sy))
    check_lengths(source.lengths, horizon)
    stats = source.statistics(horizon, forgetting, fraction, split)  # eq. 9
    if prev is None:  # eq. 16-18 (an update continues the previous posterior, which holds the prior)
        post = map_posterior(stats, _prior_of(settings, su, sy)(stats))
        if settings.method == "ls":
            warn_singular(stats, horizon, notes)
    else:
        post = map_posterior(stats, None, prev.scaled_posterior, forgetting)
    band = prev.band if prev is not None else excited_band(stats, dt, settings.band, notes)
    freqs = np.linspace(band[0], band[1], settings.n_frequencies)
    order_table = None
    if order == "auto":  # section 3.2: the order by held-out simulation error
        order, order_table = held_out_order(settings, source, split, horizon, freqs, su, sy)
    _warn_held_out(horizon_table, order_table, in_names, notes)
    records = source.arrays() if prev is None and settings.forgetting == 1.0 else None  # see `realised_model`
    model, cost = realised_model(settings, post, int(order), freqs, dt, su, sy, records, notes)  # eq. 10-15
    if model.n_states and excited_lines(stats) * m < int(order) / 2:
        msg = (
            f"the records excite too few frequencies for order {order} (inputs {list(in_names)}); "
            f"the data are not persistently exciting."
        )
        _excitation_warning(msg, notes, stacklevel=6)
    model = model.with_names(in_names, source.output_names)
    fit = (in_names, source.output_names, post, horizon, int(order), band, model, horizon_table, order_table, cost)
    return ChannelFit(*fit, scales=(su.copy(), sy.copy()), window_lags=source.kept_lags(horizon, split))


def held_out_order(
    settings: Any, source: Any, split: HeldOutSplit, horizon: int, freqs: np.ndarray, su, sy
) -> tuple[int, SelectionTable]:
    """Section 3.2: the order whose model, realised from the training segments' posterior,
    simulates the held-out segments best."""
    if horizon not in split.train:
        raise DataError("the records are too short to hold out data for choosing the order; give `order` explicitly.")
    train = split.train[horizon]
    post_train = map_posterior(train, _prior_of(settings, su, sy)(train))
    fraction = settings.validation_fraction
    return source.select_order(post_train, settings.max_order, freqs, fraction, realize_settings(settings))


def realised_model(
    settings: Any,
    post: Posterior,
    order: int,
    freqs: np.ndarray,
    dt: float,
    su: np.ndarray,
    sy: np.ndarray,
    records: list | None = None,
    notes: list[str] | None = None,
) -> tuple[StateSpaceModel, Any]:
    """Eq. 10-15 or the frequency route (``realization``), refined on the simulated output error
    of the (scaled) ``records`` with the outputs weighted by their noise when ``output_error`` is
    set and records are given, then back to the data's units (``u_s = u / su``, ``y_s = y / sy``);
    the model and the realisation's cost.  A refinement whose steps would exceed ``OE_MAX_WORK``
    operations is not run, and ``notes`` says so.  An update or a fit with forgetting passes no records:
    its model is the posterior's, which weighs the records unlike a refinement over all of them."""
    model, cost = realize(post, order, freqs, dt, **realize_settings(settings))
    A, B, C, D = model.A, model.B, model.C, model.D
    if settings.output_error and records is not None and model.n_states:
        n_samples = sum(u.shape[0] for u, _ in records)
        work = output_error_work(order, B.shape[1], C.shape[0], n_samples, len(records))
        if work <= OE_MAX_WORK:
            A, B, C, D, _ = refine_output_error(A, B, C, D, records, output_weights(post), settings.feedthrough)
        elif notes is not None:
            notes.append(
                f"the output-error refinement was not run: a step would take {work:.1e} operations "
                f"(at most {OE_MAX_WORK:.0e}) with {C.shape[0]} outputs at order {order}; the model is the realisation's."
            )
    A, B, C, D = A, B / su[None, :], C * sy[:, None], D * sy[:, None] / su[None, :]
    return StateSpaceModel(A, B, C, D, dt), cost


def realize_settings(settings: Any) -> dict:
    """The realisation's keyword settings of the estimator."""
    return {"realization": settings.realization, "feedthrough": settings.feedthrough, "refine": settings.refine}


def require_channel_memory(settings: Any, lengths: list[int], m: int, q: int, horizon: Any, order: Any) -> None:
    """Refuse (ResourceError) a horizon, order and frequency count that would not fit in memory."""
    p = max(horizon_candidates(m, q, lengths)) if horizon == "auto" else int(horizon)
    n = settings.max_order if order == "auto" else int(order)
    nz = int(settings.n_frequencies)
    need = statistics_bytes(p, m, q) + response_bytes(p, m, q, nz)
    if settings.realization == "frequency" and settings.refine:
        need += refinement_bytes(n, m, q, nz)
    if settings.output_error:
        need += output_error_bytes(n, m, q)
    require_memory(need, f"HankelMAP with horizon {p}, order {n} and {nz} frequencies on {m} inputs and {q} outputs")


def warn_singular(stats: WindowStatistics, horizon: int, notes: list[str]) -> None:
    """Warn (and note) when the least-squares normal equations needed the ridge."""
    pivot = singular_pivot(stats)
    if pivot is not None:
        msg = (
            f"the least-squares normal equations of horizon {horizon} are singular (smallest relative pivot "
            f"{pivot:.1e}, expected >= {LS_SINGULAR_PIVOT:g}; noise-free or not persistently exciting data): "
            f"solved with a {LS_RIDGE_STRENGTH:g} ridge; method='map' is the regularised estimate."
        )
        _excitation_warning(msg, notes, stacklevel=7)


def _prior_of(settings: Any, su: np.ndarray, sy: np.ndarray):
    """The prior of ``method`` for given statistics (``METHODS``)."""
    return lambda stats: METHODS[settings.method](stats, settings.prior, su, sy)


def _excitation_warning(msg: str, notes: list[str], stacklevel: int) -> None:
    """Keep ``msg`` in the result's notes and warn with it (``stacklevel`` counted from here)."""
    notes.append(msg)
    warnings.warn(msg, ExcitationWarning, stacklevel=stacklevel)


def _warn_held_out(horizon_table: SelectionTable | None, order_table: SelectionTable | None, in_names, notes) -> None:
    """Warn when a chosen horizon or order predicts the held-out data worse than zero."""
    for table in (horizon_table, order_table):
        if table is not None:
            err = table.errors[table.values.index(table.chosen)]
            if err < 1.0:
                continue
            advice = (
                f"it predicts the held-out data worse than zero (inputs {list(in_names)}): the records are too short "
                f"or too little excited for this model."
            )
            if table.kind == "order":  # one shape with every estimator's order warning
                measure = f"has held-out error {err:.3g}"
                msg = poor_order_message("HankelMAP", table.chosen, table.values, measure, "< 1", advice)
            else:
                msg = f"the chosen {table.kind} {table.chosen} has held-out error {err:.3g} (expected < 1); {advice}"
            _excitation_warning(msg, notes, stacklevel=7)
