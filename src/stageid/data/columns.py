"""The rules every table reader keeps: column names, finite samples, the time column's grid.

Shared by the readers and writers of :mod:`stageid.data` (``csv_format``, ``npz_format``,
``mat_format``, ``datasets``) and by :class:`~stageid.data.table.Table` itself:

* **Rows are data rows counted from 0**: row 0 is the first sample.
* The column named ``t`` (seconds) is the time axis, not a data column: it must be strictly
  increasing and uniform and becomes ``Table.t0`` and ``Table.dt``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from .._errors import DataError
from .experiment import check_samples
from .sampling import PERIOD_RTOL, UNIFORM_RTOL, TimeGrid, check_period, same_period, seconds, time_grid

__all__ = [
    "TIME_COLUMN",
    "DEFAULT_TIME_RTOL",
    "file_prefix",
    "positive_seconds",
    "check_unique_names",
    "check_finite",
    "time_axis",
    "time_column_grid",
    "stack_columns",
]

TIME_COLUMN = "t"


DEFAULT_TIME_RTOL = UNIFORM_RTOL


def file_prefix(source: str) -> str:
    """``"file 'x.csv': "`` for messages about a table read from ``source``; ``""`` without one."""
    return f"file '{source}': " if source else ""


def positive_seconds(label: str, value: object, where: str = "") -> float:
    """``value`` as a sample time in seconds (:func:`~stageid.data.sampling.check_period`), else DataError."""
    return check_period(value, label, where)


def check_unique_names(names: Sequence[str], where: str) -> None:
    """Raise :class:`DataError` for the first name that occurs twice."""
    first: dict[str, int] = {}
    for i, n in enumerate(names):
        if n in first:
            raise DataError(f"{where}duplicate column name '{n}' (columns {first[n]} and {i}); names must be unique.")
        first[n] = i


def check_finite(values: np.ndarray, names: Sequence[str], where: str) -> None:
    """Raise :class:`DataError` naming the first NaN or inf of a table."""
    check_samples(values, names, "column", where, " (data rows counted from 0)", max_abs=math.inf)


def time_axis(t: np.ndarray, where: str, ts: float | None, rtol: float) -> tuple[float, float]:
    """Check a time column (finite already) and return ``(t0, dt)`` (:func:`time_column_grid`)."""
    grid = time_column_grid(t, where, ts, rtol)
    return grid.t0, grid.dt


def time_column_grid(t: np.ndarray, where: str, ts: float | None, rtol: float) -> TimeGrid:
    """The grid of a time column by the sample-time rule (:mod:`stageid.data.sampling`).

    A ``ts`` given beside the column must agree with its period (to ``PERIOD_RTOL``) and is then
    the period.
    """
    if ts is not None:
        ts = check_period(ts, "ts", where)
    if t.shape[0] < 2:
        if ts is None:
            raise DataError(
                f"{where}the time column '{TIME_COLUMN}' has a single sample, so dt is unknown; pass `ts=`."
            )
        return TimeGrid(float(t[0]), ts)
    grid = time_grid(t, where, rtol)
    if ts is None:
        return grid
    if not same_period(ts, grid.dt):
        raise DataError(
            f"{where}ts={seconds(ts)} s disagrees with the period {seconds(grid.dt)} s of the time column "
            f"'{TIME_COLUMN}' (tolerance {PERIOD_RTOL:g} relative)."
        )
    return dataclasses.replace(grid, dt=ts)


def stack_columns(names: Sequence[str], columns: Sequence[np.ndarray], where: str) -> np.ndarray:
    """Columns of one length as an (n_samples, n_columns) array, else :class:`DataError`."""
    n0 = columns[0].shape[0]
    for name, col in zip(names, columns):
        if col.shape[0] != n0:
            raise DataError(
                f"{where}columns have unequal lengths: '{names[0]}' has {n0} rows and '{name}' has {col.shape[0]}; expected one length."
            )
    return np.column_stack(columns) if n0 else np.empty((0, len(columns)))
