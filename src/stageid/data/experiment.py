"""The immutable experiment container: sampled inputs and outputs of one record.

Arrays are time-first, ``(n_samples, n_channels)``, always.  The container copies
what it is given and marks its own arrays read-only, so the caller's arrays are
never modified and a result can never alter the data it was fitted on.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .._errors import DataError
from .sampling import check_period, shared_period

__all__ = ["Experiment", "as_experiments", "check_same_channels", "check_samples", "MAX_ABS_SAMPLE"]


def _as_2d(name: str, values: object) -> np.ndarray:
    arr = np.array(values, dtype=float, copy=True)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise DataError(f"`{name}` must be an array of shape (n_samples, n_channels); got {arr.ndim} dimensions.")
    return arr


#: Largest sample magnitude accepted: squares and sums of products of samples (the statistics
#: every estimator forms) must stay inside float64.
MAX_ABS_SAMPLE = 1e150


def check_samples(
    values: np.ndarray,
    names: Sequence[str],
    label: str = "column",
    where: str = "",
    rows: str = "",
    max_abs: float = MAX_ABS_SAMPLE,
) -> None:
    """Raise :class:`DataError` for the first NaN, inf or sample beyond ``max_abs`` in magnitude.

    ``label`` names the column kind (``"input column"``), ``where`` prefixes the message (a file
    name) and ``rows`` follows the row number (``" (data rows counted from 0)"``).  Tables
    (files) accept any finite float64 (``max_abs=inf``); an :class:`Experiment`, the input of
    every estimator, holds :data:`MAX_ABS_SAMPLE`.
    """
    # the sum is finite when every sample is (NaN and inf propagate; an overflow only sends us
    # to the exact search): no record-sized temporaries, whose first-touch page faults cost
    # more than the check itself in a command-line run
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is an answer here, not news
        total = values.sum()
    if not np.isfinite(total):
        bad = ~np.isfinite(values)
        if bad.any():
            row, col = (int(i) for i in np.argwhere(bad)[0])
            what = "NaN" if np.isnan(values[row, col]) else "inf"
            raise DataError(
                f"{where}{label} '{names[col]}' has {what} at row {row}{rows}; every sample must be finite."
            )
    if values.size and math.isfinite(max_abs) and (values.max() > max_abs or values.min() < -max_abs):
        huge = np.abs(values) > max_abs
        row, col = (int(i) for i in np.argwhere(huge)[0])
        raise DataError(
            f"{where}{label} '{names[col]}' has {float(values[row, col]):g} at row {row}{rows}; expected magnitudes "
            f"below {max_abs:g} (products of such samples overflow): rescale the data."
        )


def _default_names(prefix: str, count: int) -> tuple[str, ...]:
    return tuple(f"{prefix}{i + 1}" for i in range(count))


@dataclass(frozen=True, eq=False)
class Experiment:
    """One sampled input/output record.

    Parameters
    ----------
    u : array_like of shape (n_samples, n_inputs) or (n_samples,)
        Input samples (the signals you applied).
    y : array_like of shape (n_samples, n_outputs) or (n_samples,)
        Output samples (what you measured).
    dt : float
        Sample time in seconds, > 0.
    input_names, output_names : sequence of str, optional
        Channel names; default ``u1, u2, ...`` and ``y1, y2, ...``.
    input_units, output_units : sequence of str, optional
        Units of each channel (free text, e.g. ``"um"``); default empty strings.
    t0 : float
        Time of the first sample in seconds.
    name : str
        A label for plots and reports (usually the file it came from).

    Raises
    ------
    DataError
        When the arrays contain NaN/inf, have unequal lengths, ``dt`` is not positive,
        or the names do not match the number of columns.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment
    >>> exp = Experiment(u=np.zeros((100, 1)), y=np.ones((100, 2)), dt=0.002)
    >>> exp.n_samples, exp.n_inputs, exp.n_outputs
    (100, 1, 2)
    """

    u: np.ndarray
    y: np.ndarray
    dt: float
    input_names: tuple[str, ...] = ()
    output_names: tuple[str, ...] = ()
    input_units: tuple[str, ...] = ()
    output_units: tuple[str, ...] = ()
    t0: float = 0.0
    name: str = ""

    def __post_init__(self) -> None:
        u = _as_2d("u", self.u)
        y = _as_2d("y", self.y)
        if u.shape[0] != y.shape[0]:
            raise DataError(
                f"inputs and outputs must have the same number of samples; got {u.shape[0]} input rows and {y.shape[0]} output rows."
            )
        dt = check_period(self.dt, "dt")
        in_names = tuple(str(n) for n in self.input_names) or _default_names("u", u.shape[1])
        out_names = tuple(str(n) for n in self.output_names) or _default_names("y", y.shape[1])
        if len(in_names) != u.shape[1]:
            raise DataError(
                f"`input_names` must have {u.shape[1]} entries (one per input column); got {len(in_names)}."
            )
        if len(out_names) != y.shape[1]:
            raise DataError(
                f"`output_names` must have {y.shape[1]} entries (one per output column); got {len(out_names)}."
            )
        in_units = tuple(str(s) for s in self.input_units) or ("",) * u.shape[1]
        out_units = tuple(str(s) for s in self.output_units) or ("",) * y.shape[1]
        if len(in_units) != u.shape[1] or len(out_units) != y.shape[1]:
            raise DataError(
                f"units must be given for every channel: expected {u.shape[1]} input and {y.shape[1]} output units; "
                f"got {len(in_units)} and {len(out_units)}."
            )
        check_samples(u, in_names, "input column")
        check_samples(y, out_names, "output column")
        u.setflags(write=False)
        y.setflags(write=False)
        set_ = object.__setattr__
        set_(self, "u", u)
        set_(self, "y", y)
        set_(self, "dt", dt)
        set_(self, "input_names", in_names)
        set_(self, "output_names", out_names)
        set_(self, "input_units", in_units)
        set_(self, "output_units", out_units)
        set_(self, "t0", float(self.t0))
        set_(self, "name", str(self.name))

    # ------------------------------------------------------------------ shape
    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.u.shape[0])

    @property
    def n_inputs(self) -> int:
        """Number of input channels."""
        return int(self.u.shape[1])

    @property
    def n_outputs(self) -> int:
        """Number of output channels."""
        return int(self.y.shape[1])

    @property
    def time(self) -> np.ndarray:
        """Sample times in seconds, ndarray of shape (n_samples,)."""
        return self.t0 + self.dt * np.arange(self.n_samples)

    @property
    def duration(self) -> float:
        """``n_samples * dt`` in seconds."""
        return self.n_samples * self.dt

    # ------------------------------------------------------------ derivation
    def with_(self, **changes: object) -> Experiment:
        """Return a copy with some fields replaced (the copy is validated again)."""
        return replace(self, **changes)

    def slice(self, start: int = 0, stop: int | None = None) -> Experiment:
        """Return samples ``start:stop`` as a new experiment (``t0`` follows).

        Parameters
        ----------
        start, stop : int
            Sample indices (not times), ``0 <= start < stop <= n_samples``, as in
            ``u[start:stop]``; ``stop=None`` means the end of the record.  Any integral
            number is accepted (``2``, ``numpy.int64(2)``, ``2.0``); to cut at a time ``t``
            in seconds pass ``round((t - t0) / dt)``.

        Returns
        -------
        Experiment
            A copy holding rows ``start`` to ``stop - 1``, with ``t0 + start * dt``.

        Raises
        ------
        DataError
            When an index is not an integral number (e.g. ``1.5`` or ``"2"``), or the
            indices are reversed, empty or outside the record.

        Examples
        --------
        >>> import numpy as np
        >>> exp = Experiment(u=np.arange(10.0), y=np.arange(10.0), dt=0.5)
        >>> part = exp.slice(2.0, 6)
        >>> part.n_samples, part.t0
        (4, 1.0)
        """
        i0 = _sample_index("start", start, self.n_samples)
        i1 = self.n_samples if stop is None else _sample_index("stop", stop, self.n_samples)
        if not (0 <= i0 < i1 <= self.n_samples):
            raise DataError(
                f"slice must satisfy 0 <= start < stop <= {self.n_samples}; got start={start!r}, stop={stop!r}."
            )
        return replace(self, u=self.u[i0:i1], y=self.y[i0:i1], t0=self.t0 + i0 * self.dt)

    def select(self, inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None) -> Experiment:
        """Keep only the named channels, in the order given."""
        in_idx = _indices("input", self.input_names, inputs)
        out_idx = _indices("output", self.output_names, outputs)
        return replace(
            self,
            u=self.u[:, in_idx],
            y=self.y[:, out_idx],
            input_names=tuple(self.input_names[i] for i in in_idx),
            output_names=tuple(self.output_names[i] for i in out_idx),
            input_units=tuple(self.input_units[i] for i in in_idx),
            output_units=tuple(self.output_units[i] for i in out_idx),
        )

    def require_samples(self, n_needed: int, purpose: str) -> None:
        """Raise :class:`DataError` unless the record has at least ``n_needed`` samples."""
        if self.n_samples < n_needed:
            raise DataError(
                f"{purpose} needs at least {n_needed} samples; experiment '{self.name or 'unnamed'}' has {self.n_samples}."
            )

    def __repr__(self) -> str:
        return (
            f"Experiment(name={self.name!r}, n_samples={self.n_samples}, dt={self.dt:g}, "
            f"inputs={list(self.input_names)}, outputs={list(self.output_names)})"
        )


def _sample_index(param: str, value: object, n_samples: int) -> int:
    """``value`` as an int sample index, or DataError unless it is an integral real number."""
    if not isinstance(value, bool) and isinstance(value, numbers.Integral):
        return int(value)
    hint = ""
    if not isinstance(value, bool) and isinstance(value, numbers.Real):
        if float(value).is_integer():
            return int(value)
        if np.isfinite(float(value)):
            hint = " (indices count samples; for a time t in seconds pass round((t - t0) / dt))"
    raise DataError(
        f"`{param}` of Experiment.slice must be an integer sample index in 0..{n_samples}; got {value!r}{hint}."
    )


def _indices(kind: str, names: tuple[str, ...], wanted: Sequence[str] | None) -> list[int]:
    if wanted is None:
        return list(range(len(names)))
    out = []
    for w in wanted:
        if w not in names:
            raise DataError(f"unknown {kind} column '{w}'; expected one of {', '.join(names)}.")
        out.append(names.index(w))
    return out


def as_experiments(data: Experiment | Sequence[Experiment]) -> tuple[Experiment, ...]:
    """Normalise one experiment or a sequence of them into a checked tuple.

    All experiments must share the sample time (to ``PERIOD_RTOL``, :mod:`stageid.data.sampling`;
    those that differ by rounding are given the first one's) and the channel names;
    identification methods use this to accept several records (e.g. one per excited input).
    """
    exps = (data,) if isinstance(data, Experiment) else tuple(data)
    if not exps:
        raise DataError("at least one experiment is required; got none.")
    for e in exps:
        if not isinstance(e, Experiment):
            raise DataError(f"expected Experiment objects; got {type(e).__name__}.")
    dt = shared_period([e.dt for e in exps], [e.name or f"record {i}" for i, e in enumerate(exps)], "experiments")
    exps = tuple(e if e.dt == dt else replace(e, dt=dt) for e in exps)
    check_same_channels(exps, "names", "have the same channels")
    return exps


def check_same_channels(exps: Sequence[Experiment], field: str, rule: str) -> None:
    """Raise DataError unless every experiment's ``input_<field>`` and ``output_<field>`` equal the first one's.

    ``field`` is ``"names"`` or ``"units"``; ``rule`` ends the message ("all experiments must <rule>").
    """
    first = exps[0]
    want = (getattr(first, f"input_{field}"), getattr(first, f"output_{field}"))
    for e in exps[1:]:
        got = (getattr(e, f"input_{field}"), getattr(e, f"output_{field}"))
        if got != want:
            raise DataError(
                f"all experiments must {rule}; got inputs {list(want[0])} / outputs {list(want[1])} "
                f"and inputs {list(got[0])} / outputs {list(got[1])}."
            )
