"""One record larger than memory (a :class:`~stageid.data.chunked.ChunkedRecord`) as a record
source of :class:`~.estimator.HankelMAP` (:mod:`.sources` lists what a source answers).

The fit is the in-memory one, step for step (:func:`~.channel_fit.fit_channel`); only the
data's answers are computed chunk by chunk (:mod:`.statistics.chunked_statistics`), here or on
a Dask cluster:

* the channel moments: mean removal, unit-RMS scales, inputs that do not move;
* eq. 9: one pass over the whole record for its lag correlations up to the largest candidate
  horizon (the statistics at every horizon below it, and the lags a result keeps for its
  uncertainty) and the input spectrum; one pass over the training and held-out ranges of
  :func:`~.selection.held_out_segments` when the horizon or the order is chosen;
* the order by held-out simulation error: one sequential pass (:mod:`.selection.chunked_order`).

The statistics equal the in-memory ones to rounding; the excited band (when ``band`` is not
given) comes from a block-averaged input periodogram (see :mod:`.statistics.chunked_statistics`),
so it can differ from the in-memory band by a bin of ``1 / (1024 dt)``.  Not available on a
chunked record (a one-line DataError says what to give instead): ``per_channel`` (one record per
excited input), ``forgetting`` below 1, a list of several orders.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from .._errors import DataError
from ..checks import check_band
from ..data.chunked import DEFAULT_CHUNK, ChunkedRecord
from ..runtime.threads import single_blas_thread
from .channel_fit import require_channel_memory
from .map.posterior import Posterior
from .records import note_still_inputs
from .result import HankelMAPResult
from .selection import SelectionTable, held_out_segments
from .selection.chunked_order import select_order_chunked
from .selection.split import add_leading, by_largest_horizon
from .sources import HeldOutSplit, kept_window_lags
from .statistics.chunked_statistics import column_moments, range_lag_sums, ranged_statistics
from .statistics.hankel_toeplitz import WindowStatistics
from .statistics.window_covariance import WindowLags

__all__ = ["ChunkedSource", "chunked_source", "fit_chunked", "chunked_split_statistics", "check_chunked_settings"]


def check_chunked_settings(settings: Any) -> None:
    """The settings a chunked record cannot serve, refused with what to give instead."""
    if isinstance(settings.order, (list, tuple)) and len(settings.order) > 1:
        raise DataError(f"a chunked record gets one model order; got {list(settings.order)}.")
    if settings.per_channel:
        raise DataError(
            "per-channel identification needs one record per excited input; a chunked record is one "
            "record: drop `per_channel=True`."
        )
    if settings.forgetting != 1.0:
        raise DataError(f"forgetting is not available for chunked records; got {settings.forgetting}, expected 1.")


def _spectrum(power: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The block periodogram with its bin centres in cycles per sample."""
    return power, (np.arange(power.shape[0]) + 0.5) / (2 * power.shape[0])


