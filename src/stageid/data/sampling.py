"""The sample-time rule: one way to read a period from a time column, one way to compare periods.

Every reader, estimator and command takes its sampling period from here.

* **Range.** A period is a finite number of seconds in [:data:`MIN_PERIOD`, :data:`MAX_PERIOD`]:
  outside it the sampling rate ``1/dt`` or the products ``n dt`` and ``(2 pi f dt)^2`` the
  identifiers form overflow or vanish, and no sampled record is there (:func:`check_period`).
* **Period of a time column** (:func:`time_grid`). The least-squares slope of ``t`` against the
  sample index: rounding of the stamps (shortest repr, fixed decimals, accumulated sums, float32
  loggers, an offset start) averages out over the record instead of entering through the two
  end stamps.  Within the slope's own uncertainty, a whole-number rate ``1/round(1/dt)`` or a
  short decimal is preferred, so ``arange(n) / 10000`` has the period ``1e-4`` exactly.
* **Uniformity.** A repeat or reversal (a step <= 0) or a gap (a step beyond 1.5 periods) is
  refused with its row; otherwise every stamp must lie on the uniform grid ``t0 + k dt`` within
  :data:`UNIFORM_RTOL` of the period, or within the stamps' own rounding where that is larger.
  The largest deviation beyond that rounding is the record's *jitter* (a fraction of the period).
* **Records compared** (:func:`shared_period`, :func:`same_period`). Periods agree when they
  differ by at most :data:`PERIOD_RTOL` relative; records that agree share the first one's period.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from .._errors import DataError

__all__ = [
    "MIN_PERIOD",
    "MAX_PERIOD",
    "PERIOD_RTOL",
    "UNIFORM_RTOL",
    "JITTER_NOTE",
    "TimeGrid",
    "jitter_note",
    "check_period",
    "time_grid",
    "ends_step",
    "StampScan",
    "scan_stamps",
    "grid_from_scan",
    "same_period",
    "shared_period",
    "seconds",
]

#: Shortest accepted period [s]: 1 fs (a 1 PHz rate), far beyond any sampled record.
MIN_PERIOD = 1e-15
#: Longest accepted period [s]: about 30 000 years.
MAX_PERIOD = 1e12
#: Two periods are one when they differ by at most this fraction: rounding of the stamps leaves
#: far less (about 1e-12 for double stamps, 1e-9 for float32 ones), while two loggers' clocks
#: set to different rates differ by 1e-4 or more.
PERIOD_RTOL = 1e-6
#: Allowed deviation of a stamp from the uniform grid, as a fraction of the period (beyond the
#: stamps' own rounding): clock jitter of a real-time target; a lost sample deviates by 1.
UNIFORM_RTOL = 1e-3
#: Jitter worth a note: above the drift of double stamps accumulated sample by sample.
JITTER_NOTE = 1e-5
#: Coarsest decimal quantum of fixed-decimal stamps accepted as their rounding, as a fraction of the period.
MAX_QUANTUM = 0.05
#: A step beyond this many periods is a gap (lost samples), refused with its row.
GAP_STEPS = 1.5


def seconds(value: float) -> str:
    """A period for messages: shortest round-trip digits, so two different values print differently."""
    return repr(float(value))


def check_period(value: object, label: str = "dt", where: str = "", error: type[Exception] = DataError) -> float:
    """``value`` as a period in seconds within [MIN_PERIOD, MAX_PERIOD], else ``error`` in one line."""
    name = f"`{label}`" if label.isidentifier() else label  # a parameter's name, or words
    try:
        dt = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise error(f"{where}{name} must be a positive number of seconds; got {value!r}.") from None
    if not math.isfinite(dt) or dt <= 0:
        raise error(f"{where}{name} must be a positive number of seconds; got {value!r}.")
    if not MIN_PERIOD <= dt <= MAX_PERIOD:
        raise error(
            f"{where}{name} must be a period between {MIN_PERIOD:g} s and {MAX_PERIOD:g} s "
            f"(its rate 1/dt and the fits' arithmetic stay finite); got {dt!r} s."
        )
    return dt


@dataclasses.dataclass(frozen=True)
class TimeGrid:
    """A time column read as a uniform grid: first stamp ``t0``, period ``dt`` [s], and ``jitter``,
    the largest deviation of a stamp from the grid beyond the stamps' rounding, as a fraction of dt."""

    t0: float
    dt: float
    jitter: float = 0.0


def jitter_note(jitter: float, dt: float, where: str = "") -> str:
    """One line on a record's jitter (a fraction of ``dt``) when it exceeds :data:`JITTER_NOTE`, else ``""``."""
    if not jitter > JITTER_NOTE:
        return ""
    return (
        f"note: {where}time stamps deviate from the uniform {seconds(dt)} s grid by up to "
        f"{jitter:.3g} of the period (accepted up to {UNIFORM_RTOL:g} beyond their rounding)."
    )


