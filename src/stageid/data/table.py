"""The :class:`Table`: named float columns on a uniform time grid, as read from a file.

Every reader in :mod:`stageid.data.io` ends in :func:`assemble_table`; the rules it keeps
(names, finite samples, the time column ``t``) are :mod:`.columns`, re-exported here.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import DataError, NoSampleTimeError
from ..checks import shown
from . import columns
from .columns import *  # noqa: F403 - the readers' shared rules, re-exported where they were
from .columns import TIME_COLUMN, check_finite, check_unique_names, file_prefix, time_column_grid
from .experiment import Experiment
from .sampling import check_period

__all__ = ["Table", "assemble_table", *columns.__all__]


@dataclass(frozen=True, eq=False)
class Table:
    """Named float columns sampled on a uniform time grid (what a file reader returns).

    Parameters
    ----------
    names : sequence of str
        Column names, unique, non-empty, without surrounding whitespace.  The name ``t``
        is reserved for the time axis (use ``dt``/``t0``).
    values : array_like of shape (n_samples, n_columns)
        Finite samples, time first.  Copied and made read-only.
    dt : float or None
        Sample time in seconds, > 0; ``None`` when unknown (such a table can be written
        but not turned into an :class:`Experiment`).
    t0 : float
        Time of the first sample in seconds.
    units : sequence of str, optional
        One unit string per column (``""`` = unknown); default all empty.
    source : str
        Where the table came from (the file name for tables read from disk).
    jitter : float
        Largest deviation of the file's time stamps from the uniform grid beyond their rounding,
        as a fraction of ``dt`` (0 without a time column); see :mod:`stageid.data.sampling`.

    Raises
    ------
    DataError
        Duplicate/empty/reserved names, a name count that does not match the columns,
        no samples, NaN/inf values, or a non-positive ``dt``.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Table
    >>> table = Table(["V", "y"], np.ones((4, 2)), dt=0.001, units=["V", "um"])
    >>> exp = table.experiment(inputs=["V"], outputs=["y"])
    >>> exp.n_samples, exp.input_names, exp.output_units
    (4, ('V',), ('um',))
    """

    names: tuple[str, ...]
    values: np.ndarray
    dt: float | None = None
    t0: float = 0.0
    units: tuple[str, ...] = ()
    source: str = ""
    jitter: float = 0.0

    def __post_init__(self) -> None:
        where = file_prefix(str(self.source))
        names = tuple(self.names) if not isinstance(self.names, str) else (self.names,)
        for i, n in enumerate(names):
            if not isinstance(n, str) or not n or n != n.strip() or "\n" in n or "\r" in n:
                raise DataError(
                    f"{where}column {i} must have a non-empty name without surrounding whitespace or newlines; got {n!r}."
                )
        if not names:
            raise DataError(f"{where}a table needs at least one named column; got none.")
        check_unique_names(names, where)
        if TIME_COLUMN in names:
            raise DataError(
                f"{where}the column name '{TIME_COLUMN}' is reserved for the time axis; pass dt and t0 instead."
            )
        try:
            values = np.array(self.values, dtype=float, copy=True)
        except (TypeError, ValueError) as exc:
            raise DataError(f"{where}`values` must be numeric; got {type(self.values).__name__} ({exc}).") from None
        if values.ndim == 1 and len(names) == 1:
            values = values[:, None]
        if values.ndim != 2 or values.shape[1] != len(names):
            raise DataError(
                f"{where}`values` must have shape (n_samples, {len(names)}) (one column per name); got {values.shape}."
            )
        if values.shape[0] == 0:
            raise DataError(f"{where}the table has no data rows; expected at least one sample.")
        check_finite(values, names, where)
        dt = self.dt
        if dt is not None:
            dt = check_period(dt, "dt", where)
        try:
            t0 = float(self.t0)
        except (TypeError, ValueError):
            raise DataError(f"{where}`t0` must be a finite number of seconds; got {self.t0!r}.") from None
        if not math.isfinite(t0):
            raise DataError(f"{where}`t0` must be a finite number of seconds; got {self.t0!r}.")
        units = tuple(str(u) for u in self.units) or ("",) * len(names)
        if len(units) != len(names):
            raise DataError(f"{where}`units` must have {len(names)} entries (one per column); got {len(units)}.")
        values.setflags(write=False)
        set_ = object.__setattr__
        set_(self, "names", names)
        set_(self, "values", values)
        set_(self, "dt", dt)
        set_(self, "t0", t0)
        set_(self, "units", units)
        set_(self, "source", str(self.source))

    @property
    def n_samples(self) -> int:
        """Number of samples (rows)."""
        return int(self.values.shape[0])

    @property
    def n_columns(self) -> int:
        """Number of data columns (the time axis is not a column)."""
        return int(self.values.shape[1])

    @property
    def time(self) -> np.ndarray:
        """Sample times ``t0 + dt * k`` in seconds, ndarray of shape (n_samples,).

        Raises
        ------
        DataError
            When the sample time is unknown (``dt is None``).
        """
        return self.t0 + self._require_dt("the time axis") * np.arange(self.n_samples)

    def column(self, name: str) -> np.ndarray:
        """Return one column as a read-only ndarray of shape (n_samples,).

        Raises
        ------
        DataError
            ``"unknown column 'X'; expected one of a, b, c"`` when ``name`` is not a column.
        """
        return self.values[:, self._index(name)]

    def experiment(
        self,
        inputs: Sequence[str] | str,
        outputs: Sequence[str] | str,
        name: str | None = None,
    ) -> Experiment:
        """Build an :class:`Experiment` from named input and output columns.

        Parameters
        ----------
        inputs, outputs : sequence of str (or one str)
            Column names, in the order wanted; each list non-empty, no column in both.
        name : str, optional
            Experiment label; default the table's ``source``.

        Returns
        -------
        Experiment
            ``u`` of shape (n_samples, len(inputs)), ``y`` of shape (n_samples, len(outputs)),
            with the table's ``dt``, ``t0`` and units.

        Raises
        ------
        DataError
            Unknown column (``"unknown column 'X'; expected one of a, b, c"``), an empty
            list, a column used twice, or an unknown sample time.

        Examples
        --------
        >>> import numpy as np
        >>> from stageid.data import Table
        >>> t = Table(["u", "y1", "y2"], np.zeros((10, 3)), dt=0.5)
        >>> t.experiment(inputs=["u"], outputs=["y2", "y1"]).output_names
        ('y2', 'y1')
        """
        ins = (inputs,) if isinstance(inputs, str) else tuple(inputs)
        outs = (outputs,) if isinstance(outputs, str) else tuple(outputs)
        for kind, chosen in (("inputs", ins), ("outputs", outs)):
            if not chosen:
                raise DataError(f"{kind} must name at least one column; expected some of {', '.join(self.names)}.")
        in_idx = [self._index(n) for n in ins]
        out_idx = [self._index(n) for n in outs]
        seen: dict[str, str] = {}
        for kind, chosen in (("input", ins), ("output", outs)):
            for n in chosen:
                if n in seen:
                    raise DataError(f"column '{n}' is listed twice (as {seen[n]} and as {kind}); use each column once.")
                seen[n] = kind
        dt = self._require_dt("an Experiment")
        return Experiment(
            u=self.values[:, in_idx],
            y=self.values[:, out_idx],
            dt=dt,
            input_names=ins,
            output_names=outs,
            input_units=tuple(self.units[i] for i in in_idx),
            output_units=tuple(self.units[i] for i in out_idx),
            t0=self.t0,
            name=self.source if name is None else name,
        )

    def between(self, start: float | None = None, stop: float | None = None) -> Table:
        """The samples with ``start <= t <= stop`` (seconds on the table's time axis), t0 moved.

        A stamp within 1e-6 of a period of a bound counts as on it.  ``None`` leaves that
        side open.  The table itself is unchanged.

        Raises
        ------
        DataError
            ``start >= stop``, an unknown sample time, or a window that keeps fewer than 2
            samples (naming the record's time span).

        Examples
        --------
        >>> import numpy as np
        >>> from stageid.data import Table
        >>> part = Table(["u"], np.arange(10.0), dt=0.5, t0=1.0).between(2.0, 3.0)
        >>> part.t0, part.column("u").tolist()
        (2.0, [2.0, 3.0, 4.0])
        """
        where = file_prefix(self.source)
        if start is not None and stop is not None and not start < stop:
            raise DataError(f"{where}`start={start:g}` s must be before `stop={stop:g}` s.")
        dt = self._require_dt("`start=`/`stop=`")
        n = self.n_samples
        first = 0 if start is None else max(0, math.ceil((start - self.t0) / dt - 1e-6))
        last = n - 1 if stop is None else min(n - 1, math.floor((stop - self.t0) / dt + 1e-6))
        if last - first + 1 < 2:
            span = f"{self.t0:g} s to {self.t0 + (n - 1) * dt:g} s"
            window = f"[{'start' if start is None else f'{start:g} s'}, {'end' if stop is None else f'{stop:g} s'}]"
            raise DataError(
                f"{where}`start=`/`stop=` window {window} keeps {max(last - first + 1, 0)} samples of the record "
                f"({span}); expected at least 2."
            )
        return dataclasses.replace(self, values=self.values[first : last + 1], t0=self.t0 + first * dt)

    @classmethod
    def from_experiment(cls, exp: Experiment) -> Table:
        """The table of an experiment's columns: inputs first, then outputs.

        Raises
        ------
        DataError
            When an input and an output share a name (a table needs unique names).
        """
        return cls(
            names=exp.input_names + exp.output_names,
            values=np.hstack([exp.u, exp.y]),
            dt=exp.dt,
            t0=exp.t0,
            units=exp.input_units + exp.output_units,
            source=exp.name,
        )

    def _index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            listed = ", ".join(n if len(n) <= 40 else shown(n, 40) for n in self.names[:50])
            more = f" and {len(self.names) - 50} more" if len(self.names) > 50 else ""
            raise DataError(
                f"{file_prefix(self.source)}unknown column {shown(name)}; expected one of {listed}{more}"
            ) from None

    def _require_dt(self, purpose: str) -> float:
        if self.dt is None:
            raise DataError(
                f"{file_prefix(self.source)}the sample time is unknown; {purpose} needs dt (pass `ts=` when reading)."
            )
        return self.dt

    def __repr__(self) -> str:
        dt = "None" if self.dt is None else f"{self.dt:g}"
        return f"Table(source={self.source!r}, n_samples={self.n_samples}, dt={dt}, columns={list(self.names)})"


def assemble_table(
    source: str,
    names: Sequence[str],
    values: np.ndarray,
    units: Sequence[str],
    ts: float | None,
    time_rtol: float,
) -> Table:
    """Validate columns (names, finiteness, time axis) and build the Table."""
    where = file_prefix(source)
    check_unique_names(names, where)
    if values.shape[0] == 0:
        raise DataError(f"{where}no data rows; expected at least one sample.")
    check_finite(values, names, where)
    names = list(names)
    units = list(units)
    if TIME_COLUMN in names:
        i = names.index(TIME_COLUMN)
        if units[i] not in ("", "s"):
            raise DataError(f"{where}the time column '{TIME_COLUMN}' must be in seconds; got unit '{units[i]}'.")
        grid = time_column_grid(values[:, i], where, ts, time_rtol)
        t0, dt, jitter = grid.t0, grid.dt, grid.jitter
        keep = [j for j in range(len(names)) if j != i]
        values = values[:, keep]
        names = [names[j] for j in keep]
        units = [units[j] for j in keep]
    else:
        if ts is None:
            raise NoSampleTimeError(f"{where}no time column '{TIME_COLUMN}'; pass `ts=` (the sample time in seconds).")
        t0, dt, jitter = 0.0, check_period(ts, "ts", where), 0.0
    if not names:
        raise DataError(f"{where}only a time column '{TIME_COLUMN}' was found; expected at least one data column.")
    return Table(names=tuple(names), values=values, dt=dt, t0=t0, units=tuple(units), source=source, jitter=jitter)
