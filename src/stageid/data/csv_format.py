"""CSV records: a header row of column names (``name [unit]`` allowed), one line per sample.

Read by :func:`read_csv`, written by :func:`write_csv` so that every float64 and every name
reads back unchanged.  Conventions shared with the other formats: :mod:`stageid.data.io`.
"""

from __future__ import annotations

import csv
import io
import re
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._errors import DataError
from ..atomic import atomic_write
from ..checks import shown
from ..runtime.resources import require_memory
from .columns import DEFAULT_TIME_RTOL, TIME_COLUMN, check_unique_names, file_prefix
from .experiment import Experiment
from .files import SNIFF_BYTES, PathLike, looks_like, open_checked, resolve_ts, table_for_writing
from .table import Table, assemble_table

if TYPE_CHECKING:  # pragma: no cover
    from numpy.typing import ArrayLike

__all__ = ["read_csv", "write_csv", "UNIT_RE", "is_number"]

#: A header cell ``name [unit]``.
UNIT_RE = re.compile(r"^(?P<name>.*\S)\s+\[(?P<unit>[^\[\]]*)\]$")


def read_csv(path: PathLike, ts: float | None = None, *, time_rtol: float = DEFAULT_TIME_RTOL) -> Table:
    """Read a CSV file with a header row of column names.

    The delimiter is ``,`` (or tab / ``;`` when the header uses it and has no comma).
    Header cells may carry a unit as ``name [unit]``.  Empty lines are skipped; every other
    line must have one number per header column.  Parameters, returns and errors as
    :func:`read_table`; non-numeric cells give ``"column 'u' row 5: 'abc' is not a number"``
    followed by the file line.

    Examples
    --------
    >>> import tempfile, os
    >>> from stageid.data.io import read_csv
    >>> path = os.path.join(tempfile.mkdtemp(), "x.csv")
    >>> with open(path, "w") as fh:
    ...     _ = fh.write("t,V [V],y [um]\\n0,1,2\\n0.5,3,4\\n")
    >>> table = read_csv(path)
    >>> table.names, table.units, table.dt
    (('V', 'y'), ('V', 'um'), 0.5)
    """
    p, head = open_checked(path)
    where = file_prefix(p.name)
    ts = resolve_ts(ts, time_rtol, where)
    delimiter, names, units = _read_header(p, head, where)
    _require_memory_for_cells(p, delimiter)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="loadtxt: input contained no data", category=UserWarning)
            values = np.loadtxt(
                p,
                delimiter=delimiter,
                skiprows=1,
                dtype=float,
                ndmin=2,
                comments=None,
                quotechar='"',
                encoding="utf-8-sig",
            )
    except (ValueError, UnicodeDecodeError) as exc:
        _raise_first_bad_cell(p, delimiter, names)
        raise DataError(f"{where}could not parse the numbers: {exc}") from None
    if values.shape[0] == 0:
        raise DataError(f"file '{p.name}' has a header but no data rows.")
    if values.shape[1] != len(names):
        raise DataError(
            f"{where}the header has {len(names)} columns but the data rows have {values.shape[1]} fields; expected one number per header column."
        )
    return assemble_table(p.name, names, values, units, ts, time_rtol)


def _read_header(p: Path, head: bytes, where: str) -> tuple[str, list[str], list[str]]:
    """The delimiter, names and units of the header line (read whole, however long)."""
    if b"\x00" in head:
        raise DataError(f"file '{p.name}' is not a text CSV file: it contains binary data{looks_like(head)}.")
    if b"\n" not in head and len(head) == SNIFF_BYTES:  # a header longer than the sniffed bytes
        with open(p, "rb") as fh:
            head = fh.readline()
    try:
        head_text = head.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 4:  # not merely a multi-byte character cut by the sniff window
            raise DataError(f"file '{p.name}' is not a UTF-8 text CSV file{looks_like(head)}.") from None
        head_text = head[: exc.start].decode("utf-8-sig")
    first_line = head_text.splitlines()[0] if head_text.strip() else ""
    if not first_line.strip():
        raise DataError(f"file '{p.name}' has no header row; expected column names in the first line.")
    delimiter = "," if "," in first_line else "\t" if "\t" in first_line else ";" if ";" in first_line else ","
    raw_names = next(csv.reader([first_line], delimiter=delimiter))
    names, units = _parse_header(raw_names, where)
    if all(is_number(n) for n in names):
        raise DataError(
            f"file '{p.name}' has no header row; expected column names in the first line, got {shown(first_line, 60)}."
        )
    return delimiter, names, units


def _require_memory_for_cells(p: Path, delimiter: str) -> None:
    """Refuse a file whose numbers would not fit in memory, counting its cells before parsing.

    Each cell becomes a float64, held about three times (parse buffer, table, experiment).
    Small files are let through without counting.
    """
    size = p.stat().st_size
    if size < 64 * 2**20:
        return
    sep, newline = delimiter.encode(), b"\n"
    cells = 0
    with open(p, "rb") as fh:
        while chunk := fh.read(16 * 2**20):
            cells += chunk.count(sep) + chunk.count(newline)
    require_memory(24.0 * cells, f"reading the {cells:.3g} cells of '{p.name}'")


def _parse_header(raw: Sequence[str], where: str) -> tuple[list[str], list[str]]:
    names, units = [], []
    for i, cell in enumerate(raw):
        cell = cell.strip()
        m = UNIT_RE.match(cell)
        name, unit = (m.group("name"), m.group("unit").strip()) if m else (cell, "")
        if not name:
            raise DataError(f"{where}header column {i} is empty; every column needs a name.")
        names.append(name)
        units.append(unit)
    check_unique_names(names, where)
    return names, units