@dataclasses.dataclass(frozen=True)
class StampScan:
    """What one pass over a time column gathers (range by range for long records): the first stamp,
    the end-to-end step ``dt_ends``, the largest deviation from that line [s], the least-squares
    slope correction's numerator ``sxy`` (sum over k of (k - kbar) * deviation), and the stamps'
    rounding [s]; ``worst_row`` is the row of the largest deviation."""

    n: int
    t_first: float
    dt_ends: float
    max_deviation: float = 0.0
    worst_row: int = 0
    sxy: float = 0.0
    resolution: float = 0.0


def time_grid(t: np.ndarray, where: str = "", rtol: float = UNIFORM_RTOL) -> TimeGrid:
    """The uniform grid of a finite time column of at least two samples (see the module notes).

    Raises
    ------
    DataError
        A period out of range, a repeat, reversal or gap (with its row), or a stamp off the grid.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data.sampling import time_grid
    >>> float((np.arange(4988) / 10000)[-1] / 4987)  # the end-to-end step is an ulp off
    9.999999999999999e-05
    >>> time_grid(np.arange(4988) / 10000).dt
    0.0001
    """
    t = np.asarray(t, dtype=float)
    scan = StampScan(int(t.shape[0]), float(t[0]), ends_step(float(t[0]), float(t[-1]), t.shape[0], where))
    return grid_from_scan(scan_stamps(t, 0, scan, where, rtol), where, rtol)


def ends_step(t_first: float, t_last: float, n: int, where: str) -> float:
    """The step from the first to the last stamp, checked to be a period in range."""
    if n < 2:
        raise DataError(f"{where}the time column 't' has a single sample, so its period is unknown.")
    span = t_last - t_first
    if not span > 0:
        raise DataError(
            f"{where}time column 't' must increase; its last stamp {t_last!r} is not after its first {t_first!r}."
        )
    return check_period(span / (n - 1), "the step of the time column 't'", where)


def scan_stamps(t: np.ndarray, k0: int, scan: StampScan, where: str, rtol: float = UNIFORM_RTOL) -> StampScan:
    """Fold the stamps ``t`` (rows ``k0 ..``; consecutive ranges overlap by one row) into ``scan``.

    Repeats, reversals and gaps are refused here with their row; the deviation from the grid is
    checked by :func:`grid_from_scan` once the whole column has been seen.
    """
    steps = np.diff(t)
    if steps.size and not (steps.min() > 0 and steps.max() <= GAP_STEPS * scan.dt_ends):  # two reductions
        # clear most columns; the refusal's row is searched for only when one fails
        _refuse_steps(t, steps, k0, scan.dt_ends, where)
    k = np.arange(k0, k0 + t.shape[0], dtype=float)
    deviation = (t - scan.t_first) - k * scan.dt_ends  # small numbers: the slope sum keeps its digits
    worst = int(np.argmax(np.abs(deviation)))
    largest = abs(float(deviation[worst]))
    kbar = (scan.n - 1) / 2.0
    first = 1 if k0 > 0 else 0  # the overlapping row was counted with the previous range
    return dataclasses.replace(
        scan,
        max_deviation=max(scan.max_deviation, largest),
        worst_row=scan.worst_row if scan.max_deviation >= largest else k0 + worst,
        sxy=scan.sxy + float(np.dot(k[first:] - kbar, deviation[first:])),
        resolution=max(scan.resolution, stamp_resolution(t, steps, scan.dt_ends, rtol)),
    )


def _refuse_steps(t: np.ndarray, steps: np.ndarray, k0: int, dt: float, where: str) -> None:
    """DataError at the first repeat or reversal (a step <= 0), else at the first gap (a step beyond
    :data:`GAP_STEPS` periods ``dt``), of stamps ``t`` whose first row is ``k0``."""
    back = np.flatnonzero(~(steps > 0))
    if back.size:
        k = int(back[0])
        raise DataError(
            f"{where}time column 't' must be strictly increasing; row {k0 + k + 1} has t={float(t[k + 1])!r} "
            f"after t={float(t[k])!r} at row {k0 + k} (data rows counted from 0)."
        )
    gaps = np.flatnonzero(steps > GAP_STEPS * dt)
    if gaps.size:
        k = int(gaps[0])
        raise DataError(
            f"{where}time column 't' has a gap at row {k0 + k + 1} (data rows counted from 0): t={float(t[k + 1])!r} "
            f"after t={float(t[k])!r}, a step of {float(steps[k]) / dt:.6g} periods of "
            f"{seconds(dt)} s; expected a uniform grid."
        )


