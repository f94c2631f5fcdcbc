"""Records larger than memory: HDF5, Zarr and ``.npy`` files read range by range.

A :class:`ChunkedRecord` names a file and its input and output columns; it holds no samples.
:meth:`ChunkedRecord.read` returns the rows ``start .. stop - 1`` of the channels (inputs
first), opening the file for each call, so a record can be shipped to a Dask worker as a few
hundred bytes and every task reads its own range (:mod:`stageid.subspace.chunked_statistics`,
:mod:`stageid.frf.welch_chunked`).  Nothing here ever reads a whole column.

Layouts
-------
* **HDF5** (``.h5``, ``.hdf5``): one 1-D dataset per column at the file's root.  The sample
  time is the root attribute ``dt`` (seconds), or a 1-D dataset ``t`` (uniform, increasing),
  or ``ts``.
* **Zarr** (a directory store, v2 or v3): one 1-D array per column at the root group; ``dt``
  as a group attribute, a ``t`` array, or ``ts``.
* **NumPy** ``.npy`` (memory-mapped, no metadata, so the sample time is ``t`` or ``ts``):

  - a folder of one 1-D ``<column>.npy`` file per column (and optionally ``t.npy``): the
    layout a logger writing channel by channel produces;
  - one ``<name>.npy`` file: a 1-D array is the column ``<name>``; a 2-D array of shape
    (n_samples, k) holds the columns ``<name>_1 .. <name>_k`` (the rule of the ``.npz`` and
    ``.mat`` readers for 2-D arrays); ``ts`` gives the sample time.

The sample time follows the one rule of :mod:`stageid.data.sampling`: the ``t`` column's
least-squares period, uniform within ``time_rtol``; when more than one source gives it they must
agree to ``PERIOD_RTOL``.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from .._errors import DataError
from ..atomic import note_input
from .columns import TIME_COLUMN
from .sampling import (
    PERIOD_RTOL,
    UNIFORM_RTOL,
    StampScan,
    check_period,
    ends_step,
    grid_from_scan,
    same_period,
    scan_stamps,
    seconds,
)

__all__ = [
    "ChunkedRecord",
    "open_chunked",
    "is_chunked_path",
    "CHUNKED_SUFFIXES",
    "DEFAULT_CHUNK",
    "check_finite_rows",
    "map_reduce",
]

#: File extensions read as chunked records (a directory is a Zarr store or a folder of .npy).
CHUNKED_SUFFIXES = (".h5", ".hdf5", ".npy", ".zarr")

#: Samples per task of a chunked computation: 2^20 rows of four float64 channels are 32 MB.
DEFAULT_CHUNK = 1 << 20
#: Samples read at once when the time column is checked.
TIME_CHUNK = 1 << 20


def is_chunked_path(path: str | os.PathLike[str]) -> bool:
    """True for the files and folders :func:`open_chunked` reads (by extension, or a directory)."""
    p = Path(path)
    return p.suffix.lower() in CHUNKED_SUFFIXES or p.is_dir()


@dataclasses.dataclass(frozen=True)
class ChunkedRecord:
    """One record on disk: ``channels`` = input then output column names, ``n_samples`` each.

    ``kind`` is ``"hdf5"``, ``"zarr"``, ``"npy-folder"`` or ``"npy"``; ``keys[i]`` is where
    channel ``i`` lives (dataset name, array name, file path) and ``columns[i]`` its column
    index in a 2-D ``.npy`` array (None otherwise).
    """

    path: str
    kind: str
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    keys: tuple[str, ...]
    columns: tuple[int | None, ...]
    n_samples: int
    dt: float
    name: str = ""

    @property
    def names(self) -> tuple[str, ...]:
        return self.input_names + self.output_names

    @property
    def n_inputs(self) -> int:
        return len(self.input_names)

    @property
    def n_outputs(self) -> int:
        return len(self.output_names)

    def read(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start .. stop - 1`` of every channel: a new float64 array of shape (stop - start, n_channels)."""
        start, stop = max(0, int(start)), min(self.n_samples, int(stop))
        out = np.empty((max(stop - start, 0), len(self.keys)))
        if stop <= start:
            return out
        store = _opened(self.path, self.kind)
        for j, (key, col) in enumerate(zip(self.keys, self.columns)):
            out[:, j] = _slice(store, self.kind, key, col, start, stop)
        return out


#: Open HDF5 files and Zarr groups of this process, by (path, size, modification time): a worker
#: reading hundreds of chunks of one file opens it once (a rewritten file is opened afresh).
_OPEN: dict[tuple[str, int, int], object] = {}
_OPEN_MAX = 8


