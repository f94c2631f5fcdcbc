"""Records, starting states and per-record errors of the hysteresis identification (step 4).

A fit reads its data once, in ``fit(data)``, into :class:`Records` (:func:`read_records`:
the checked ``(u, y)`` pairs, the channel names, each record's clock) and hands those down;
a fit inside another (the stage's hysteresis, :meth:`PIIdentifier.fit_records`) takes them
as they are.

The letter starts every record from the zero state (``x0 = z0 = 0``, eq. 3); measured records
may instead start after an idle period at one end of the range.  :func:`choose_initial_states`
picks, per record, the kind with the least residual unless the record starts at rest;
:func:`align_record` does the same for a record the model was not fitted to.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..._errors import DataError, IdentificationError, ModelError
from ...data import Experiment
from ...data.sampling import PERIOD_RTOL, check_period, same_period, seconds, shared_period
from ...validation.edges import EdgeError, edge_errors
from ..models.pi import STATE_KINDS, ModifiedPIModel, PIModel
from .weights import WeightProblem

__all__ = [
    "STATE_CHOICES",
    "Records",
    "read_records",
    "record_items",
    "sampling_period",
    "with_former_channels",
    "choose_initial_states",
    "record_errors",
    "record_residuals",
    "error_percents",
    "replace_offset",
    "align_record",
]

STATE_CHOICES = ("auto",) + STATE_KINDS


@dataclass(frozen=True)
class Records:
    """Single-input single-output records as every hysteresis fit reads them (once, in ``fit``).

    :func:`read_records` makes them from what ``fit(data)`` accepts; the steps of a fit and
    the fits inside another (the stage's hysteresis) take them as they are.

    Attributes
    ----------
    pairs : tuple of (u, y)
        Float arrays of shape (n_samples,), C-contiguous, one pair per record.
    input_name, output_name : str
        The channel names the model gets.
    periods : tuple of float or None
        Each record's sampling period (an Experiment's ``dt``; None for a (u, y) pair).
    starts : tuple of float
        Each record's first time (an Experiment's ``t0``; 0 for a pair).
    labels : tuple of str
        Each record's name as the sample-time messages give it (an Experiment's name, else
        "record k").
    """

    pairs: tuple[tuple[np.ndarray, np.ndarray], ...]
    input_name: str
    output_name: str
    periods: tuple[float | None, ...]
    starts: tuple[float, ...]
    labels: tuple[str, ...]

    @property
    def recs(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The ``(u, y)`` pairs as a list (the form the fitting steps index)."""
        return list(self.pairs)

    def with_outputs(self, outputs: Sequence[np.ndarray]) -> Records:
        """The same records with other outputs (derived from these, so not checked again)."""
        pairs = tuple((u, np.ascontiguousarray(y, dtype=float)) for (u, _), y in zip(self.pairs, outputs))
        return replace(self, pairs=pairs)

    def sample_time(self, sample_time: float | None) -> float | None:
        """The one sampling period of the records (Experiment.dt, else ``sample_time``), by the
        sample-time rule (:mod:`stageid.data.sampling`: periods that differ by rounding are one).

        None when (u, y) records come without ``sample_time`` (the caller says what is missing);
        DataError when the records' periods differ or are out of range, IdentificationError when
        ``sample_time`` contradicts them.
        """
        named = [(d, name) for d, name in zip(self.periods, self.labels) if d is not None]
        if len(named) < len(self.pairs):
            if sample_time is None:
                return None
            named.append((check_period(sample_time, "sample_time"), "sample_time"))
        elif sample_time is not None:
            dt = shared_period([d for d, _ in named], [n for _, n in named])
            if not same_period(check_period(sample_time, "sample_time"), dt):
                raise IdentificationError(
                    f"`sample_time` {seconds(sample_time)} s differs from the records' dt {seconds(dt)} s "
                    f"(tolerance {PERIOD_RTOL:g} relative)."
                )
        return check_period(shared_period([d for d, _ in named], [n for _, n in named]), "the records' dt")

    def edges(self, residuals: list[np.ndarray]) -> tuple[tuple[int, EdgeError], ...]:
        """``(record index, edge)`` for each record whose error concentrates at an edge
        (:mod:`stageid.validation.edges`); times on each Experiment's axis, sample counts for pairs."""
        found = []
        for j, ((_, y), e) in enumerate(zip(self.pairs, residuals)):
            found += [(j, edge) for edge in edge_errors(e, float(np.ptp(y)), self.periods[j], self.starts[j])]
        return tuple(found)


def record_items(data: Any) -> list[Any]:
    """``data`` as a list of records (one Experiment or one (u, y) pair become a list of one)."""
    if isinstance(data, Experiment):
        return [data]
    if isinstance(data, tuple) and len(data) == 2 and not isinstance(data[0], Experiment):
        return [data]
    return list(data)