def grid_from_scan(scan: StampScan, where: str = "", rtol: float = UNIFORM_RTOL) -> TimeGrid:
    """The grid of a scanned column: least-squares period, uniformity checked, jitter measured."""
    n = scan.n
    sxx = n * (n * n - 1.0) / 12.0  # sum over k of (k - kbar)^2
    dt = scan.dt_ends + scan.sxy / sxx
    # deviations are measured from the line through the end stamps, which rounding moves too
    rounding = 2.0 * scan.resolution
    tolerance = max(rtol * dt, rounding)
    if scan.max_deviation > tolerance:
        raise DataError(
            f"{where}time column 't' is not uniform: the stamp at row {scan.worst_row} (data rows counted from 0) "
            f"lies {scan.max_deviation / dt:.3g} periods off the uniform {seconds(dt)} s grid; expected within "
            f"{rtol:g} of the period (or the stamps' rounding; pass time_rtol= to accept more clock jitter)."
        )
    # |slope error| <= 3 max|error| / n for any stamp errors (sum |k - kbar| / sxx <= 3 / n)
    uncertainty = 3.0 * max(scan.max_deviation, scan.resolution) / max(n - 1, 1)
    dt = simplest_period(dt, uncertainty)
    jitter = max(0.0, scan.max_deviation - rounding) / dt
    return TimeGrid(scan.t_first, check_period(dt, "the period of the time column 't'", where), jitter)


def simplest_period(dt: float, uncertainty: float) -> float:
    """A whole-number rate's period, or the shortest decimal, within ``uncertainty`` of ``dt``."""
    allowed = max(uncertainty, 1e-12 * dt)  # 1e-12: the slope's own arithmetic
    rate = round(1.0 / dt)
    if rate >= 1 and abs(1.0 / rate - dt) <= allowed:
        return 1.0 / rate
    for digits in range(1, 17):
        candidate = float(f"{dt:.{digits}g}")
        if abs(candidate - dt) <= allowed:
            return candidate
    return dt


def stamp_resolution(t: np.ndarray, steps: np.ndarray, dt: float, rtol: float = UNIFORM_RTOL) -> float:
    """How far rounding alone can move a stamp of increasing ``t`` (steps ``steps``) off its grid [s].

    Double stamps: a few ulps of the largest stamp (``4 eps max|t|``; at epoch times that is
    0.24 % of a 10 kHz period).  Stamps that are all float32 values: a float32 spacing.  Stamps
    that are all multiples of a decimal quantum between ``rtol * dt`` and :data:`MAX_QUANTUM` of
    the period, with steps that differ (fixed-decimal text of a period that is not a multiple of
    it): half that quantum (a finer quantum is within the uniformity tolerance anyway; coarser
    stamps cannot tell a lost sample from rounding).
    """
    big = max(abs(float(t[0])), abs(float(t[-1])))  # the stamps increase: the largest is at an end
    out = 4.0 * float(np.finfo(float).eps) * big
    if _all_float32(t[:64]) and _all_float32(t):  # double stamps fail on the first few
        out = max(out, float(np.spacing(np.float32(big))))
    if steps.size and float(np.ptp(steps)) > 2.0 * out:
        quantum = decimal_quantum(t, big)
        if rtol * dt < quantum <= MAX_QUANTUM * dt:
            out = max(out, 0.5 * quantum)
    return out


def _all_float32(t: np.ndarray) -> bool:
    return bool(np.array_equal(t, t.astype(np.float32).astype(float)))


def decimal_quantum(t: np.ndarray, big: float) -> float:
    """The coarsest power of ten all stamps are multiples of (to double rounding); inf when none is."""
    floor = 1e3 * float(np.finfo(float).eps) * max(big, 1e-300)  # finer quanta are lost in double rounding
    head = t[:1000]  # candidates are tried on the first stamps, the one that fits them on all

    def multiples(x: np.ndarray, quantum: float) -> bool:
        scaled = x / quantum
        return bool(np.max(np.abs(scaled - np.round(scaled))) <= 1e-6)

    for digits in range(-3, 16):
        quantum = 10.0**-digits
        if quantum < floor:
            break
        if multiples(head, quantum) and multiples(t, quantum):
            return quantum
    return math.inf


def same_period(a: float, b: float) -> bool:
    """True when two periods agree to :data:`PERIOD_RTOL`."""
    return abs(a - b) <= PERIOD_RTOL * max(abs(a), abs(b))


def shared_period(periods: Sequence[float], names: Sequence[str] = (), what: str = "records") -> float:
    """The one period of several records (the first's), else DataError naming the two that differ.

    Raises
    ------
    DataError
        Two periods that differ by more than :data:`PERIOD_RTOL` relative.
    """
    if not periods:
        raise DataError(f"no {what} given; expected at least one.")
    first = float(periods[0])
    for i, dt in enumerate(periods[1:], start=1):
        if not same_period(first, float(dt)):
            a = f" ({names[0]})" if names else ""
            b = f" ({names[i]})" if names else ""
            raise DataError(
                f"all {what} must share one sample time (to a relative {PERIOD_RTOL:g}); got {seconds(first)} s{a} "
                f"and {seconds(dt)} s{b}, {abs(dt - first) / first:.3g} apart."
            )
    return first
