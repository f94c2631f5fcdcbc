"""The records of a fit: checks, mean removal, unit-RMS scaling and the excited band.

``HankelMAP`` works on fresh copies of the records' channels, mean-removed (``detrend``) and
divided by their RMS over all records (:func:`channel_scales`), so that thresholds, floors, the
default prior and the flat prior's minimum-norm solution do not depend on the units of the
data; the identified model and posterior are scaled back (:func:`unscaled_posterior`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import DataError
from ..checks import check_freqs  # re-exported: result.py checks its frequencies with it
from ..data.experiment import Experiment, as_experiments
from ..data.sampling import PERIOD_RTOL, same_period, seconds
from ..models.statespace import StateSpaceModel
from .map.posterior import Posterior, regressor_scales
from .statistics.hankel_toeplitz import WindowStatistics

__all__ = [
    "as_records",
    "check_continuation",
    "prepared_records",
    "still_inputs",
    "note_still_inputs",
    "channel_scales",
    "to_unit_rms",
    "unscaled_posterior",
    "excited_band",
    "excited_lines",
    "check_freqs",
]


def as_records(data: object, where: str) -> tuple[Experiment, ...]:
    """``as_experiments`` with a one-line DataError for anything that is not records."""
    if not isinstance(data, (Experiment, list, tuple)):
        raise DataError(f"{where} needs an Experiment or a sequence of them; got {type(data).__name__}.")
    return as_experiments(data)


def check_continuation(model: StateSpaceModel, first: Experiment) -> None:
    """New records continuing a fit of ``model`` need its channels and its sample time (DataError)."""
    if model.inputs != first.input_names or model.outputs != first.output_names:
        raise DataError(
            f"new data must have inputs {list(model.inputs)} and outputs "
            f"{list(model.outputs)}; got {list(first.input_names)} and {list(first.output_names)}."
        )
    if not same_period(first.dt, model.dt):
        raise DataError(
            f"new data must have the sample time of the fitted model, {seconds(model.dt)} s; got {seconds(first.dt)} s "
            f"(tolerance {PERIOD_RTOL:g} relative)."
        )


def _minus_column_means(x: np.ndarray) -> np.ndarray:
    """``x - x.mean(axis=0)`` as a new array, column by column: a strided pass per column is
    faster here than numpy's axis-0 reduction and row broadcasting over a few-column array."""
    out = np.empty_like(x)
    for j in range(x.shape[1]):
        col = x[:, j]
        np.subtract(col, col.mean(), out=out[:, j])
    return out


def prepared_records(exps: Sequence[Experiment], detrend: bool) -> list[tuple[np.ndarray, np.ndarray]]:
    """Fresh float copies ``(u, y)`` of the records' channels, mean-removed when ``detrend``.

    Raises
    ------
    DataError
        When a record has fewer than 2 samples.
    """
    empty = [e.n_samples for e in exps if e.n_samples < 2]
    if empty:
        raise DataError(f"every record needs at least 2 samples; got {min(empty)}.")
    out = []
    for e in exps:
        u = np.asarray(e.u, dtype=float)
        y = np.asarray(e.y, dtype=float)
        if detrend:  # one new array each: the subtraction is the copy
            out.append((_minus_column_means(u), _minus_column_means(y)))
        else:
            out.append((u.copy(), y.copy()))
    return out


def still_inputs(
    records: Sequence[tuple[np.ndarray, np.ndarray]], names: Sequence[str], notes: list[str]
) -> list[bool]:
    """Which inputs never move in any record (a note for each); DataError when none moves."""
    # column by column: numpy reduces a (n, 3) array along axis 0 much slower
    still = [all(np.ptp(r[0][:, j]) == 0 for r in records) for j in range(len(names))]
    note_still_inputs(still, names, len(records), notes)
    return still


