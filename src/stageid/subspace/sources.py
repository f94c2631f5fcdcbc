"""Where a fit's eq. 9 statistics come from: records in memory (here) or one record larger than
memory (:mod:`.chunked_source`).

:meth:`HankelMAP.fit <.estimator.HankelMAP.fit>` runs one pipeline,
:func:`~.channel_fit.fit_channel`, whatever holds the data.  A *record source* answers the
few questions that pipeline asks of the data, each the way its storage allows:

=============================  ================================================================
what the pipeline asks         what a source gives
=============================  ================================================================
``lengths``, names, ``dt``     the records' lengths, channel names and sample time
``groups(per_channel)``        eq. 19: the (input columns, source) of every sub-model
``held_out_split(...)``        section 3.2: training / held-out statistics per candidate
                               horizon and the whole records' lag correlations (one pass)
``statistics(horizon, ...)``   eq. 9 over the whole records, with the input spectrum
``kept_lags(horizon, split)``  the lag statistics a result keeps for its uncertainty
``select_order(...)``          section 3.2: the order by held-out simulation error
=============================  ================================================================

The mean removal, the unit-RMS scaling and the "input does not move" notes come with the
source (:meth:`RecordArrays.prepare`), so that every later step sees channels of unit RMS.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from .._errors import DataError
from ..data.experiment import Experiment
from .channels import channel_groups
from .map.posterior import Posterior
from .records import prepared_records, still_inputs, to_unit_rms
from .selection import SelectionTable, pooled_split, select_order, split_statistics
from .statistics.hankel_toeplitz import WindowStatistics, hankel_toeplitz_statistics
from .statistics.window_covariance import WindowLags, window_lags

__all__ = ["HeldOutSplit", "RecordArrays", "kept_window_lags", "check_lengths"]


@dataclasses.dataclass(frozen=True)
class HeldOutSplit:
    """The candidate horizons, the training and held-out statistics per candidate (empty when
    nothing is chosen), the whole records' lag correlations (None with forgetting, an update or
    records shorter than ``8 p``) and, when the same pass gave it, their input spectrum
    ``(power, freqs)``."""

    candidates: list[int]
    train: dict[int, WindowStatistics]
    val: dict[int, WindowStatistics]
    whole: WindowLags | None
    input_power: tuple[np.ndarray, np.ndarray] | None = None


def kept_window_lags(split: HeldOutSplit, horizon: int, again) -> WindowLags | None:
    """The lag statistics of the records at ``horizon`` a result keeps (the split's, cut down to
    it, or ``again(horizon)`` when the chosen horizon is above the split's); None without them."""
    whole = split.whole
    if whole is None:
        return None
    return whole.at(horizon) if whole.horizon >= horizon else again(horizon)


@dataclasses.dataclass(frozen=True, eq=False)
class RecordArrays:
    """Records in memory as a record source: ``records`` are fresh ``(u, y)`` arrays, mean-removed
    (``detrend``) and scaled to unit RMS, that the fit may keep reading."""

    records: list[tuple[np.ndarray, np.ndarray]]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    dt: float

    @classmethod
    def prepare(
        cls,
        exps: Sequence[Experiment],
        detrend: bool,
        scales: tuple[np.ndarray | None, np.ndarray | None] | None,
        notes: list[str],
    ) -> tuple[RecordArrays, np.ndarray, np.ndarray]:
        """The source and the channels' ``(input, output)`` scales: the records' own RMS, or the
        given ``scales`` of an earlier fit (an update keeps them); a note for each still input."""
        first = exps[0]
        records = prepared_records(exps, detrend)
        still_inputs(records, first.input_names, notes)
        su, sy = to_unit_rms(records, scales)
        return cls(records, tuple(first.input_names), tuple(first.output_names), first.dt), su, sy

    @property
    def lengths(self) -> list[int]:
        return [u.shape[0] for u, _ in self.records]

    def arrays(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The scaled records, which the output-error refinement simulates."""
        return self.records

    def groups(self, per_channel: bool) -> list[tuple[list[int], RecordArrays]]:
        """Eq. 19: every sub-model's input columns and records (:func:`~.channels.channel_groups`)."""
        groups = channel_groups(self.records, self.input_names, per_channel)
        return [(cols, dataclasses.replace(self, records=recs)) for cols, recs in groups]

    def held_out_split(
        self, cands: list[int], needed: bool, forgetting: float, validation_fraction: float, pooled: bool
    ) -> HeldOutSplit:
        """Training / held-out statistics per candidate when ``needed``; with ``pooled`` (a first
        fit without forgetting) one lag pass over the whole records serves their statistics,
        the kept lags and, less the held-out segments', the training segments' statistics."""
        whole = window_lags(self.records, max(cands)) if pooled else None
        train: dict[int, WindowStatistics] = {}
        val: dict[int, WindowStatistics] = {}
        if needed:
            train, val = split_statistics(self.records, cands, forgetting, validation_fraction, whole)
        return HeldOutSplit(cands, train, val, whole)

    def statistics(
        self, horizon: int, forgetting: float, validation_fraction: float, split: HeldOutSplit
    ) -> WindowStatistics:
        """Eq. 9 over the whole records: from the split's lag pass when it has one, else their
        own pass (with forgetting)."""
        stats = None
        if split.whole is not None:
            stats = pooled_split(split.train, split.val, horizon, self.records, validation_fraction, split.whole)
        return stats if stats is not None else hankel_toeplitz_statistics(self.records, horizon, forgetting)

    def kept_lags(self, horizon: int, split: HeldOutSplit) -> WindowLags | None:
        return kept_window_lags(split, horizon, lambda p: window_lags(self.records, p))

    def select_order(
        self,
        post: Posterior,
        max_order: int,
        freqs: np.ndarray,
        validation_fraction: float,
        realize_settings: dict,
    ) -> tuple[int, SelectionTable]:
        """Section 3.2 on the records in memory (:func:`~.selection.select_order`)."""
        return select_order(post, max_order, freqs, self.dt, self.records, validation_fraction, **realize_settings)


def check_lengths(lengths: Sequence[int], horizon: int) -> None:
    """DataError for a record too short for the horizon (eq. 9 needs more than ``2 p`` samples)."""
    short = [n for n in lengths if n <= 2 * horizon]
    if short:
        raise DataError(f"horizon {horizon} needs records of more than {2 * horizon} samples; got {min(short)}.")
