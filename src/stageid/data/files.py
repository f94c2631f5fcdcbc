"""What the file formats of :mod:`stageid.data` share: opening and sniffing a file, the time
arguments of the readers, array-to-column rules, and the checks on tables before writing.

The formats themselves live in :mod:`~stageid.data.csv_format`, :mod:`~stageid.data.npz_format`
and :mod:`~stageid.data.mat_format`; :mod:`stageid.data.io` is the front door.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Union

import numpy as np

from .._errors import DataError
from ..atomic import note_input
from ..checks import shown
from .columns import DEFAULT_TIME_RTOL, TIME_COLUMN, check_finite, positive_seconds, stack_columns, time_axis
from .experiment import Experiment
from .table import Table

if TYPE_CHECKING:  # pragma: no cover
    from numpy.typing import ArrayLike

__all__ = [
    "PathLike",
    "HDF5_SIGNATURE",
    "ZIP_SIGNATURES",
    "open_checked",
    "looks_like",
    "is_dunder",
    "resolve_ts",
    "array_columns",
    "table_for_writing",
    "NAME_SEPARATOR",
    "SNIFF_BYTES",
]

PathLike = Union[str, "os.PathLike[str]"]
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
ZIP_SIGNATURES = (b"PK\x03\x04", b"PK\x05\x06")
SNIFF_BYTES = 65536
#: Column lists on the command line (``--inputs a,b``) are split at commas, so no written
#: column name may hold one: every column written can be selected again.
NAME_SEPARATOR = ","


def open_checked(path: PathLike) -> tuple[Path, bytes]:
    """Check that ``path`` is a readable, non-empty file; return it and its first bytes.

    The file is registered as an input of the current job (:func:`stageid.atomic.note_input`),
    so no output of the job may overwrite it.
    """
    p = Path(path)
    if not p.exists():
        raise DataError(f"file '{p}' does not exist.")
    if not p.is_file():
        raise DataError(f"'{p}' is not a file.")
    note_input(p)
    try:
        with open(p, "rb") as fh:
            head = fh.read(SNIFF_BYTES)
    except OSError as exc:
        raise DataError(f"file '{p}' cannot be read: {exc.strerror or exc}.") from None
    if not head:
        raise DataError(f"file '{p.name}' is empty; expected a header row and data rows.")
    return p, head


def is_dunder(name: str) -> bool:
    """``__name__`` keys are metadata (``__header__`` in .mat, ``__units__`` in .npz), not columns."""
    return len(name) > 4 and name.startswith("__") and name.endswith("__")


def looks_like(head: bytes) -> str:
    """`` (it looks like ...)`` naming the format the first bytes suggest, for messages; else ``""``."""
    if head.startswith(ZIP_SIGNATURES):
        return " (it looks like a zip/.npz archive)"
    if head.startswith(b"\x93NUMPY"):
        return " (it looks like a NumPy .npy array)"
    if head.startswith(b"MATLAB") or head[512:520] == HDF5_SIGNATURE or head.startswith(HDF5_SIGNATURE):
        return " (it looks like a MATLAB/HDF5 file)"
    return ""


def resolve_ts(ts: float | None, time_rtol: float, where: str) -> float | None:
    """Check the ``ts`` and ``time_rtol`` arguments of the readers."""
    if not isinstance(time_rtol, (int, float)) or not 0.0 <= time_rtol < 1.0:
        raise DataError(f"`time_rtol` must be a number in [0, 1); got {shown(time_rtol)}.")
    return None if ts is None else positive_seconds("ts", ts, where)


def array_columns(key: str, arr: np.ndarray, where: str, kind: str) -> list[tuple[str, np.ndarray]]:
    """A 1-D or (n, 1) array as one column ``key``; an (n, k) array as ``key_1 .. key_k``."""
    if arr.dtype.kind not in "biuf":
        raise DataError(f"{where}{kind} {shown(key)} has dtype {arr.dtype}; expected real numbers.")
    if arr.ndim == 1:
        return [(key, arr.astype(float))]
    if arr.ndim == 2 and arr.shape[1] == 1:
        return [(key, arr[:, 0].astype(float))]
    if arr.ndim == 2:
        return [(f"{key}_{j + 1}", arr[:, j].astype(float)) for j in range(arr.shape[1])]
    raise DataError(f"{where}{kind} {shown(key)} has shape {arr.shape}; expected (n_samples,) or (n_samples, k).")


def _check_writable_names(names: tuple[str, ...]) -> None:
    for n in names:
        if NAME_SEPARATOR in n:
            raise DataError(
                f"column name {shown(n)} contains '{NAME_SEPARATOR}'; expected names without commas "
                "(column lists such as --inputs are comma-separated, so it could not be selected again)."
            )


def table_for_writing(data: Mapping[str, ArrayLike] | Table | Experiment, dt: float | None, t0: float | None) -> Table:
    """The :class:`Table` a writer writes: from a Table, an Experiment or a mapping of columns.

    A mapping may hold a ``t`` column (checked, and used as the time axis) or get ``dt``/``t0``.
    Names must be selectable again on the command line (no commas).
    """
    if isinstance(data, (Table, Experiment)):
        if dt is not None or t0 is not None:
            raise DataError(
                f"dt and t0 are taken from the {type(data).__name__}; pass them only with a mapping of columns."
            )
        table = data if isinstance(data, Table) else Table.from_experiment(data)
        _check_writable_names(table.names)
        return table
    if not isinstance(data, Mapping):
        raise DataError(
            f"data must be a mapping of column name -> array, a Table or an Experiment; got {type(data).__name__}."
        )
    names, columns = [], []
    for key, value in data.items():
        arr = np.asarray(value)
        if arr.dtype.kind not in "biuf":
            raise DataError(f"column {shown(key)} must hold real numbers; got dtype {arr.dtype}.")
        if arr.ndim == 2 and arr.shape[1] == 1:
            arr = arr[:, 0]
        if arr.ndim != 1:
            raise DataError(f"column {shown(key)} must have shape (n_samples,) or (n_samples, 1); got {arr.shape}.")
        names.append(str(key))
        columns.append(arr.astype(float))  # astype copies: the caller's arrays are never touched
    if not columns:
        raise DataError("data must hold at least one column; got none.")
    _check_writable_names(tuple(names))
    values = stack_columns(names, columns, "")
    if TIME_COLUMN not in names:
        return Table(tuple(names), values, dt=dt, t0=0.0 if t0 is None else t0)
    i = names.index(TIME_COLUMN)
    check_finite(values[:, i : i + 1], [TIME_COLUMN], "")
    t0_col, dt_col = time_axis(values[:, i], "", None if dt is None else positive_seconds("dt", dt), DEFAULT_TIME_RTOL)
    if t0 is not None and abs(t0 - t0_col) > max(DEFAULT_TIME_RTOL * dt_col, 4.0 * np.finfo(float).eps * abs(t0_col)):
        raise DataError(f"t0={t0!r} disagrees with the first time stamp {t0_col!r} of column '{TIME_COLUMN}'.")
    keep = [j for j in range(len(names)) if j != i]
    return Table(tuple(names[j] for j in keep), values[:, keep], dt=dt_col, t0=t0_col)
