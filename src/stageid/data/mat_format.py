"""MATLAB ``.mat`` records (v4/v5/v7 through scipy, v7.3 through h5py): numeric vectors are columns.

Read by :func:`read_mat`.  Conventions shared with the other formats: :mod:`stageid.data.io`.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .._errors import DataError, NoSampleTimeError, StageIdError, StageIdWarning
from ..runtime.resources import require_memory
from .columns import DEFAULT_TIME_RTOL, TIME_COLUMN, file_prefix, stack_columns
from .files import HDF5_SIGNATURE, PathLike, array_columns, is_dunder, looks_like, open_checked, resolve_ts
from .table import Table, assemble_table

__all__ = ["read_mat", "mat_leaves", "struct_leaves", "PARAMETER_RATIO"]

#: A vector with fewer than the record's samples / PARAMETER_RATIO is a parameter, not a signal.
PARAMETER_RATIO = 10


def read_mat(path: PathLike, ts: float | None = None, *, time_rtol: float = DEFAULT_TIME_RTOL) -> Table:
    """Read the numeric signals of a MATLAB ``.mat`` file (v4/v5/v7 or v7.3), structs included.

    v5-style files are read with :func:`scipy.io.loadmat`, v7.3 files (HDF5 signature) with
    h5py.  Real numeric vectors — shape (n, 1), (1, n) or 1-D — become columns of their
    name; an (n, k) matrix ``v`` with n > 1 becomes columns ``v_1 .. v_k``.  Struct fields
    are flattened to MATLAB-style paths: ``s.a.b``, and ``s(2).b`` for element 2 of a struct
    array; a file holding a single 1x1 struct drops its variable name (a dSPACE ControlDesk
    export gives ``X.Data``, ``Y(1).Data``, ``Y(2).Data`` ... whatever the variable is called).
    Scalars (parameters such as gains), strings, cells, complex, sparse and 3-D arrays are
    not columns and are skipped, as are ``__dunder__`` keys.

    The time axis is the variable ``t``; else the one vector whose last name part is ``t`` or
    ``time`` (a Simulink "structure with time"); else ``X.Data`` (dSPACE: the time of the ``Y``
    signals).  The columns are those of the record's length (the time axis's, else the one most
    columns share); vectors with fewer than a tenth of its samples (a row of means, filter
    coefficients) are parameters: skipped with a :class:`~stageid.StageIdWarning` naming them.
    Parameters, returns and errors as :func:`read_table`.

    Raises
    ------
    DataError
        As :func:`read_table`; also a file with no numeric vectors (naming what it holds),
        vectors of lengths that cannot be aligned (no single record length with only far shorter
        vectors beside it; grouped by length, with their names) and several different time
        vectors.

    Examples
    --------
    >>> import numpy as np, tempfile, os, scipy.io
    >>> from stageid.data.io import read_mat
    >>> path = os.path.join(tempfile.mkdtemp(), "x.mat")
    >>> scipy.io.savemat(path, {"t": np.arange(4.0)[:, None], "u": np.zeros((4, 1)), "gain": 2.0})
    >>> read_mat(path).names
    ('u',)
    >>> rec = {"time": 0.5 * np.arange(4.0), "signals": {"values": np.ones((4, 2))}}
    >>> scipy.io.savemat(path, {"run": rec})
    >>> table = read_mat(path)
    >>> table.names, table.dt
    (('signals.values_1', 'signals.values_2'), 0.5)
    """
    p, _ = open_checked(path)
    where = file_prefix(p.name)
    ts = resolve_ts(ts, time_rtol, where)
    variables, skipped = _real_columns(*mat_leaves(p))
    variables, time_source = _with_time_axis(variables, where)
    names: list[str] = []
    columns: list[np.ndarray] = []
    for key, arr in variables:
        for name, col in array_columns(key, arr, where, kind="variable"):
            names.append(name)
            columns.append(col)
    if not columns:
        found = f"; found only {_listed(skipped)}" if skipped else ""
        raise DataError(f"file '{p.name}' holds no numeric signals (vectors of samples){found}.")
    names, columns = _record_columns(names, columns, where)
    values = stack_columns(names, columns, where)
    units = ["s" if n == TIME_COLUMN else "" for n in names]
    try:
        return assemble_table(p.name, names, values, units, ts, time_rtol)
    except NoSampleTimeError as exc:
        responses = [s[: -len(" (complex)")] for s in skipped if s.endswith(" (complex)")]
        if not responses:
            raise
        # complex vectors and no time: most likely a measured FRF, which is not a time record
        raise NoSampleTimeError(
            f"{str(exc).rstrip('.')}; the complex vectors ({_listed(responses, 4)}) look like frequency "
            "responses: read one with stageid.data.mat_responses, or fit it with `stageid identify frd`."
        ) from None
    except DataError as exc:
        if time_source is None:
            raise
        # the checks name the column 't'; the user knows it by its field name
        raise DataError(str(exc).replace(f"column '{TIME_COLUMN}'", f"vector '{time_source}'")) from None


def mat_leaves(path: PathLike) -> tuple[list[tuple[str, np.ndarray]], list[str]]:
    """The numeric arrays of a ``.mat`` file (v5 or v7.3) by flattened name, and what was skipped.

    Names as :func:`read_mat` gives them (``s.a``, ``s(2).b``, a lone struct's name dropped);
    arrays real or complex, in MATLAB's shape (a v7.3 array transposed back).  Skipped values
    are listed as ``"name (kind)"`` for messages.

    Raises
    ------
    DataError
        A missing, empty or unreadable file.
    """
    p, head = open_checked(path)
    where = file_prefix(p.name)
    if head[512:520] == HDF5_SIGNATURE or head.startswith(HDF5_SIGNATURE):
        return _mat73_variables(p, where)
    return _mat5_variables(p, head, where)


def _listed(items: list[str], limit: int = 12) -> str:
    more = f" and {len(items) - limit} more" if len(items) > limit else ""
    return ", ".join(items[:limit]) + more


def _with_time_axis(
    variables: list[tuple[str, np.ndarray]], where: str
) -> tuple[list[tuple[str, np.ndarray]], str | None]:
    """Rename the time vector of a struct file to ``t``; returns the variables and its field name.

    Candidates, by rule: ``t``; vectors whose last name part is ``t`` or ``time``; ``X.Data``
    (dSPACE).  Several equal candidates are one axis; several different ones are an error.
    """
    names = [k for k, _ in variables]
    if TIME_COLUMN in names:
        return variables, None
    vectors = {k: a for k, a in variables if a.ndim == 1 or (a.ndim == 2 and a.shape[1] == 1)}
    rules = (
        lambda k: k.rsplit(".", 1)[-1].lower() in ("t", "time"),
        lambda k: k == "X.Data",
    )
    for rule in rules:
        found = [k for k in vectors if rule(k)]
        if not found:
            continue
        first = vectors[found[0]].ravel()
        if any(vectors[k].ravel().shape != first.shape or not np.array_equal(vectors[k].ravel(), first) for k in found):
            raise DataError(f"{where}several different time vectors ({', '.join(found)}); expected one time axis.")
        kept = [(TIME_COLUMN if k == found[0] else k, a) for k, a in variables if k == found[0] or k not in found]
        return kept, found[0]
    return variables, None


def _record_columns(names: list[str], columns: list[np.ndarray], where: str) -> tuple[list[str], list[np.ndarray]]:
    """The columns of the record's length; vectors far shorter are parameters, skipped with a warning.

    The record's length is the time axis's, else the length most columns share (the longer on
    a tie).  A vector with fewer than its samples / ``PARAMETER_RATIO`` (a row of means,
    filter coefficients) cannot be a signal of the record and is skipped; any other length
    cannot be aligned without guessing which samples match, so it is an error listing the names
    of each length.
    """
    by_length: dict[int, list[str]] = {}
    for name, col in zip(names, columns):
        by_length.setdefault(int(col.shape[0]), []).append(name)
    if len(by_length) < 2:
        return names, columns
    if TIME_COLUMN in names:
        record = int(columns[names.index(TIME_COLUMN)].shape[0])
    else:
        record = max(by_length, key=lambda n: (len(by_length[n]), n))
    short = {n: ks for n, ks in by_length.items() if n * PARAMETER_RATIO < record}
    if len(by_length) - len(short) > 1:
        groups = "; ".join(
            f"{n} samples: {_listed(['time' if k == TIME_COLUMN else k for k in ks], 6)}"
            for n, ks in sorted(by_length.items(), key=lambda item: -len(item[1]))
        )
        raise DataError(f"{where}signals have unequal lengths ({groups}); expected one length for every column.")
    skipped = "; ".join(f"{_listed(ks, 6)} ({n} samples)" for n, ks in sorted(short.items(), reverse=True))
    warnings.warn(
        f"{where}skipped {skipped}: shorter than a tenth of the record's {record} samples, so read as parameters, "
        "not signals.",
        StageIdWarning,
        stacklevel=3,
    )
    kept = [(n, c) for n, c in zip(names, columns) if c.shape[0] == record]
    return [n for n, _ in kept], [c for _, c in kept]


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


def _kind(value: object) -> str:
    """What a skipped MATLAB value is, for messages."""
    if not isinstance(value, np.ndarray):
        return "sparse"
    if value.dtype.kind in "US":
        return "text"
    if value.dtype.kind == "c":
        return "complex"
    if value.dtype.kind == "O":
        return "cell"
    if value.dtype.kind in "biuf" and value.size <= 1:
        return "scalar"
    return f"{value.ndim}-D array" if value.ndim > 2 else f"{value.dtype.kind}-type"


def struct_leaves(name: str, value: object, depth: int = 0) -> tuple[list[tuple[str, np.ndarray]], list[str]]:
    """Flatten a value of :func:`scipy.io.loadmat` into ``(path, array)`` numeric leaves and skipped names.

    A 1x1 struct ``s`` gives ``s.field``; element i (1-based, MATLAB order) of a struct array
    gives ``s(i).field``.  Numeric (real or complex) leaves are returned as stored; strings,
    cells and sparse matrices are listed as skipped, ``"name (kind)"``.
    """
    if type(value).__name__ == "MatlabOpaque":  # a MATLAB object (tf, ss, ...): scipy cannot read its data
        return [], [f"{name} (MATLAB object)"]
    if isinstance(value, np.ndarray) and value.dtype.names is not None:
        if depth > 16:  # MATLAB structs are shallow; a deeper one is a reference loop
            return [], [f"{name} (struct nested too deeply)"]
        elements = value.ravel(order="F")
        leaves, skipped = [], []
        for i, element in enumerate(elements):
            base = name if elements.size == 1 else f"{name}({i + 1})"
            for field in value.dtype.names:
                child = f"{base}.{field}" if base else field
                sub_leaves, sub_skipped = struct_leaves(child, element[field], depth + 1)
                leaves += sub_leaves
                skipped += sub_skipped
        return leaves, skipped
    if isinstance(value, np.ndarray) and value.dtype.kind in "biufc":
        return [(name, value)], []
    return [], [f"{name} ({_kind(value)})"]


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
    keys = [k for k in content if not is_dunder(k)]
    single = len(keys) == 1 and _is_struct(content[keys[0]]) and content[keys[0]].size == 1
    leaves, skipped = [], []
    for key in keys:
        value = content[key]
        if issparse(value):
            skipped.append(f"{key} (sparse)")
            continue
        # a lone struct is the whole record (dSPACE names it after the run): its fields are the names
        found, passed = struct_leaves("" if single else key, value)
        leaves += found
        skipped += passed
    return leaves, skipped


def _is_struct(value: object) -> bool:
    return isinstance(value, np.ndarray) and value.dtype.names is not None


def _real_columns(
    leaves: list[tuple[str, np.ndarray]], skipped: list[str]
) -> tuple[list[tuple[str, np.ndarray]], list[str]]:
    """The leaves that are columns (real vectors and matrices); the others join ``skipped``."""
    out = []
    for name, arr in leaves:
        col = _mat_column_array(arr)
        if col is None:
            skipped.append(f"{name} ({_kind(arr)})")
        else:
            out.append((name, col))
    return out, skipped


def _mat73_variables(p: Path, where: str) -> tuple[list[tuple[str, np.ndarray]], list[str]]:
    import h5py

    try:
        with h5py.File(p, "r") as fh:
            sizes: list[float] = []
            fh.visititems(
                lambda _, o: (
                    sizes.append(float(o.size) * (o.dtype.itemsize + 16.0)) if isinstance(o, h5py.Dataset) else None
                )
            )
            require_memory(sum(sizes), f"reading the datasets of '{p.name}'")
            keys = [k for k in fh.keys() if not k.startswith("#") and not is_dunder(k)]
            single = len(keys) == 1 and isinstance(fh[keys[0]], h5py.Group)
            leaves, skipped = [], []
            for key in keys:
                found, passed = _h5_leaves(fh, "" if single else key, fh[key], 0)
                leaves += found
                skipped += passed
    except (OSError, ValueError, TypeError, KeyError) as exc:
        raise DataError(f"file '{p.name}' is not a readable MATLAB v7.3 (HDF5) file: {exc}.") from None
    return leaves, skipped


def _h5_leaves(fh, name: str, obj, depth: int) -> tuple[list[tuple[str, np.ndarray]], list[str]]:
    """Flatten a v7.3 object as :func:`struct_leaves` does a v5 one (structs are HDF5 groups)."""
    import h5py

    if depth > 16:  # MATLAB structs are shallow; a deeper one is a reference loop
        return [], [f"{name} (struct nested too deeply)"]
    leaves, skipped = [], []
    if isinstance(obj, h5py.Group):
        for key in obj.keys():
            member = obj[key]
            refs = isinstance(member, h5py.Dataset) and h5py.check_dtype(ref=member.dtype) is not None
            if refs and _matlab_class(member) != "cell":  # a field of a struct array: one reference per element
                targets = np.asarray(member[()]).T.ravel(order="F")
                for i, ref in enumerate(targets):
                    child = f"{name}({i + 1}).{key}" if targets.size > 1 else f"{name}.{key}"
                    found, passed = _h5_leaves(fh, child.lstrip("."), fh[ref], depth + 1)
                    leaves += found
                    skipped += passed
                continue
            found, passed = _h5_leaves(fh, f"{name}.{key}" if name else key, member, depth + 1)
            leaves += found
            skipped += passed
        return leaves, skipped
    cls = _matlab_class(obj)
    if cls in ("char", "cell", "struct") or obj.attrs.get("MATLAB_empty", 0):
        return [], [f"{name} ({'text' if cls == 'char' else cls})"]
    arr = np.asarray(obj[()])
    if arr.dtype.names is not None:  # complex data are stored as (real, imag) records
        arr = arr["real"] + 1j * arr["imag"]
    return [(name, arr.T)], []  # HDF5 stores MATLAB arrays transposed


def _matlab_class(obj) -> str:
    cls = obj.attrs.get("MATLAB_class", b"double")
    return cls.decode() if isinstance(cls, bytes) else str(cls)
