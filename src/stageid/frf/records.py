"""Records as separate channel arrays, and NPZ files read that way (no table copy).

Welch's spectra need each channel once, segment by segment; copying a long record into a
(n_samples, n_channels) table first (and checking it there) costs more than the spectra
themselves.  :class:`ChannelRecord` holds one 1-D array per channel; :func:`read_npz_record`
reads the named arrays of an ``.npz`` archive directly and checks the time axis, and the
finiteness of the samples is checked segment batch by segment batch while the spectra are
accumulated (:func:`check_finite_batch`).
"""

from __future__ import annotations

import dataclasses
import os
import re
import zipfile
from collections.abc import Sequence

import numpy as np

from .._errors import DataError
from ..data.sampling import check_period, shared_period
from ..data.table import time_column_grid
from ..runtime.heap import prime_heap

__all__ = ["ChannelRecord", "as_channel_records", "read_npz_record", "check_finite_batch"]


@dataclasses.dataclass(frozen=True)
class ChannelRecord:
    """One record: ``channels`` = inputs then outputs, 1-D arrays of one length, sample time ``dt``."""

    channels: tuple[np.ndarray, ...]
    n_inputs: int
    dt: float
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    name: str = ""

    @property
    def n_samples(self) -> int:
        return int(self.channels[0].shape[0])

    @property
    def n_outputs(self) -> int:
        return len(self.channels) - self.n_inputs


def as_channel_records(data) -> tuple[ChannelRecord, ...]:
    """Experiments (one or a sequence, checked by ``as_experiments``) or ChannelRecords as a tuple
    of :class:`ChannelRecord` sharing dt and channel names; experiments' columns are views."""
    from ..data import as_experiments

    items = (data,) if isinstance(data, ChannelRecord) else data
    if isinstance(items, ChannelRecord) or (
        isinstance(items, Sequence) and items and isinstance(items[0], ChannelRecord)
    ):
        recs = tuple(items)
    else:
        recs = tuple(
            ChannelRecord(
                tuple(e.u[:, k] for k in range(e.n_inputs)) + tuple(e.y[:, k] for k in range(e.n_outputs)),
                e.n_inputs,
                float(e.dt),
                tuple(e.input_names),
                tuple(e.output_names),
                e.name or "",
            )
            for e in as_experiments(data)
        )
    dt = shared_period([r.dt for r in recs], [r.name or f"record {i}" for i, r in enumerate(recs)])
    recs = tuple(r if r.dt == dt else dataclasses.replace(r, dt=dt) for r in recs)
    first = recs[0]
    for r in recs[1:]:
        if (r.input_names, r.output_names) != (first.input_names, first.output_names):
            raise DataError("all records must have the same input and output channels.")
    return recs


def check_finite_batch(record: ChannelRecord, batch: np.ndarray, channel: int, start: int, step: int) -> None:
    """Raise DataError naming the column and row of the first NaN/inf in a batch of segments.

    ``batch`` has shape (n_segments, segment) of channel ``channel``, its first segment starting
    at sample ``start``, consecutive segments ``step`` samples apart.
    """
    bad = ~np.isfinite(batch)
    if bad.any():
        s, k = (int(i) for i in np.argwhere(bad)[0])
        names = record.input_names + record.output_names
        what = "NaN" if np.isnan(batch[s, k]) else "inf"
        where = f"{record.name}: " if record.name else ""
        raise DataError(
            f"{where}column '{names[channel]}' has {what} at row {start + s * step + k}; every sample must be finite."
        )


def read_npz_record(
    path: str | os.PathLike[str], inputs: Sequence[str], outputs: Sequence[str], ts: float | None, time_rtol: float
) -> ChannelRecord | None:
    """The named 1-D float arrays of an ``.npz`` archive as a :class:`ChannelRecord`.

    Returns None when the archive does not hold every name as a 1-D float array (the caller
    then reads it through :func:`stageid.data.read_table`, which knows every layout).  The
    time axis ``t`` (when present) must be uniform to ``time_rtol`` of its step and agree
    with ``ts``; without ``t``, ``ts`` is required.

    Raises
    ------
    DataError
        Unequal lengths, a non-uniform or non-increasing time axis, no time information,
        fewer than 2 samples.
    """
    prime_heap()  # the estimates' temporaries reuse freed pages instead of faulting in new ones
    name = os.path.basename(os.fspath(path))
    try:
        fh = open(path, "rb")
    except OSError as exc:
        raise DataError(f"{name}: cannot read the archive ({exc}).") from None
    with fh:
        try:
            archive = np.load(fh, allow_pickle=False)
        except (OSError, ValueError, zipfile.BadZipFile) as exc:
            raise DataError(f"{name}: cannot read the archive ({exc}).") from None
        with archive:
            keys = set(archive.files)
            wanted = list(inputs) + list(outputs)
            if not all(k in keys for k in wanted):
                return None
            members = _Members(fh, archive)
            arrays = [members.get(k) for k in wanted]
            if any(a.ndim != 1 or a.dtype.kind != "f" for a in arrays):
                return None
            t = members.get("t") if "t" in keys else None
    n = arrays[0].shape[0]
    for k, a in zip(wanted, arrays):
        if a.shape[0] != n:
            raise DataError(
                f"{name}: column '{k}' has {a.shape[0]} samples, column '{wanted[0]}' {n}; expected equal lengths."
            )
    if n < 2:
        raise DataError(f"{name}: a record needs at least 2 samples; got {n}.")
    dt = _time_step(t, ts, n, name, time_rtol)
    channels = tuple(a if a.dtype == np.float64 else np.asarray(a, dtype=float) for a in arrays)
    return ChannelRecord(channels, len(inputs), dt, tuple(inputs), tuple(outputs), name)