def is_number(text: str) -> bool:
    """True when ``text`` parses as a float (a header of numbers is no header)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def _raise_first_bad_cell(p: Path, delimiter: str, names: Sequence[str]) -> None:
    """Slow path after np.loadtxt failed: find the first offending cell and raise for it."""
    where = file_prefix(p.name)
    try:
        fh = open(p, encoding="utf-8-sig", newline="")
    except OSError:
        return
    with fh:
        line_no = 1
        row = -1
        reader = csv.reader(fh, delimiter=delimiter, quotechar='"')
        try:
            next(reader)  # header
            for fields in reader:
                line_no = reader.line_num
                if not fields:
                    continue  # empty line: skipped, as np.loadtxt does
                row += 1
                if len(fields) != len(names):
                    raise DataError(
                        f"{where}row {row} (file line {line_no}) has {len(fields)} fields; expected {len(names)} (one per header column)."
                    )
                for name, cell in zip(names, fields):
                    text = cell.strip()
                    if not is_number(text) or "_" in text:
                        shown = "empty cell" if not text else repr(text[:40])
                        raise DataError(
                            f"column '{name}' row {row}: {shown} is not a number (file '{p.name}', line {line_no}; data rows counted from 0)."
                        )
        except UnicodeDecodeError:
            raise DataError(
                f"file '{p.name}' is not a UTF-8 text CSV file: undecodable bytes after file line {line_no}."
            ) from None
        except csv.Error as exc:
            raise DataError(f"{where}malformed CSV at file line {line_no}: {exc}.") from None


# ====================================================================== writing
def _write_rows(fh: io.TextIOBase, values: np.ndarray, block: int = 65536) -> None:
    """Write rows as ``'%.17g'`` (exact for float64), formatted a block at a time (np.savetxt goes row by row)."""
    row_format = ",".join(["%.17g"] * values.shape[1]) + "\n"
    for start in range(0, values.shape[0], block):
        rows = values[start : start + block].tolist()
        fh.write("".join([row_format % tuple(r) for r in rows]))


def _header_line(header: Sequence[str]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(header)
    return buf.getvalue()


def _check_header_reads_back(line: str, header: Sequence[str]) -> None:
    """Parse ``line`` the way :func:`read_csv` parses a header; raise unless it gives ``header`` back.

    The reader picks the delimiter from the header line (``,``, else tab, else ``;``), so a
    name holding a tab or ``;`` in a one-column file, a quote, a line break or a leading byte
    order mark would come back as different columns.
    """
    first = line.rstrip("\n")
    delimiter = "," if "," in first else "\t" if "\t" in first else ";" if ";" in first else ","
    problem = ""
    if "\n" in first or "\r" in first:
        problem = "it contains a line break"
    elif first.startswith("\ufeff"):
        problem = "it starts with a byte order mark"
    else:
        parsed = next(csv.reader([first], delimiter=delimiter))
        if [c.strip() for c in parsed] != list(header) or (delimiter != "," and len(header) > 1):
            problem = f"the header would be split at {delimiter!r} into {len(parsed)} column(s)"
    if problem:
        bad = next((h for h in header if any(c in h for c in ',;\t"\n\r\ufeff')), header[0])
        raise DataError(
            f"column name {bad!r} would not read back from CSV ({problem}); expected names without "
            f"tabs, ';', quotes or line breaks."
        )


def write_csv(
    path: PathLike,
    data: Mapping[str, ArrayLike] | Table | Experiment,
    *,
    dt: float | None = None,
    t0: float | None = None,
) -> Path:
    """Write columns to a CSV file atomically, readable back by :func:`read_csv`.

    Layout: one header row (``name`` or ``name [unit]``), then one line per sample; the
    time column ``t`` comes first whenever the sample time is known.  Numbers are written
    with ``'%.17g'`` so every float64 reads back bit-for-bit.  The file is written to a
    temporary file in the same directory and renamed into place, so a crash never leaves a
    half-written file under ``path``.

    Parameters
    ----------
    path : str or path-like
        Destination (overwritten).
    data : mapping of str to array_like of shape (n_samples,), or Table, or Experiment
        The columns (an Experiment writes inputs then outputs, with units).  A mapping may
        contain a ``t`` column, which is checked and used as the time axis.
    dt, t0 : float, optional
        Sample time and first time stamp for a mapping without ``t`` (then ``t`` is written
        as ``t0 + dt * k``).  Not allowed with a Table or Experiment, which carry their own.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    DataError
        Non-finite values, unequal lengths, non-numeric or non-column arrays, duplicate
        names, names that would not read back unchanged, or a missing directory.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from stageid.data import write_csv
    >>> path = os.path.join(tempfile.mkdtemp(), "x.csv")
    >>> _ = write_csv(path, {"u": [0.1, 0.2]}, dt=0.5)
    >>> open(path).read().splitlines()
    ['t,u', '0,0.10000000000000001', '0.5,0.20000000000000001']
    """
    table = table_for_writing(data, dt, t0)
    for n in table.names:
        if UNIT_RE.match(n):
            raise DataError(f"column name '{n}' would be read back as a name with a unit; rename it.")
    if all(is_number(n) for n in table.names):
        raise DataError(
            f"column names {list(table.names)} all look like numbers and would not be read back as a header; rename them."
        )
    header = [n if not u else f"{n} [{u}]" for n, u in zip(table.names, table.units)]
    values = table.values
    if table.dt is not None:
        header.insert(0, TIME_COLUMN)
        values = np.column_stack([table.time, values])
    header_line = _header_line(header)
    _check_header_reads_back(header_line, header)

    def write(fh: io.TextIOBase) -> None:
        fh.write(header_line)
        _write_rows(fh, values)

    return atomic_write(path, write, binary=False)