def _opened(path: str, kind: str):
    """The open file or store of a record (kept open for the next read of the same file)."""
    if kind not in ("hdf5", "zarr"):
        return None
    st = os.stat(path)
    key = (path, st.st_size, st.st_mtime_ns)
    handle = _OPEN.get(key)
    if handle is None:
        if len(_OPEN) >= _OPEN_MAX:
            old = _OPEN.pop(next(iter(_OPEN)))
            if kind == "hdf5" and hasattr(old, "close"):
                old.close()
        if kind == "hdf5":
            import h5py

            handle = h5py.File(path, "r")
        else:
            import zarr

            handle = zarr.open_group(path, mode="r")
        _OPEN[key] = handle
    return handle


def _slice(store, kind: str, key: str, col: int | None, start: int, stop: int) -> np.ndarray:
    if kind in ("hdf5", "zarr"):
        return np.asarray(store[key][start:stop], dtype=float)
    arr = np.load(key, mmap_mode="r")
    return np.asarray(arr[start:stop] if col is None else arr[start:stop, col], dtype=float)


def check_finite_rows(block: np.ndarray, names: Sequence[str], start: int, where: str) -> None:
    """DataError naming the column and (absolute) row of the first NaN/inf in ``block`` of rows from ``start``."""
    if np.isfinite(block).all():
        return
    bad = ~np.isfinite(block)
    if bad.any():
        i, j = (int(v) for v in np.argwhere(bad)[0])
        what = "NaN" if np.isnan(block[i, j]) else "inf"
        raise DataError(f"{where}: column '{names[j]}' has {what} at row {start + i}; every sample must be finite.")


def open_chunked(
    path: str | os.PathLike[str],
    inputs: Sequence[str],
    outputs: Sequence[str],
    ts: float | None = None,
    time_rtol: float = UNIFORM_RTOL,
) -> ChunkedRecord:
    """The record of an HDF5 file, a Zarr store or ``.npy`` file(s) (see the module notes).

    Only metadata and the time column (range by range) are read.

    Raises
    ------
    DataError
        A missing file, a column not in the file, a column that is not 1-D real numbers, an
        empty column, columns of different lengths, no sample time (no ``dt`` attribute, no
        ``t`` column and no ``ts``), a non-uniform time column, or sources of the sample
        time that disagree.
    """
    p = Path(path)
    if not p.exists():
        raise DataError(f"file '{p}' does not exist.")
    note_input(p)
    wanted = list(inputs) + list(outputs)
    kind, entries, attr_dt = _layout(p)
    where = p.name
    for name in wanted:
        if name not in entries:
            shown = ", ".join(sorted(k for k in entries if k != TIME_COLUMN)) or "none"
            raise DataError(f"{where}: no column '{name}'; the file has {shown}.")
    shapes = {name: entries[name][2] for name in wanted}
    for name in wanted:
        _check_column(where, name, shapes[name], entries[name][3])
    n = shapes[wanted[0]][0]
    for name in wanted[1:]:
        if shapes[name][0] != n:
            raise DataError(
                f"{where}: column '{name}' has {shapes[name][0]} samples, column '{wanted[0]}' {n}; "
                "expected equal lengths."
            )
    if n < 2:
        raise DataError(f"{where}: a record needs at least 2 samples; got {n}.")
    store_path = str(p)
    dt = _sample_time(store_path, kind, entries, n, attr_dt, ts, time_rtol, where)
    keys = tuple(entries[name][0] for name in wanted)
    cols = tuple(entries[name][1] for name in wanted)
    return ChunkedRecord(store_path, kind, tuple(inputs), tuple(outputs), keys, cols, int(n), dt, where)


