"""MATLAB ``.mat`` records (v4/v5/v7 through scipy, v7.3 through h5py): numeric vectors are columns.

Read by :func:`read_mat`.  Conventions shared with the other formats: :mod:`stageid.data.io`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._errors import DataError, StageIdError
from ..runtime.resources import require_memory
from .files import HDF5_SIGNATURE, PathLike, array_columns, is_dunder, looks_like, open_checked, resolve_ts
from .table import DEFAULT_TIME_RTOL, TIME_COLUMN, Table, assemble_table, file_prefix, stack_columns

__all__ = ["read_mat"]


def read_mat(path: PathLike, ts: float | None = None, *, time_rtol: float = DEFAULT_TIME_RTOL) -> Table:
    """Read the numeric column variables of a MATLAB ``.mat`` file (v4/v5/v7 or v7.3).

    v5-style files are read with :func:`scipy.io.loadmat`, v7.3 files (HDF5 signature) with
    h5py.  Real numeric vectors — shape (n, 1), (1, n) or 1-D — become columns of their
    name; an (n, k) matrix ``v`` with n > 1 becomes columns ``v_1 .. v_k``.  Scalars
    (parameters such as gains), structs, cells, strings, complex, sparse and 3-D arrays are
    not columns and are skipped, as are ``__dunder__`` keys.  An optional ``t`` variable is
    the time axis.  Parameters, returns and errors as :func:`read_table`; a file holding
    only structs raises a :class:`DataError` naming them.

    Examples
    --------
    >>> import numpy as np, tempfile, os, scipy.io
    >>> from stageid.data.io import read_mat
    >>> path = os.path.join(tempfile.mkdtemp(), "x.mat")
    >>> scipy.io.savemat(path, {"t": np.arange(4.0)[:, None], "u": np.zeros((4, 1)), "gain": 2.0})
    >>> read_mat(path).names
    ('u',)
    """
    p, head = open_checked(path)
    where = file_prefix(p.name)
    ts = resolve_ts(ts, time_rtol, where)
    if head[512:520] == HDF5_SIGNATURE or head.startswith(HDF5_SIGNATURE):
        variables, skipped = _mat73_variables(p, where)
    else:
        variables, skipped = _mat5_variables(p, head, where)
    names: list[str] = []
    columns: list[np.ndarray] = []
    for key, arr in variables:
        for name, col in array_columns(key, arr, where, kind="variable"):
            names.append(name)
            columns.append(col)
    if not columns:
        found = (
            f"; found only {', '.join(skipped)} (use a dedicated loader from stageid.data.datasets for structs)"
            if skipped
            else ""
        )
        raise DataError(f"file '{p.name}' holds no numeric column variables{found}.")
    values = stack_columns(names, columns, where)
    units = ["s" if n == TIME_COLUMN else "" for n in names]
    return assemble_table(p.name, names, values, units, ts, time_rtol)


def _mat_column_array(arr: np.ndarray) -> np.ndarray | None:
    """MATLAB-shaped array -> 1-D vector or 2-D (n, k) matrix, or None when it is no column."""
    if arr.dtype.kind not in "biuf" or arr.size == 0:
        return None
    if arr.ndim == 2 and arr.shape[0] == 1 and arr.shape[1] > 1:
        return arr[0]
    if arr.ndim == 1 and arr.size > 1:
        return arr
    if arr.ndim == 2 and arr.shape[0] > 1:
        return arr
    return None  # scalars and N-D arrays


def _mat5_variables(p: Path, head: bytes, where: str) -> tuple[list[tuple[str, np.ndarray]], list[str]]:
    import scipy.io
    from scipy.sparse import issparse

    if len(head) < 128 or not head.startswith(b"MATLAB"):
        if b"\x00" not in head[:128]:
            raise DataError(f"file '{p.name}' is not a MATLAB .mat file (it looks like text){looks_like(head)}.")
    try:
        # the variables' declared sizes, read from their headers before anything is inflated
        declared = sum(float(np.prod(shape, dtype=float)) for _, shape, _ in scipy.io.whosmat(p))
        require_memory(declared * 24.0, f"reading the variables of '{p.name}'")
        content = scipy.io.loadmat(p, squeeze_me=False, mat_dtype=False)
    except StageIdError:
        raise
    except Exception as exc:  # scipy raises ValueError/TypeError/OSError for foreign files
        raise DataError(f"file '{p.name}' is not a readable MATLAB .mat file{looks_like(head)}: {exc}.") from None
    out, skipped = [], []
    for key, value in content.items():
        if is_dunder(key):
            continue
        if issparse(value) or not isinstance(value, np.ndarray):
            skipped.append(f"'{key}' (sparse)")
            continue
        col = _mat_column_array(value)
        if col is None:
            if value.dtype.names is not None:
                skipped.append(f"struct '{key}'")
            elif value.dtype.kind not in "biuf":
                skipped.append(f"'{key}' ({value.dtype.kind}-type)")
            continue
        out.append((key, col))
    return out, skipped


def _mat73_variables(p: Path, where: str) -> tuple[list[tuple[str, np.ndarray]], list[str]]:
    import h5py

    out, skipped = [], []
    try:
        with h5py.File(p, "r") as fh:
            datasets = [fh[k] for k in fh.keys() if isinstance(fh[k], h5py.Dataset)]
            need = sum(float(d.size) * (d.dtype.itemsize + 16.0) for d in datasets)
            require_memory(need, f"reading the datasets of '{p.name}'")
            for key in fh.keys():
                if key.startswith("#") or is_dunder(key):
                    continue
                obj = fh[key]
                if not isinstance(obj, h5py.Dataset):
                    skipped.append(f"struct '{key}'")
                    continue
                cls = obj.attrs.get("MATLAB_class", b"double")
                cls = cls.decode() if isinstance(cls, bytes) else str(cls)
                if cls in ("char", "cell", "struct") or obj.attrs.get("MATLAB_empty", 0):
                    skipped.append(f"{cls} '{key}'")
                    continue
                arr = np.asarray(obj[()])
                if arr.dtype.names is not None:  # complex data are stored as (real, imag) records
                    skipped.append(f"complex '{key}'")
                    continue
                col = _mat_column_array(arr.T)  # HDF5 stores MATLAB arrays transposed
                if col is not None:
                    out.append((key, col))
    except (OSError, ValueError, TypeError) as exc:
        raise DataError(f"file '{p.name}' is not a readable MATLAB v7.3 (HDF5) file: {exc}.") from None
    return out, skipped
