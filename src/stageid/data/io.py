"""Reading and writing measured records: CSV, NumPy ``.npz`` and MATLAB ``.mat`` files.

Every reader returns a :class:`~stageid.data.table.Table` — named float columns on a uniform time grid — and
``table.experiment(inputs=[...], outputs=[...])`` turns it into an :class:`Experiment`.

Conventions shared by every reader and every error message
-----------------------------------------------------------
* **Rows are data rows counted from 0**: row 0 is the first sample (in a CSV file, the first
  line after the header).  Messages about a CSV cell also give the 1-based file line.
* The column named ``t`` (seconds) is the time axis, not a data column: it must be strictly
  increasing and uniform, and becomes ``Table.t0`` and ``Table.dt`` by the one sample-time
  rule (:mod:`stageid.data.sampling`).  Without it the sample time must be passed as ``ts``.
* Bad input raises a one-line :class:`~stageid.DataError` naming the file, column and row.
* A file whose content would need more memory than is available (a compressed member that
  inflates to gigabytes) is refused before it is read (:class:`~stageid.ResourceError`).
* Writers go through :mod:`stageid.atomic` (whole files only, never over an input of the job);
  column names may not contain commas, so every written column can be selected again.

Formats: :mod:`~stageid.data.csv_format`, :mod:`~stageid.data.npz_format`,
:mod:`~stageid.data.mat_format`; what they share: :mod:`~stageid.data.files`.
"""

from __future__ import annotations

from pathlib import Path

from .._errors import DataError
from ..runtime.heap import prime_heap
from .columns import DEFAULT_TIME_RTOL
from .csv_format import read_csv, write_csv
from .files import PathLike
from .mat_format import read_mat
from .npz_format import read_npz, write_npz
from .table import Table

__all__ = ["Table", "read_table", "read_csv", "read_npz", "read_mat", "write_csv", "write_npz"]


def read_table(path: PathLike, ts: float | None = None, *, time_rtol: float = DEFAULT_TIME_RTOL) -> Table:
    """Read a measured record from ``.csv``, ``.npz`` or ``.mat`` (chosen by extension).

    Parameters
    ----------
    path : str or path-like
        The file.  See :func:`read_csv`, :func:`read_npz` and :func:`read_mat` for each format.
    ts : float, optional
        Sample time in seconds.  Required when the file has no ``t`` column; when it has
        one, ``ts`` must agree with its period (to ``PERIOD_RTOL`` of
        :mod:`stageid.data.sampling`) and is then used as dt.
    time_rtol : float
        Allowed deviation of each stamp from the uniform grid beyond the stamps' own rounding,
        relative to dt (default ``UNIFORM_RTOL`` = 1e-3: clock jitter of a real-time target).

    Returns
    -------
    Table
        Columns other than ``t``; ``dt``/``t0`` from the time column or ``ts``.

    Raises
    ------
    DataError
        Unknown extension, missing/empty file, wrong content for the extension, NaN/inf
        (``"column 'y2' has NaN at row 17"``), non-numeric cells, unequal column lengths,
        duplicate names, a time column that is not strictly increasing and uniform, or no
        time information at all.  Rows are data rows counted from 0.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from stageid.data import write_csv, read_table
    >>> path = os.path.join(tempfile.mkdtemp(), "step.csv")
    >>> _ = write_csv(path, {"u": np.ones(5), "y": np.arange(5.0)}, dt=0.01)
    >>> table = read_table(path)
    >>> table.names, table.dt
    (('u', 'y'), 0.01)
    >>> table.experiment(inputs=["u"], outputs=["y"]).n_samples
    5
    """
    suffix = Path(path).suffix.lower()
    # before the reader's temporaries: freed, they then stay in the heap for the fit that
    # usually follows instead of being faulted in again (stageid._heap)
    prime_heap()
    readers = {".csv": read_csv, ".npz": read_npz, ".mat": read_mat}
    if suffix not in readers:
        raise DataError(f"file '{Path(path).name}' has extension '{suffix}'; expected one of .csv, .npz, .mat.")
    return readers[suffix](path, ts=ts, time_rtol=time_rtol)