def _check_column(where: str, name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
    if len(shape) != 1:
        raise DataError(f"{where}: column '{name}' has shape {shape}; expected a 1-D dataset (one per column).")
    if np.dtype(dtype).kind not in "biuf":
        raise DataError(f"{where}: column '{name}' has dtype {dtype}; expected real numbers.")
    if shape[0] == 0:
        raise DataError(f"{where}: column '{name}' is empty; expected samples.")


def _layout(p: Path) -> tuple[str, dict[str, tuple[str, int | None, tuple[int, ...], np.dtype]], float | None]:
    """``(kind, {column: (key, column index, shape, dtype)}, dt attribute)`` of a file or folder."""
    suffix = p.suffix.lower()
    try:
        if p.is_dir():
            if any((p / marker).exists() for marker in ("zarr.json", ".zgroup")):
                return _zarr_layout(p)
            files = sorted(p.glob("*.npy"))
            if not files:
                raise DataError(f"folder '{p.name}' is neither a Zarr store nor a folder of .npy columns.")
            entries = {}
            for f in files:
                arr = np.load(f, mmap_mode="r")
                entries[f.stem] = (str(f), None, tuple(arr.shape), arr.dtype)
            return "npy-folder", entries, None
        if suffix in (".h5", ".hdf5"):
            return _hdf5_layout(p)
        if suffix == ".npy":
            arr = np.load(p, mmap_mode="r")
            if arr.ndim == 2:
                k = arr.shape[1]
                return "npy", {f"{p.stem}_{j + 1}": (str(p), j, (arr.shape[0],), arr.dtype) for j in range(k)}, None
            return "npy", {p.stem: (str(p), None, tuple(arr.shape), arr.dtype)}, None
        if suffix == ".zarr":
            return _zarr_layout(p)
    except DataError:
        raise
    except Exception as exc:  # h5py, zarr and numpy raise many kinds for a damaged file
        raise DataError(f"{p.name}: cannot read it as a {suffix or 'chunked'} record ({exc}).") from None
    raise DataError(f"file '{p.name}' has extension '{suffix}'; expected one of {', '.join(CHUNKED_SUFFIXES)}.")


def _hdf5_layout(p: Path):
    import h5py

    with h5py.File(p, "r") as f:
        entries = {
            k: (k, None, tuple(v.shape), v.dtype)
            for k, v in f.items()
            if isinstance(v, h5py.Dataset) and v.dtype.kind != "O"
        }
        return "hdf5", entries, _attribute_dt(f.attrs, p.name)


def _zarr_layout(p: Path):
    import zarr

    g = zarr.open_group(str(p), mode="r")
    entries = {k: (k, None, tuple(v.shape), v.dtype) for k, v in g.arrays()}
    return "zarr", entries, _attribute_dt(g.attrs, p.name)


def _attribute_dt(attrs, where: str) -> float | None:
    if "dt" not in attrs:
        return None
    try:
        value = float(np.asarray(attrs["dt"]).reshape(()))
    except (TypeError, ValueError):
        raise DataError(f"{where}: the 'dt' attribute must be one number of seconds; got {attrs['dt']!r}.") from None
    return check_period(value, "dt", f"{where}: the attribute ")


def _sample_time(path, kind, entries, n, attr_dt, ts, rtol, where) -> float:
    """The sample time from the ``t`` column, the ``dt`` attribute and ``ts`` (all that are given agree)."""
    given: list[tuple[str, float]] = []
    if TIME_COLUMN in entries:
        key, col, shape, dtype = entries[TIME_COLUMN]
        _check_column(where, TIME_COLUMN, shape, dtype)
        if shape[0] != n:
            raise DataError(f"{where}: the time column 't' has {shape[0]} samples, the channels {n}; expected equal.")
        rec = ChunkedRecord(path, kind, (TIME_COLUMN,), (), (key,), (col,), n, 1.0, where)
        given.append(("the time column 't'", _uniform_step(rec, n, rtol, where)))
    if attr_dt is not None:
        given.append(("the 'dt' attribute", attr_dt))
    if ts is not None:
        given.append(("ts", check_period(ts, "ts", f"{where}: ")))
    if not given:
        raise DataError(f"{where}: no sample time; expected a 'dt' attribute, a 't' column or `ts=`.")
    first_name, first = given[0]
    for other_name, other in given[1:]:
        if not same_period(other, first):
            raise DataError(
                f"{where}: {other_name} ({seconds(other)} s) disagrees with {first_name} ({seconds(first)} s); "
                f"expected agreement to {PERIOD_RTOL:g} relative."
            )
    return float(given[-1][1])


def _uniform_step(rec: ChunkedRecord, n: int, rtol: float, where: str) -> float:
    """The period of a time column by the sample-time rule, read range by range."""
    prefix = f"{where}: "
    t_first, t_last = float(rec.read(0, 1)[0, 0]), float(rec.read(n - 1, n)[0, 0])
    if not (np.isfinite(t_first) and np.isfinite(t_last)):
        raise DataError(f"{prefix}the time column 't' must be finite; got {t_first!r} to {t_last!r}.")
    scan = StampScan(n, t_first, ends_step(t_first, t_last, n, prefix))
    for a in range(0, n - 1, TIME_CHUNK):
        t = rec.read(a, min(n, a + TIME_CHUNK + 1))[:, 0].astype(float)
        if not np.all(np.isfinite(t)):
            raise DataError(f"{prefix}the time column 't' must be finite; rows {a} to {a + t.shape[0] - 1} are not.")
        scan = scan_stamps(t, a, scan, prefix, rtol)
    return grid_from_scan(scan, prefix, rtol).dt


def map_reduce(
    function: Callable, arguments: Sequence[tuple], reduce: Callable[[object, int, object], object], client=None
):
    """``reduce(total, i, function(*arguments[i]))`` over all ``i`` (``total`` starts as None).

    With a ``dask.distributed`` client the calls run on its workers and are reduced here as
    they finish (one result in memory at a time); without, they run here in order.
    """
    total = None
    if client is None:
        for i, args in enumerate(arguments):
            total = reduce(total, i, function(*args))
        return total
    from distributed import as_completed

    futures = client.map(function, *zip(*arguments), pure=False) if arguments else []
    index = {f.key: i for i, f in enumerate(futures)}
    for future, value in as_completed(futures, loop=client.loop, with_results=True):
        total = reduce(total, index[future.key], value)
        future.release()
    return total
