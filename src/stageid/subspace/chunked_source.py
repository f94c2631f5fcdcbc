"""``HankelMAP`` on one record larger than memory (a :class:`~stageid.data.chunked.ChunkedRecord`).

:func:`fit_chunked` runs the steps of :meth:`HankelMAP.fit <.estimator.HankelMAP.fit>` with the
statistics computed chunk by chunk (:mod:`.chunked_statistics`), locally or on a Dask cluster:

1. the channel moments: mean removal, unit-RMS scales, inputs that do not move (:mod:`.records`);
2. eq. 9: the window statistics, of the whole record for a given horizon, or (``horizon="auto"``)
   of the training and held-out segments of :func:`~.selection.held_out_segments` for every
   candidate, in one pass, pooled into the whole record's statistics as
   :func:`~.selection.pooled_split` does;
3. eq. 16-18 (MAP or least squares), the excited band, the realisation (eq. 10-15 or the
   frequency route) on the statistics alone, as the in-memory fit.

The statistics equal the in-memory ones to rounding; the excited band (when ``band`` is not
given) comes from a block-averaged input periodogram (see :mod:`.chunked_statistics`), so it
can differ from the in-memory band by a bin of ``1 / (1024 dt)``.

``order="auto"`` simulates every candidate over the record in one sequential pass here
(:mod:`.chunked_order`).  Not available on a chunked record (a one-line DataError says what to
give instead): ``per_channel`` (one record per excited input), ``forgetting`` below 1.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError
from ..checks import check_band
from ..data.chunked import DEFAULT_CHUNK, ChunkedRecord
from ..models.statespace import StateSpaceModel
from ..runtime.resources import require_memory
from ..runtime.threads import single_blas_thread
from .map.posterior import METHODS, map_posterior
from .realisation.era import realize
from .realisation.refinement import refinement_bytes
from .records import excited_band
from .result import ChannelFit, HankelMAPResult
from .selection import held_out_segments, horizon_candidates, select_horizon
from .selection.chunked_order import select_order_chunked
from .statistics.chunked_statistics import column_moments, range_lag_sums, ranged_statistics
from .statistics.hankel_toeplitz import WindowStatistics, statistics_bytes
from .statistics.theta_response import response_bytes

__all__ = ["fit_chunked", "chunked_split_statistics"]


def _check_settings(est, record: ChunkedRecord) -> None:
    """The settings a chunked record cannot serve, refused with what to give instead."""
    if isinstance(est.order, (list, tuple)) and len(est.order) > 1:
        raise DataError(f"a chunked record gets one model order; got {list(est.order)}.")
    if est.per_channel:
        raise DataError(
            "per-channel identification needs one record per excited input; a chunked record is one "
            "record: drop `per_channel=True`."
        )
    if est.forgetting != 1.0:
        raise DataError(f"forgetting is not available for chunked records; got {est.forgetting}, expected 1.")
    if est.band is not None:
        check_band(est.band, "band", "HankelMAP", nyquist=0.5 / record.dt)


def _shift_and_scale(est, record: ChunkedRecord, client, chunk: int, notes: list[str]):
    """The mean removed from every channel and its unit-RMS scale (``records.to_unit_rms``)."""
    mom = column_moments(record, chunk, client)
    m = record.n_inputs
    still = (mom.high - mom.low)[:m] == 0
    if still.all():
        raise DataError(
            f"at least one input must move in some record; got every input ({', '.join(record.input_names)}) "
            f"constant in all 1 record(s)."
        )
    for name in np.asarray(record.input_names)[still]:
        notes.append(f"input '{name}' does not move in any record; its response cannot be identified.")
    if est.detrend:
        return mom.mean, mom.rms
    raw = np.sqrt((mom.m2 + mom.count * mom.mean**2) / mom.count)
    return np.zeros_like(mom.mean), np.where(np.isfinite(raw) & (raw > 0), raw, 1.0)


def chunked_split_statistics(record, cands, validation_fraction, shift, scale, chunk=DEFAULT_CHUNK, client=None):
    """:func:`~.selection.split_statistics` of a chunked record (no forgetting), with the block
    input periodogram of the whole record: ``(train, val, (power, freqs))``.

    One pass: the lag sums of every training and held-out range up to the largest candidate's
    window; each range counts at the largest candidate it holds, smaller horizons use the
    leading block of that Gram matrix, as in the in-memory split.
    """
    n = record.n_samples
    tr, va = held_out_segments(n, validation_fraction)
    ranges = tr + va
    lags, power = range_lag_sums(record, ranges, 2 * max(cands) - 1, shift, scale, chunk, client, spectrum=True)
    out: tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]] = ({}, {})
    for part, acc in ((range(len(tr)), out[0]), (range(len(tr), len(ranges)), out[1])):
        groups: dict[int, list[int]] = {}
        for i in part:
            a, b = ranges[i]
            usable = [p for p in cands if 2 * p + 1 <= b - a]
            if usable:
                groups.setdefault(usable[-1], []).append(i)
        tops = {
            ph: ranged_statistics(record, [ranges[i] for i in idx], [lags[i] for i in idx], ph, shift, scale)
            for ph, idx in groups.items()
        }
        for p in cands:
            for ph, top in tops.items():
                if ph >= p:
                    k = 2 * p * (top.n_inputs + top.n_outputs)
                    sp = WindowStatistics(
                        top.W[:k, :k], top.n_windows, p, top.n_inputs, top.n_outputs, None, None, top.count
                    )
                    acc[p] = sp if p not in acc else acc[p] + sp
    return out[0], out[1], (power, (np.arange(power.shape[0]) + 0.5) / (2 * power.shape[0]))


def _record_statistics(est, record, shift, scale, su, sy, chunk, client):
    """Eq. 9 for the whole record at the given or chosen horizon: ``(stats, train, horizon table)``,
    ``train`` the training segments' statistics (per horizon) when a selection needs them."""
    m, q, n = record.n_inputs, record.n_outputs, record.n_samples
    if est.horizon == "auto" or est.order == "auto":
        cands = horizon_candidates(m, q, [n]) if est.horizon == "auto" else [int(est.horizon)]
        train, val, (power, _) = chunked_split_statistics(
            record, cands, est.validation_fraction, shift, scale, chunk, client
        )
    else:
        train, val = {}, {}
    table = None
    if est.horizon == "auto":
        prior_of = METHODS[est.method]
        p, table = select_horizon(train, val, cands, lambda s: prior_of(s, est.prior, su, sy))
    else:
        p = int(est.horizon)
    if n <= 2 * p:
        raise DataError(f"horizon {p} needs records of more than {2 * p} samples; got {n}.")
    if p in train and p in val and train[p].count + val[p].count >= 0.99 * (n - 2 * p + 1):
        return _with_power(train[p] + val[p], power), train, table  # as selection.pooled_split
    lags, power = range_lag_sums(record, [(0, n)], 2 * p - 1, shift, scale, chunk, client, spectrum=True)
    return _with_power(ranged_statistics(record, [(0, n)], lags, p, shift, scale), power), train, table