class _Members:
    """The arrays of one open NPZ archive, memory-mapped when stored uncompressed (``np.savez``).

    A mapped array is read from the page cache segment by segment as the spectra need it,
    instead of being copied whole through the zip reader first.  The file is mapped once and
    every member is a view of that map (a map per member cost more than reading the headers).
    Compressed members and anything but a 1-D array in C order are read the ordinary way.
    """

    def __init__(self, fh, archive) -> None:
        self.fh, self.archive = fh, archive
        self.whole: np.memmap | None = None

    def get(self, key: str) -> np.ndarray:
        """Array ``key``: a view of the mapped file where it can be, else as ``np.load`` reads it."""
        try:
            # np.load has parsed the zip directory already; reopening it per member cost more than the read
            info = self.archive.zip.getinfo(key + ".npy")
            if info.compress_type != zipfile.ZIP_STORED:
                return self.archive[key]
            header = self._header(info.header_offset)
            if header is None:
                return self.archive[key]
            (n,), dtype, offset = header
            if self.whole is None:
                self.whole = np.memmap(self.fh, dtype=np.uint8, mode="r")
            if offset + n * dtype.itemsize > self.whole.size:  # a cut file: the zip reader says what is wrong
                return self.archive[key]
            return self.whole[offset : offset + n * dtype.itemsize].view(dtype)
        except (KeyError, ValueError, OSError, AttributeError, zipfile.BadZipFile):
            return self.archive[key]

    def _header(self, header_offset: int) -> tuple[tuple[int], np.dtype, int] | None:
        """Shape, dtype and data offset of the ``.npy`` member whose local zip header is at
        ``header_offset``; None unless it is a 1-D array in C order of a plain dtype."""
        fh = self.fh
        fh.seek(header_offset)
        local = fh.read(30)  # the local file header: name and extra-field lengths at 26 and 28
        fh.seek(header_offset + 30 + int.from_bytes(local[26:28], "little") + int.from_bytes(local[28:30], "little"))
        version = np.lib.format.read_magic(fh)
        if version not in ((1, 0), (2, 0)):
            return None
        parsed = _plain_header(fh, version)
        if parsed is None:
            reader = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
            parsed = reader(fh)
        shape, fortran, dtype = parsed
        if fortran or dtype.hasobject or len(shape) != 1:
            return None
        return shape, dtype, fh.tell()


#: The header ``np.save`` writes for a 1-D array of a plain dtype (the common case, read without ``ast``).
_PLAIN_HEADER = re.compile(
    r"\{'descr': '([<>|=]?[fiuc]\d+)', 'fortran_order': (True|False), 'shape': \((\d+),\), \}\s*"
)


def _plain_header(fh, version: tuple[int, int]) -> tuple[tuple[int], bool, np.dtype] | None:
    """Shape, order and dtype of a 1-D array's ``.npy`` header parsed directly; None (the file
    position restored) for any other header, which numpy's own reader then parses.

    numpy's reader evaluates the header with ``ast.literal_eval``: a fifth of the time of reading
    a few hundred memory-mapped members.
    """
    start = fh.tell()
    size_bytes = 2 if version == (1, 0) else 4
    size = int.from_bytes(fh.read(size_bytes), "little")
    match = _PLAIN_HEADER.fullmatch(fh.read(size).decode("latin1"))
    if match is None:
        fh.seek(start)
        return None
    return (int(match.group(3)),), match.group(2) == "True", np.dtype(match.group(1))


def _time_step(t: np.ndarray | None, ts: float | None, n: int, name: str, rtol: float) -> float:
    """The period of the record by the sample-time rule (``ts`` without a time column)."""
    if t is None:
        if ts is None:
            raise DataError(f"{name}: no time column 't'; give the sample time as `ts=`.")
        return check_period(ts, "ts", f"{name}: ")
    if t.dtype != np.float64 or not t.flags.aligned:
        # a mapped member lies wherever the zip put it, and numpy's loops on unaligned stamps
        # cost more than an aligned copy and the check together
        t = np.array(t, dtype=float)
    if t.ndim != 1 or t.shape[0] != n or not np.all(np.isfinite(t)):
        raise DataError(f"{name}: the time column 't' must be {n} finite values.")
    return time_column_grid(t, f"{name}: ", ts, rtol).dt
