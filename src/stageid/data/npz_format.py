"""NumPy ``.npz`` records: one array per column, ``t`` as the time axis, ``__units__`` metadata.

Read by :func:`read_npz` (never unpickling: object arrays are refused), written by
:func:`write_npz`.  Conventions shared with the other formats: :mod:`stageid.data.io`.
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._errors import DataError, StageIdError
from ..atomic import atomic_write
from ..checks import shown
from ..runtime.resources import require_memory
from .columns import DEFAULT_TIME_RTOL, TIME_COLUMN, file_prefix, stack_columns
from .experiment import Experiment
from .files import (
    ZIP_SIGNATURES,
    PathLike,
    array_columns,
    is_dunder,
    looks_like,
    open_checked,
    resolve_ts,
    table_for_writing,
)
from .table import Table, assemble_table

if TYPE_CHECKING:  # pragma: no cover
    from numpy.typing import ArrayLike

__all__ = ["read_npz", "write_npz"]


def read_npz(path: PathLike, ts: float | None = None, *, time_rtol: float = DEFAULT_TIME_RTOL) -> Table:
    """Read a NumPy ``.npz`` archive whose arrays are the columns.

    Each array is 1-D or of shape (n, 1) and becomes the column of its name; an (n, k)
    array ``v`` becomes columns ``v_1 .. v_k``.  An optional ``t`` array is the time axis.
    Names of the form ``__name__`` are metadata, not columns; ``__units__`` (written by
    :func:`write_npz`) is an array of ``[name, unit]`` pairs.  Parameters, returns and errors
    as :func:`read_table`.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from stageid.data.io import read_npz
    >>> path = os.path.join(tempfile.mkdtemp(), "x.npz")
    >>> np.savez(path, t=np.arange(3) * 0.1, u=np.zeros(3), y=np.ones((3, 2)))
    >>> read_npz(path).names
    ('u', 'y_1', 'y_2')
    """
    p, head = open_checked(path)
    where = file_prefix(p.name)
    ts = resolve_ts(ts, time_rtol, where)
    if not head.startswith(ZIP_SIGNATURES):
        raise DataError(f"file '{p.name}' is not a NumPy .npz archive{looks_like(head)}.")
    names: list[str] = []
    columns: list[np.ndarray] = []
    unit_of: dict[str, str] = {}
    try:
        with np.load(p, allow_pickle=False) as archive:
            _require_memory_for_members(archive, p.name, where)
            for key in archive.files:
                try:
                    arr = archive[key]
                except ValueError:
                    raise DataError(f"{where}array {shown(key)} holds Python objects; expected numbers.") from None
                if key == "__units__":
                    unit_of = _units_from_pairs(arr, where)
                    continue
                if is_dunder(key):
                    continue
                for name, col in array_columns(key, arr, where, kind="array"):
                    names.append(name)
                    columns.append(col)
    except StageIdError:  # a refusal of ours (bad content, too large), not a broken archive
        raise
    except Exception as exc:  # zipfile.BadZipFile, OSError, ...: a broken archive
        raise DataError(f"file '{p.name}' is not a readable NumPy .npz archive: {exc}.") from None
    if not columns:
        raise DataError(f"file '{p.name}' holds no arrays; expected one array per column.")
    values = stack_columns(names, columns, where)
    units = [unit_of.get(n, "s" if n == TIME_COLUMN else "") for n in names]
    return assemble_table(p.name, names, values, units, ts, time_rtol)


def _member_header(archive: Any, key: str) -> tuple[tuple[int, ...], np.dtype] | None:
    """Shape and dtype an ``.npy`` member declares, read from its header without inflating it."""
    name = key if key in archive.zip.namelist() else f"{key}.npy"
    try:
        with archive.zip.open(name) as fh:
            version = np.lib.format.read_magic(fh)
            read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
            shape, _, dtype = read(fh)
    except Exception:  # not an .npy member, or a header numpy cannot read: np.load will say so
        return None
    return tuple(shape), dtype


def _require_memory_for_members(archive: Any, filename: str, where: str) -> None:
    """Refuse an archive whose arrays would not fit in memory, judged by their headers.

    A few megabytes of zip can declare gigabytes of zeros; each array is held as read and
    again as float64 columns.
    """
    need = 0.0
    for key in archive.files:
        header = _member_header(archive, key)
        if header is None:
            continue
        shape, dtype = header
        if dtype.hasobject:
            raise DataError(f"{where}array {shown(key)} holds Python objects; expected numbers.")
        count = float(np.prod(shape, dtype=float))
        need += count * (dtype.itemsize + 16.0)
    require_memory(need, f"reading the arrays of '{filename}'")


def _units_from_pairs(arr: np.ndarray, where: str) -> dict[str, str]:
    if arr.dtype.kind not in "US" or arr.ndim != 2 or arr.shape[1] != 2:
        raise DataError(
            f"{where}'__units__' must be a string array of [name, unit] pairs; got dtype {arr.dtype}, shape {arr.shape}."
        )
    return {str(n): str(u) for n, u in arr}


def write_npz(
    path: PathLike,
    data: Mapping[str, ArrayLike] | Table | Experiment,
    *,
    dt: float | None = None,
    t0: float | None = None,
) -> Path:
    """Write columns to an uncompressed ``.npz`` archive atomically (read back by :func:`read_npz`).

    One 1-D float64 array per column, ``t`` first when the sample time is known, and a
    ``__units__`` array of ``[name, unit]`` pairs when any unit is set.  Parameters,
    returns and errors as :func:`write_csv`.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from stageid.data import write_npz, read_table
    >>> path = os.path.join(tempfile.mkdtemp(), "x.npz")
    >>> _ = write_npz(path, {"u": np.arange(3.0)}, dt=0.25)
    >>> read_table(path).dt
    0.25
    """
    table = table_for_writing(data, dt, t0)
    arrays: dict[str, np.ndarray] = {}
    if table.dt is not None:
        arrays[TIME_COLUMN] = table.time
    for j, n in enumerate(table.names):
        if is_dunder(n):
            raise DataError(f"column name '{n}' is reserved for metadata in .npz files; rename it.")
        arrays[n] = np.ascontiguousarray(table.values[:, j])
    if any(table.units):
        arrays["__units__"] = np.array([[n, u] for n, u in zip(table.names, table.units)], dtype=str)

    def write(fh: io.BufferedIOBase) -> None:
        np.savez(fh, **arrays)

    return atomic_write(path, write, binary=True)