def _with_power(stats: WindowStatistics, power: np.ndarray) -> WindowStatistics:
    freqs = (np.arange(power.shape[0]) + 0.5) / (2 * power.shape[0])
    return WindowStatistics(
        stats.W, stats.n_windows, stats.horizon, stats.n_inputs, stats.n_outputs, power, freqs, stats.count
    )


@single_blas_thread
def fit_chunked(est, record: ChunkedRecord, client=None, chunk: int = DEFAULT_CHUNK) -> HankelMAPResult:
    """``est.fit`` (a :class:`~.estimator.HankelMAP`) on a chunked record; statistics on ``client``'s
    workers when given (a ``dask.distributed.Client``), else here, chunk by chunk.

    Raises
    ------
    ParameterError, DataError, ResourceError, IdentificationError
        As :meth:`HankelMAP.fit`; DataError also for the settings in the module notes.
    """
    est.validate_params()
    _check_settings(est, record)
    notes: list[str] = []
    m, q, dt = record.n_inputs, record.n_outputs, record.dt
    order = None if est.order == "auto" else int(est.order[0] if isinstance(est.order, (list, tuple)) else est.order)
    p_max = max(horizon_candidates(m, q, [record.n_samples])) if est.horizon == "auto" else int(est.horizon)
    nz = int(est.n_frequencies)
    n_max = est.max_order if order is None else order
    need = statistics_bytes(p_max, m, q) + response_bytes(p_max, m, q, nz) + refinement_bytes(n_max, m, q, nz)
    require_memory(
        need, f"HankelMAP with horizon {p_max}, order {n_max} and {nz} frequencies on {m} inputs and {q} outputs"
    )
    shift, scale = _shift_and_scale(est, record, client, chunk, notes)
    su, sy = scale[:m], scale[m:]
    stats, train, horizon_table = _record_statistics(est, record, shift, scale, su, sy, chunk, client)
    prior_of = METHODS[est.method]
    post = map_posterior(stats, prior_of(stats, est.prior, su, sy))  # eq. 16-18
    band = excited_band(stats, dt, est.band, notes)
    freqs = np.linspace(band[0], band[1], est.n_frequencies)
    settings = {"realization": est.realization, "feedthrough": est.feedthrough, "refine": est.refine}
    order_table = None
    if order is None:  # section 3.2: the order by held-out simulation error, one pass here
        p = stats.horizon
        if p not in train:
            raise DataError(
                "the records are too short to hold out data for choosing the order; give `order` explicitly."
            )
        post_train = map_posterior(train[p], prior_of(train[p], est.prior, su, sy))
        order, order_table = select_order_chunked(
            post_train, est.max_order, freqs, dt, record, est.validation_fraction, shift, scale, chunk, **settings
        )
    model, cost = realize(post, order, freqs, dt, **settings)  # eq. 10-15 or the frequency route
    model = StateSpaceModel(
        model.A, model.B / su[None, :], model.C * sy[:, None], model.D * sy[:, None] / su[None, :], dt
    ).with_names(record.input_names, record.output_names)
    fit = ChannelFit(
        record.input_names, record.output_names, post, stats.horizon, order, band, model,
        horizon_table, order_table, cost, scales=(su.copy(), sy.copy()),
    )  # fmt: skip
    stable = model.is_stable()
    if not stable:
        notes.append("the identified model is unstable (a pole on or outside the unit circle).")
    diagnostics = {
        "horizon": stats.horizon,
        "order": order,
        "band_hz": band,
        "n_windows": float(post.n_windows),
        "stable": bool(stable),
        "warnings": notes,
    }
    return HankelMAPResult(model, (fit,), est.clone(), diagnostics, su.copy(), sy.copy())