def note_still_inputs(still: Sequence[bool], names: Sequence[str], n_records: int, notes: list[str]) -> None:
    """A note for every input that does not move in any of ``n_records`` records; DataError when none moves."""
    if all(still):
        raise DataError(
            f"at least one input must move in some record; got every input ({', '.join(names)}) "
            f"constant in all {n_records} record(s)."
        )
    for name, is_still in zip(names, still):
        if is_still:
            notes.append(f"input '{name}' does not move in any record; its response cannot be identified.")


def channel_scales(records: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """RMS of every input and output channel over all records (1 for a channel that is zero)."""
    n = sum(u.shape[0] for u, _ in records)
    su = np.sqrt(sum(np.einsum("ij,ij->j", u, u) for u, _ in records) / n)  # no squared copy
    sy = np.sqrt(sum(np.einsum("ij,ij->j", y, y) for _, y in records) / n)
    ok_u = np.isfinite(su) & (su > 0)
    ok_y = np.isfinite(sy) & (sy > 0)
    return np.where(ok_u, su, 1.0), np.where(ok_y, sy, 1.0)


def to_unit_rms(
    records: Sequence[tuple[np.ndarray, np.ndarray]], scales: tuple[np.ndarray | None, np.ndarray | None] | None
) -> tuple[np.ndarray, np.ndarray]:
    """Divide every channel of the (fresh, see :func:`prepared_records`) records in place by its
    RMS over all records, or by the given ``(input, output)`` scales of an earlier fit; return them."""
    if scales is not None and scales[0] is not None and scales[1] is not None:
        su, sy = scales
    else:
        su, sy = channel_scales(records)
    for u, y in records:
        for x, scale in ((u, su), (y, sy)):
            for j in range(x.shape[1]):  # column by column: see _minus_column_means
                x[:, j] /= scale[j]
    return su, sy


def unscaled_posterior(post: Posterior, su: np.ndarray, sy: np.ndarray) -> Posterior:
    """The posterior of a fit on scaled channels, in the data's units (``theta = ys theta_s / xs``)."""
    xs, ys = regressor_scales(post.horizon, su, sy)
    XX_ = np.outer(xs, xs)
    YX_ = np.outer(ys, xs)
    YY_ = np.outer(ys, ys)
    sums = tuple(a * f for a, f in zip(post.data_sums, (XX_, YX_, YY_)))
    return Posterior(
        post.information * XX_,
        post.moment * YX_,
        post.theta * (ys[:, None] / xs[None, :]),
        post.noise_cov * YY_,
        post.n_windows,
        post.horizon,
        post.n_inputs,
        post.n_outputs,
        post.residual * YY_,
        sums,
    )


def _excited(P: np.ndarray) -> np.ndarray:
    """Bins with at least 1 % of some input's peak bin power."""
    return np.max(P / np.maximum(P.max(axis=0, keepdims=True), 1e-300), axis=1) >= 1e-2


def excited_band(
    stats: WindowStatistics, dt: float, band: tuple[float, float] | None, notes: list[str]
) -> tuple[float, float]:
    """The band of the frequency route in Hz: ``band`` (capped at Nyquist), else the excited
    bins (1/(1024 dt) wide, >= 1 % of an input's peak bin power) widened by half a bin."""
    nyq = 0.5 / dt
    if band is not None:
        return float(band[0]), min(float(band[1]), nyq)
    P, f = stats.input_power, stats.freqs
    if P is None:
        return 0.0, nyq
    exc = _excited(P)
    if not exc.any():
        return 0.0, nyq
    half = 0.5 / (2 * len(f))  # half a bin, in cycles per sample
    lo = max(0.0, float(f[exc].min() - half)) / dt
    hi = min(0.5, float(f[exc].max() + half)) / dt
    if exc.sum() < 3:
        notes.append("the inputs excite a very narrow band; the model is only valid there.")
    return lo, hi


def excited_lines(stats: WindowStatistics) -> int:
    """Number of excited bins (as in :func:`excited_band`); very many without a spectrum."""
    P = stats.input_power
    if P is None:
        return 10**6
    return int(np.sum(_excited(P)))