def read_records(data: Any, inputs: str | None = None, outputs: str | None = None) -> Records:
    """The records of ``data`` (an Experiment, a (u, y) pair, or a sequence of them), checked once.

    ``inputs`` / ``outputs`` name the channel: an Experiment with several inputs (outputs)
    gives the column of that name; one with a single column gives it under that name, as a
    pair does.  Default: the first Experiment's names, else "V" and "y".

    Raises DataError for anything but one input and one output column of at least 10 finite
    samples whose output varies, and for a channel name a record does not hold.
    """
    recs, periods, starts, labels = [], [], [], []
    in_name, out_name = inputs or "V", outputs or "y"
    for k, item in enumerate(record_items(data)):
        if isinstance(item, Experiment):
            u, y = _experiment_columns(item, k, inputs, outputs)
            if k == 0:
                in_name = inputs or item.input_names[0]
                out_name = outputs or item.output_names[0]
            periods.append(float(item.dt))
            starts.append(float(item.t0))
        else:
            u, y = _pair_columns(item, k)
            periods.append(None)
            starts.append(0.0)
        name = item.name if isinstance(item, Experiment) else None
        _check_samples(u, y, f"record {k}" + (f" ('{name}')" if name else ""))
        recs.append((np.ascontiguousarray(u, dtype=float), np.ascontiguousarray(y, dtype=float)))
        labels.append(name or f"record {k}")
    if not recs:
        raise DataError("no records given; expected at least one Experiment.")
    return Records(tuple(recs), in_name, out_name, tuple(periods), tuple(starts), tuple(labels))


def _experiment_columns(item: Experiment, k: int, inputs: str | None, outputs: str | None):
    """The input and output column of an Experiment: its only one, or the one named."""
    columns = []
    for what, names, values, wanted in (
        ("input", item.input_names, item.u, inputs),
        ("output", item.output_names, item.y, outputs),
    ):
        if len(names) == 1:
            columns.append(values[:, 0])
        elif wanted is not None and wanted in names:
            columns.append(values[:, list(names).index(wanted)])
        else:
            choice = f"`{what}s`={wanted!r} is not one of them" if wanted is not None else f"give `{what}s`"
            raise DataError(
                f"hysteresis identification needs one {what} per record; record {k} has {len(names)} "
                f"({', '.join(names)}): {choice} to name the one to use."
            )
    return columns[0], columns[1]


def _pair_columns(item: Any, k: int) -> tuple[np.ndarray, np.ndarray]:
    """A (u, y) pair as two float vectors of equal length."""
    try:
        pair = [np.asarray(item[0], dtype=float), np.asarray(item[1], dtype=float)]
    except (TypeError, ValueError, IndexError, KeyError):
        raise DataError(
            f"record {k} must be an Experiment or a (u, y) pair of numeric arrays; got {type(item).__name__}."
        ) from None
    for j, what in enumerate(("input", "output")):
        a = pair[j]
        if a.ndim > 2 or (a.ndim == 2 and a.shape[1] != 1):
            raise DataError(
                f"record {k}: one {what} column expected (shape (n_samples,) or (n_samples, 1)); got shape {a.shape}."
            )
    u, y = pair[0].reshape(-1), pair[1].reshape(-1)
    if u.shape != y.shape:
        raise DataError(f"record {k}: input and output must have equal length; got {u.size} and {y.size}.")
    return u, y


def _check_samples(u: np.ndarray, y: np.ndarray, label: str) -> None:
    if u.size < 10:
        raise DataError(f"{label} has {u.size} samples; hysteresis identification needs at least 10.")
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
        raise DataError(f"{label} has NaN or inf samples.")
    if not np.ptp(y) > 0:
        raise DataError(
            f"{label}: the output is constant ({y[0]:g}); every record's output must vary "
            "(errors are reported in % of each record's output range)."
        )


def sampling_period(data: Any, sample_time: float | None) -> float | None:
    """:meth:`Records.sample_time` of ``data`` (Records, or what :func:`read_records` reads)."""
    records = data if isinstance(data, Records) else read_records(data)
    return records.sample_time(sample_time)


def with_former_channels(fit: Callable) -> Callable:
    """``fit(data)`` that still takes the former ``fit(data, inputs, outputs)``, with a DeprecationWarning.

    The channel names are parameters of the estimator now; given to ``fit`` they are set on a
    copy of it (this estimator's settings stay as they are) and the copy fits.
    """

    @functools.wraps(fit)
    def wrapper(self: Any, data: Any, *args: Any, **kwargs: Any) -> Any:
        if len(args) > 2:
            raise TypeError(f"{type(self).__name__}.fit takes the data as one argument; got {1 + len(args)}.")
        former = dict(zip(("inputs", "outputs"), args))
        for name in ("inputs", "outputs"):
            if name in kwargs:
                if name in former:
                    raise TypeError(f"{type(self).__name__}.fit got `{name}` twice.")
                former[name] = kwargs.pop(name)
        if not former:
            return fit(self, data, **kwargs)
        warnings.warn(
            f"`{type(self).__name__}.fit(data, inputs, outputs)` is now `{type(self).__name__}(inputs=..., "
            "outputs=...).fit(data)`; the former call form will be removed.",
            DeprecationWarning,
            stacklevel=2,
        )
        est = self.clone()
        for name, value in former.items():
            if value is not None:
                setattr(est, name, value)
        return fit(est, data, **kwargs)

    return wrapper


