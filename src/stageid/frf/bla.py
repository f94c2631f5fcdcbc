"""Best linear approximation (BLA) of a nonlinear system, with its noise and nonlinear distortion levels.

Pintelon & Schoukens, *System Identification: A Frequency Domain Approach*, 2nd ed., sec. 3.4
and 4.3.1 (the robust method): ``M`` random-phase multisine realisations of ``P`` steady-state
periods each (one record per input and realisation for MIMO, e.g. an orthogonal design).
For realisation ``m`` the period means give ``G^[m] = Y^[m] U^[m]^-1`` and, from the
period-to-period scatter, the noise variance ``var_n(G^[m])`` (as :func:`periodic_frf`).  Then

* ``G_BLA = mean_m G^[m]``;
* noise variance of ``G_BLA``: ``sum_m var_n(G^[m]) / M^2``;
* total variance of ``G_BLA``: ``sum_m |G^[m] - G_BLA|^2 / (M (M - 1))`` - the
  realisation-to-realisation scatter holds the noise *and* the stochastic nonlinear
  contributions ``G_S``;
* their difference is the nonlinear distortion level; ``M`` times it is ``var(G_S)`` of a
  single realisation.

At unexcited *detection lines* inside the band (odd and even lines of an odd or random-odd
multisine) the output holds only noise and nonlinear distortion: odd nonlinearities put power
on odd lines, even ones on even lines.  Their level above the noise flags each kind, and
(interpolated to the excited lines and referred through ``U^-1``) estimates its share of the
BLA's variance (sec. 4.3.2).

Realisations are added one at a time (:class:`BLAAccumulator`), so memory stays that of one
realisation whatever ``M``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from .._errors import DataError, ParameterError
from ..data import Experiment
from ..models.frequency_response import FrequencyResponse
from ..runtime.heap import prime_heap
from ..runtime.threads import map_in_threads
from .bla_result import DETECTION_DB, BLAResult, DetectionLevels
from .periodic import excited_lines, period_average
from .periods import detect_periods, detect_transient_periods
from .records import ChannelRecord, as_channel_records, check_finite_batch

__all__ = [
    "BLAResult",
    "BLAAccumulator",
    "DetectionLevels",
    "bla_frf",
    "detect_periods",
    "detect_transient_periods",
    "DETECTION_DB",
]


class BLAAccumulator:
    """Realisation-by-realisation robust BLA estimate (memory of one realisation).

    Parameters
    ----------
    periods : int, optional
        Whole periods per record; detected from the first record's input when None.
    transient_periods : int, optional
        Leading periods dropped; detected per realisation from the outputs when None
        (``transient="drop"`` only).
    transient : {"drop", "lpm"}
        ``"drop"``: the leading transient periods are dropped and the noise comes from the
        period-to-period scatter.  ``"lpm"``: every period is kept; the transient at each line
        is estimated from the in-between lines of the whole record's DFT and removed, and the
        noise comes from that local fit (:mod:`.bla_lpm`) - for records that never settle or
        are too short to lose a period (at least 2 periods).
    excited, detection_odd, detection_even : sequence of int, optional
        Line indices on the grid of one period (``k / (L dt)``); taken from the first
        realisation's input (excited) and the unexcited odd / even lines between the first
        and last excited one (detection) when None.
    n_threads : int, optional
        Threads that transform a realisation's channels (``transient="drop"``); None uses
        :func:`~stageid.runtime.threads.default_threads` (``STAGEID_THREADS``, else 1).  They
        pay only where CPUs are idle; the result does not depend on them.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment
    >>> from stageid.signals import multisine
    >>> acc = BLAAccumulator()
    >>> for r in range(4):
    ...     u = multisine(2048, 1.0, 0.01, 0.2, seed=1, realisation=r, n_periods=4, lines="odd")
    ...     acc.add(Experiment(u, np.convolve(u, [0.0, 1.0, 0.5])[:2048] + 0.1 * u**3, 1.0))
    >>> res = acc.result()
    >>> res.n_realisations, res.n_periods, bool(res.even.detected[0])
    (4, 3, False)
    """

    def __init__(
        self,
        periods: int | None = None,
        transient_periods: int | None = None,
        excited: Sequence[int] | None = None,
        detection_odd: Sequence[int] | None = None,
        detection_even: Sequence[int] | None = None,
        transient: str = "drop",
        n_threads: int | None = None,
    ) -> None:
        if transient not in ("drop", "lpm"):
            raise ParameterError(f"`transient` of BLAAccumulator must be 'drop' or 'lpm'; got {transient!r}.")
        if transient == "lpm" and transient_periods not in (None, 0):
            raise ParameterError(
                f"`transient_periods` applies to transient='drop'; got {transient_periods!r} with 'lpm'."
            )
        if n_threads is not None and (not isinstance(n_threads, int) or isinstance(n_threads, bool) or n_threads < 1):
            raise ParameterError(
                f"`n_threads` of BLAAccumulator must be a positive integer or None; got {n_threads!r}."
            )
        self.periods = periods
        self.transient = transient
        self.n_threads = n_threads
        self.transient_periods = 0 if transient == "lpm" else transient_periods
        self._lines = None if excited is None else _lines_of(excited, detection_odd, detection_even)
        self._first: ChannelRecord | None = None
        self._count = 0
        self._sums: dict[str, Any] = {}
        self._kept: list[int] = []
        self._dropped: list[int] = []

    def add(self, realisation: Experiment | ChannelRecord | Sequence[Experiment] | Sequence[ChannelRecord]) -> None:
        """Add one realisation: one record, or one per experiment of a MIMO design.

        Records may be :class:`~stageid.data.Experiment` or :class:`~stageid.frf.records.ChannelRecord`
        (e.g. memory-mapped NPZ channels from :func:`~stageid.frf.records.read_npz_record`).
        """
        prime_heap()  # each realisation's temporaries reuse the pages the last one freed
        recs = as_channel_records(realisation)
        if self.transient == "lpm":
            G, var, Uinv, Ym, detection = self._lpm_lines(recs)
        else:
            G, var, Uinv, Ym, detection = self._period_lines(recs)
        self._count += 1
        s = self._sums
        # Welford's update: the mean and the squared deviations without storing the G^[m]
        delta = G - s.get("mean", 0.0)
        s["mean"] = s.get("mean", 0.0) + delta / self._count
        s["m2"] = s.get("m2", 0.0) + np.abs(delta * np.conj(G - s["mean"]))
        s["var_n"] = s.get("var_n", 0.0) + var
        s["uinv2"] = s.get("uinv2", 0.0) + np.sum(np.abs(Uinv) ** 2, axis=1)  # (lines, m)
        s["y_power"] = s.get("y_power", 0.0) + np.mean(np.abs(Ym) ** 2, axis=(0, 2))
        for kind, (power, noise) in detection.items():
            s[f"{kind}_power"] = s.get(f"{kind}_power", 0.0) + power
            s[f"{kind}_noise"] = s.get(f"{kind}_noise", 0.0) + noise

    def _period_lines(self, recs: Sequence[ChannelRecord]) -> tuple:
        """``G^[m]``, its noise variance, ``U^-1``, the output at the excited lines and the detection
        lines' (power, noise) per kind, from the steady-state periods' means and scatter."""
        Up, Yp = self._period_spectra(recs)
        exc, det_odd, det_even = self._lines
        k1, k2 = exc.size, exc.size + det_odd.size  # positions of the lines in Up and Yp
        G, var, _, Uinv = period_average(Up[:, :k1], Yp[:, :k1])
        detection = {}
        for kind, det, where in (("odd", det_odd, slice(k1, k2)), ("even", det_even, slice(k2, None))):
            if det.size:
                Yd = Yp[:, where]  # (P, lines, q, ne)
                mean = Yd.mean(axis=0)
                noise = np.sum(np.abs(Yd - mean) ** 2, axis=0) / (Yd.shape[0] - 1) / Yd.shape[0]
                detection[kind] = (np.mean(np.abs(mean) ** 2, axis=2), np.mean(noise, axis=2))
        return G, var, Uinv, Yp[:, :k1].mean(axis=0), detection

    def _lpm_lines(self, recs: Sequence[ChannelRecord]) -> tuple:
        """As :meth:`_period_lines`, from the whole records' DFT with the transient removed by the LPM."""
        from .bla_lpm import transient_free_lines

        first = recs[0]
        if self._first is None:
            self._first = dataclasses.replace(first, channels=tuple(c[:0] for c in first.channels))
            inputs = np.column_stack(first.channels[: first.n_inputs])
            self._period_samples = first.n_samples // (self.periods or detect_periods(inputs))
            self._n_records, self._n_samples = len(recs), first.n_samples
        _check_like(recs, self._first, self._n_records, self._n_samples, self._period_samples)
        periods = first.n_samples // self._period_samples
        X = np.stack([np.stack([np.fft.rfft(np.asarray(c)) for c in r.channels], -1) for r in recs], -1)
        if not np.isfinite(X).all():
            for r in recs:  # name the first bad sample
                for c, x in enumerate(r.channels):
                    check_finite_batch(r, np.asarray(x)[None, :], c, 0, r.n_samples)
        if self._lines is None:
            self._lines = _infer_lines(X[::periods][: self._period_samples // 2 + 1, : first.n_inputs])
        self._kept.append(periods)
        self._dropped.append(0)
        exc, det_odd, det_even = self._lines
        Xc, var = transient_free_lines(X, np.concatenate(self._lines), periods)
        m, k1, k2 = first.n_inputs, exc.size, exc.size + det_odd.size
        U, Y = Xc[:k1, :m], Xc[:k1, m:]
        Uinv = np.linalg.pinv(U) if U.shape[1] != U.shape[2] else np.linalg.inv(U)
        G = Y @ Uinv
        # residual variance of Y - G U: the output's noise and the inputs' through G
        resid = var[:k1, m:] + np.einsum("kqm,kme->kqe", np.abs(G) ** 2, var[:k1, :m])
        var_G = np.einsum("kqe,kem->kqm", resid, np.abs(Uinv) ** 2)
        detection = {}
        for kind, where in (("odd", slice(k1, k2)), ("even", slice(k2, None))):
            Yd = Xc[where, m:]
            if Yd.shape[0]:
                detection[kind] = (np.mean(np.abs(Yd) ** 2, axis=2), np.mean(var[where, m:], axis=2))
        return G, var_G, Uinv, Y, detection

    def result(self) -> BLAResult:
        """The BLA and its levels from the realisations added so far.

        Raises
        ------
        DataError
            When no realisation was added.
        """
        if not self._count or self._first is None or self._lines is None:
            raise DataError("a best linear approximation needs at least one realisation; got none.")
        M, s, first = self._count, self._sums, self._first
        exc, det_odd, det_even = self._lines
        period = self._period_samples
        freqs = exc / (period * first.dt)
        total = np.sqrt(s["m2"] / (M - 1) / M) if M > 1 else None
        frd = FrequencyResponse(
            freqs, s["mean"], np.sqrt(s["var_n"]) / M, None, first.input_names, first.output_names, total
        )
        levels, shares = {}, {}
        for kind, det in (("odd", det_odd), ("even", det_even)):
            if not det.size:
                continue
            power, noise = s[f"{kind}_power"] / M, s[f"{kind}_noise"] / M
            floor = 1e-12 * s["y_power"] / M
            levels[kind] = DetectionLevels(kind, det / (period * first.dt), power, noise, first.output_names, floor)
            excess = np.maximum(power - noise, 0.0)  # the nonlinear part of the detection lines' power
            at_exc = np.stack([np.interp(exc, det, excess[:, i]) for i in range(excess.shape[1])], axis=1)
            shares[kind] = np.sqrt(at_exc[:, :, None] * s["uinv2"][:, None, :]) / M
        return BLAResult(
            frd,
            M,
            min(self._kept),
            max(self._dropped),
            levels.get("odd"),
            levels.get("even"),
            shares.get("odd"),
            shares.get("even"),
            self.transient,
        )

    def _period_spectra(self, recs: Sequence[ChannelRecord]) -> tuple[np.ndarray, np.ndarray]:
        """Per-period DFTs of the steady-state periods: (P, lines, channels, records) for u and y.

        Channel by channel, each period reshaped in place (a view of the record) and
        transformed; only the lines the estimate uses are kept once the design is known.
        """
        first = recs[0]
        if self._first is None:
            self._first = dataclasses.replace(first, channels=tuple(c[:0] for c in first.channels))
            self._period_samples = first.n_samples // (
                self.periods or detect_periods(np.column_stack(first.channels[: first.n_inputs]))
            )
            self._n_records, self._n_samples = len(recs), first.n_samples
        _check_like(recs, self._first, self._n_records, self._n_samples, self._period_samples)
        L = self._period_samples
        periods = first.n_samples // L
        dropped = self.transient_periods
        if dropped is None:
            dropped = max(detect_transient_periods(r.channels[r.n_inputs :], periods) for r in recs)
        kept = periods - dropped
        if kept < 2:
            raise DataError(
                f"{periods} periods minus {dropped} transient periods leaves {kept}; at least 2 are needed for the noise."
            )
        self._kept.append(kept)
        self._dropped.append(dropped)
        keep = None if self._lines is None else np.concatenate(self._lines)
        if keep is not None and keep.max() > L // 2:
            raise DataError(f"line {int(keep.max())} lies above Nyquist of a {L}-sample period.")
        blocks = _channel_spectra(recs, L, dropped, keep, self.n_threads)
        X = blocks.transpose(2, 3, 1, 0)
        if keep is None:  # the design is inferred from this first realisation's full spectrum
            self._lines = _infer_lines(X[:, :, : first.n_inputs].mean(axis=0))
            X = X[:, np.concatenate(self._lines)]
        # the lines in the order excited, odd detection, even detection
        return X[:, :, : first.n_inputs], X[:, :, first.n_inputs :]


def bla_frf(
    realisations: Experiment | Iterable[Experiment | Sequence[Experiment]],
    periods: int | None = None,
    transient_periods: int | None = None,
    excited: Sequence[int] | None = None,
    detection_odd: Sequence[int] | None = None,
    detection_even: Sequence[int] | None = None,
    transient: str = "drop",
) -> BLAResult:
    """The robust BLA from random-phase multisine realisations (see the module docstring).

    Parameters
    ----------
    realisations : Experiment or iterable
        One record per realisation (SISO, or MIMO with several inputs in one record only if
        ``n_inputs == 1``), or per realisation a sequence of records, one per experiment;
        an iterator is consumed one realisation at a time.
    periods, transient_periods, excited, detection_odd, detection_even, transient
        As in :class:`BLAAccumulator`.

    Returns
    -------
    BLAResult

    Raises
    ------
    DataError
        Records that differ in length, sample time or channels, fewer than 2 steady-state
        periods, fewer records than inputs, or realisations exciting other lines.
    """
    acc = BLAAccumulator(periods, transient_periods, excited, detection_odd, detection_even, transient)
    for realisation in [realisations] if isinstance(realisations, (Experiment, ChannelRecord)) else realisations:
        acc.add(realisation)
    return acc.result()


def _lines_of(excited, detection_odd, detection_even) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The given lines checked: increasing indices >= 1, the three sets disjoint."""
    sets = []
    for name, lines in (("excited", excited), ("detection_odd", detection_odd), ("detection_even", detection_even)):
        x = np.asarray([] if lines is None else lines, dtype=int).reshape(-1)
        if np.any(x <= 0) or np.any(np.diff(x) <= 0) or (name == "excited" and x.size == 0):
            raise DataError(f"`{name}` must be increasing line indices >= 1; got {x.tolist()[:8]}.")
        sets.append(x)
    every = np.sort(np.concatenate(sets))  # each set increases: a repeat is a line in two sets
    if np.any(every[1:] == every[:-1]):
        raise DataError("a line cannot be both excited and a detection line; got one in two of the sets.")
    return sets[0], sets[1], sets[2]


def _infer_lines(Um: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Excited lines from the input; the unexcited ones between the first and last, by parity."""
    exc = excited_lines(Um)
    unexcited = np.ones(exc[-1] - exc[0] + 1, bool)  # not np.setdiff1d: it imports numpy.ma
    unexcited[exc - exc[0]] = False
    rest = exc[0] + np.flatnonzero(unexcited)
    return exc, rest[rest % 2 == 1], rest[rest % 2 == 0]


def _channel_spectra(
    recs: Sequence[ChannelRecord], L: int, dropped: int, keep: np.ndarray | None, n_threads: int | None
) -> np.ndarray:
    """The DFT of every period after the first ``dropped`` of every record's channels, at the
    lines ``keep`` (all when None): shape (records, channels, periods, lines).

    One contiguous (periods, lines) block per record and channel (the caller's (periods, lines,
    channels, records) view of it; writing that order directly strides the cache).  The channels
    are transformed on ``n_threads`` threads: numpy's FFT and the first touch of mapped records
    run without the GIL.

    Raises
    ------
    DataError
        Naming the first non-finite sample of the first channel (in record order) that has one.
    """
    n_channels, kept = len(recs[0].channels), recs[0].n_samples // L - dropped
    blocks = np.empty((len(recs), n_channels, kept, L // 2 + 1 if keep is None else keep.size), complex)

    def periods_of(e: int, c: int) -> np.ndarray:
        return np.asarray(recs[e].channels[c][dropped * L :]).reshape(kept, L)  # a view of the record

    def transform(item: int) -> bool:
        e, c = divmod(item, n_channels)
        spectrum = np.fft.rfft(periods_of(e, c), axis=1)
        if keep is None:
            blocks[e, c] = spectrum
        else:
            np.take(spectrum, keep, axis=1, out=blocks[e, c])
        # a NaN or inf sample spreads over every line of its period's DFT: checking the kept
        # lines finds it; the samples are searched only to name the row
        return bool(np.isfinite(blocks[e, c]).all())

    finite = map_in_threads(transform, len(recs) * n_channels, n_threads)
    for item in (i for i, ok in enumerate(finite) if not ok):
        e, c = divmod(item, n_channels)  # the first bad channel in record order, as one thread finds it
        check_finite_batch(recs[e], periods_of(e, c), c, dropped * L, L)
    return blocks


def _check_like(recs: Sequence[ChannelRecord], first: ChannelRecord, n_records: int, n: int, period: int) -> None:
    """Every realisation alike: records, length (whole periods), sample time and channels."""
    if len(recs) != n_records:
        raise DataError(f"every realisation needs {n_records} record(s) like the first; got {len(recs)}.")
    if len(recs) < first.n_inputs:
        raise DataError(
            f"{first.n_inputs} inputs need at least {first.n_inputs} records per realisation; got {len(recs)}."
        )
    for e in recs:
        if e.n_samples != n or n % period:
            raise DataError(
                f"records of whole {period}-sample periods and one length are needed; got {e.n_samples} samples."
            )
        if e.input_names != first.input_names or e.output_names != first.output_names or e.dt != first.dt:
            raise DataError(
                f"every record needs inputs {first.input_names}, outputs {first.output_names} and dt {first.dt:g}; "
                f"got {e.input_names}, {e.output_names} and {e.dt:g}."
            )