@dataclasses.dataclass(frozen=True, eq=False)
class ChunkedSource:
    """A chunked record as a record source: its channels are ``(x - shift) / scale``, read chunk
    by chunk of ``chunk`` samples, the sums on ``client``'s workers when given."""

    record: ChunkedRecord
    shift: np.ndarray
    scale: np.ndarray
    chunk: int = DEFAULT_CHUNK
    client: Any = None

    @classmethod
    def prepare(
        cls, record: ChunkedRecord, detrend: bool, notes: list[str], chunk: int = DEFAULT_CHUNK, client: Any = None
    ) -> tuple[ChunkedSource, np.ndarray, np.ndarray]:
        """The source and the channels' unit-RMS ``(input, output)`` scales, from one pass of
        channel moments (as :func:`~.records.prepared_records` and :func:`~.records.to_unit_rms`)."""
        mom = column_moments(record, chunk, client)
        m = record.n_inputs
        note_still_inputs(list((mom.high - mom.low)[:m] == 0), record.input_names, 1, notes)
        if detrend:
            shift, scale = mom.mean, mom.rms
        else:
            raw = np.sqrt((mom.m2 + mom.count * mom.mean**2) / mom.count)
            shift, scale = np.zeros_like(mom.mean), np.where(np.isfinite(raw) & (raw > 0), raw, 1.0)
        return cls(record, shift, scale, chunk, client), scale[:m], scale[m:]

    @property
    def input_names(self) -> tuple[str, ...]:
        return tuple(self.record.input_names)

    @property
    def output_names(self) -> tuple[str, ...]:
        return tuple(self.record.output_names)

    @property
    def dt(self) -> float:
        return self.record.dt

    @property
    def lengths(self) -> list[int]:
        return [self.record.n_samples]

    def groups(self, per_channel: bool) -> list[tuple[list[int], ChunkedSource]]:
        """One direct fit of all inputs (``per_channel`` is refused by :func:`check_chunked_settings`)."""
        return [(list(range(self.record.n_inputs)), self)]

    def whole_lags(self, horizon: int) -> tuple[WindowLags | None, np.ndarray]:
        """The record's :class:`WindowLags` at ``horizon`` (None when shorter than ``8 p``, as in
        memory) and its block input periodogram, from one pass."""
        n, p = self.record.n_samples, int(horizon)
        L = 4 * p - 1 if n >= 8 * p else 1  # a short record: the spectrum alone
        lags, power = self.lag_sums([(0, n)], L - 1, spectrum=True)
        if n < 8 * p:
            return None, power
        ends = [(self.record.read(a, b) - self.shift) / self.scale for a, b in ((0, L - 1), (n - L + 1, n))]
        return WindowLags(lags[0], ends[0][None], ends[1][None], (n,)), power

    def lag_sums(self, ranges: list[tuple[int, int]], max_lag: int, spectrum: bool = False):
        """Lag sums of the scaled channels over each range (:func:`~.statistics.chunked_statistics.range_lag_sums`)."""
        r = self.record
        return range_lag_sums(r, ranges, max_lag, self.shift, self.scale, self.chunk, self.client, spectrum)

    def held_out_split(
        self, cands: list[int], needed: bool, forgetting: float, validation_fraction: float, pooled: bool
    ) -> HeldOutSplit:
        """The whole record's lags and spectrum (one pass) and, when ``needed``, the training /
        held-out statistics per candidate (one pass over their ranges)."""
        whole, power = self.whole_lags(max(cands))
        train: dict[int, WindowStatistics] = {}
        val: dict[int, WindowStatistics] = {}
        if needed:
            train, val = chunked_split_statistics(self, cands, validation_fraction)
        return HeldOutSplit(cands, train, val, whole, _spectrum(power))

    def statistics(
        self, horizon: int, forgetting: float, validation_fraction: float, split: HeldOutSplit
    ) -> WindowStatistics:
        """Eq. 9 over the whole record, from the split's lags when they reach ``horizon``."""
        n, m = self.record.n_samples, self.record.n_inputs
        if split.whole is not None and split.whole.horizon >= horizon:
            s = split.whole.statistics(horizon, m)
        else:
            lags = self.lag_sums([(0, n)], 2 * horizon - 1)[0]
            s = ranged_statistics(self.record, [(0, n)], lags, horizon, self.shift, self.scale)
        power, freqs = split.input_power
        return WindowStatistics(s.W, s.n_windows, horizon, s.n_inputs, s.n_outputs, power, freqs, s.count)

    def arrays(self) -> None:
        """No records in memory: the output-error refinement, which simulates every record, is not run."""
        return None

    def kept_lags(self, horizon: int, split: HeldOutSplit) -> WindowLags | None:
        return kept_window_lags(split, horizon, lambda p: self.whole_lags(p)[0])

    def select_order(
        self, post: Posterior, max_order: int, freqs: np.ndarray, validation_fraction: float, realize_settings: dict
    ) -> tuple[int, SelectionTable]:
        """Section 3.2 in one sequential pass over the record (:func:`~.selection.chunked_order.select_order_chunked`)."""
        r, vf = self.record, validation_fraction
        args = (self.shift, self.scale, self.chunk)
        return select_order_chunked(post, max_order, freqs, r.dt, r, vf, *args, **realize_settings)


def chunked_split_statistics(
    source: ChunkedSource, cands: list[int], validation_fraction: float
) -> tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]]:
    """:func:`~.selection.split_statistics` of a chunked record (no forgetting): ``(train, val)``.

    One pass: the lag sums of every training and held-out range up to the largest candidate's
    window; each range counts at the largest candidate it holds, smaller horizons use the
    leading block of that Gram matrix, as in the in-memory split.
    """
    record = source.record
    tr, va = held_out_segments(record.n_samples, validation_fraction)
    ranges = tr + va
    lags, _ = source.lag_sums(ranges, 2 * max(cands) - 1)
    out: tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]] = ({}, {})
    for first, part, acc in ((0, tr, out[0]), (len(tr), va, out[1])):
        for ph, idx in by_largest_horizon(part, cands).items():
            rngs, rlags = [part[i] for i in idx], [lags[first + i] for i in idx]
            add_leading(acc, ranged_statistics(record, rngs, rlags, ph, source.shift, source.scale), cands)
    return out[0], out[1]


def chunked_source(
    settings: Any, record: ChunkedRecord, notes: list[str], chunk: int = DEFAULT_CHUNK, client: Any = None
) -> tuple[ChunkedSource, np.ndarray, np.ndarray]:
    """The settings checked against a chunked record, then :meth:`ChunkedSource.prepare`.

    The memory check of the fit (:func:`~.channel_fit.require_channel_memory`) runs here as
    well, before the first pass over the record: a refusal does not wait for a read of it all.
    """
    check_chunked_settings(settings)
    if settings.band is not None:  # the one band rule, with the record's Nyquist frequency
        check_band(settings.band, "band", "HankelMAP", nyquist=0.5 / record.dt)
    order = settings.order[0] if isinstance(settings.order, (list, tuple)) else settings.order
    m, q = record.n_inputs, record.n_outputs
    require_channel_memory(settings, [record.n_samples], m, q, settings.horizon, order)
    return ChunkedSource.prepare(record, settings.detrend, notes, chunk, client)


@single_blas_thread
def fit_chunked(est, record: ChunkedRecord, client=None, chunk: int = DEFAULT_CHUNK) -> HankelMAPResult:
    """``est.fit(record)`` (a :class:`~.estimator.HankelMAP`) with the statistics on ``client``'s
    workers when given (a ``dask.distributed.Client``), else here, chunk by chunk of ``chunk`` samples.

    Raises
    ------
    ParameterError, DataError, ResourceError, IdentificationError
        As :meth:`HankelMAP.fit`; DataError also for the settings in the module notes.
    """
    est.validate_params()
    notes: list[str] = []
    return est.fit_source(*chunked_source(est, record, notes, chunk, client), None, notes)