def choose_initial_states(
    problem: WeightProblem, theta: np.ndarray, kinds: list[str], at_rest: list[bool], classical: bool
) -> list[str]:
    """Per record not at rest, the starting-state kind with the least residual (the others fixed).

    The fit is *without* creep: a lag at rest at the first sample can imitate the slowly
    released memory of an "ascending" start (``studies/hysteresis/RESULTS.md`` section 2).
    """
    kinds = list(kinds)
    for j, rest in enumerate(at_rest):
        if rest:
            continue  # starts at 0 input: the letter's x0 = z0 = 0
        best = None
        for kind in STATE_KINDS:
            trial = kinds.copy()
            trial[j] = kind
            sse = problem.solve(theta, trial, classical=classical, creep=False)[0]
            if best is None or sse < best[0]:
                best = (sse, kind)
        kinds[j] = best[1]
    return kinds


def record_errors(model: Any, recs: list, kinds: list[str], offsets: np.ndarray) -> tuple[list[float], list[float]]:
    """Max and RMS error of the model on every record (own state and offset), in % of its range."""
    return error_percents(recs, record_residuals(model, recs, kinds, offsets))


def record_residuals(model: Any, recs: list, kinds: list[str], offsets: np.ndarray) -> list[np.ndarray]:
    """Measured minus simulated output of every record (own starting state and offset)."""
    out = []
    for j, (u, y) in enumerate(recs):
        m_j = model.with_state(model.consistent_state(u[0], kinds[j]))
        m_j = replace_offset(m_j, offsets[j])
        out.append(y - m_j.simulate(u)[:, 0])
    return out


def error_percents(recs: list, residuals: list[np.ndarray]) -> tuple[list[float], list[float]]:
    """Max and RMS of each residual in % of its record's output range."""
    max_e = [float(100 * np.max(np.abs(e)) / np.ptp(y)) for (_, y), e in zip(recs, residuals)]
    rms_e = [float(100 * np.sqrt(np.mean(e**2)) / np.ptp(y)) for (_, y), e in zip(recs, residuals)]
    return max_e, rms_e


def replace_offset(model: Any, offset: float) -> Any:
    """A copy of the model with output offset ``offset``."""
    return replace(model, output_offset=float(offset))


def align_record(
    model: PIModel | ModifiedPIModel, u: object, y: object, initial_state: str = "auto", fit_offset: bool = True
) -> tuple[Any, np.ndarray]:
    """Fit a record's own output offset and starting state, then simulate the model on it.

    Records taken at other times have other sensor zeros and start from unknown hysteretic
    states; this estimates only those two nuisance quantities (the mean residual and the best
    of the starting-state kinds) -- the model's thresholds and weights are untouched.

    Parameters
    ----------
    model : PIModel or ModifiedPIModel
    u, y : array_like of shape (n_samples,) or (n_samples, 1)
    initial_state : {"auto", "zero", "ascending", "descending", "model"}
        ``"model"`` keeps the model's own state.
    fit_offset : bool, default True

    Returns
    -------
    model : the model with that record's state and offset
    y_model : ndarray of shape (n_samples, 1)

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import PIModel, align_record
    >>> m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])
    >>> u = np.array([0.0, 2.0, -1.0, 1.0])
    >>> _, yh = align_record(m, u, m.simulate(u) + 3.0)
    >>> bool(np.allclose(yh, m.simulate(u) + 3.0))
    True
    """
    uu = np.asarray(u, dtype=float).reshape(-1)
    yy = np.asarray(y, dtype=float).reshape(-1)
    if uu.shape != yy.shape:
        raise DataError(f"input and output must have equal length; got {uu.size} and {yy.size}.")
    choices = STATE_KINDS if initial_state == "auto" else (initial_state,)
    if initial_state not in STATE_CHOICES + ("model",):
        raise ModelError(
            f"`initial_state` must be one of auto, zero, ascending, descending, model; got {initial_state!r}."
        )
    best = None
    for kind in choices:
        m = model if kind == "model" else model.with_state(model.consistent_state(uu[0], kind))
        yh = m.simulate(uu)[:, 0]
        off = float(np.mean(yy - yh)) if fit_offset else 0.0
        sse = float(np.sum((yy - yh - off) ** 2))
        if best is None or sse < best[0]:
            best = (sse, replace_offset(m, m.output_offset + off), (yh + off)[:, None])
    return best[1], best[2]
