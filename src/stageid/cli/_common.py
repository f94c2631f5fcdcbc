"""Helpers shared by the ``stageid`` commands: name lists, reading experiments, safe outputs.

Rules every command follows: bad input raises a :class:`~stageid.StageIdError` (or
``click.UsageError``); ``main`` turns it into one line on stderr and exit code 2. Outputs
are written through :func:`atomic_output` so a failed command never leaves a file behind.

Output files, one rule for every verb: check ``-o`` with :func:`check_output` *before any
work* (its extension picks the format, its directory must exist, ``-`` is refused), then
write with :func:`write_table_output` (tables: ``.csv`` or ``.npz``) or
:func:`write_model_output` (models: ``.json``).  Report folders: :func:`check_output_folder`.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

import click

from .._errors import DataError

__all__ = [
    "split_names",
    "read_experiments",
    "read_table_checked",
    "atomic_output",
    "check_output",
    "check_output_folder",
    "write_table_output",
    "write_model_output",
    "TABLE_SUFFIXES",
    "MODEL_SUFFIXES",
    "progress",
    "is_interactive",
]

#: Extensions of table outputs (signals, simulated records, frequency responses), by format.
TABLE_SUFFIXES = (".csv", ".npz")
#: Extensions of model outputs (stageid.lti/1 and the hysteresis formats are JSON).
MODEL_SUFFIXES = (".json",)


def split_names(text: str | None, option: str) -> tuple[str, ...] | None:
    """``"A,B, C"`` -> ``("A", "B", "C")``; ``None`` stays None. Empty items are an error."""
    if text is None:
        return None
    names = tuple(s.strip() for s in text.split(","))
    if not names or any(not s for s in names):
        raise click.UsageError(f"{option} must be a comma-separated list of column names; got {text!r}.")
    return names


# Data loggers often store time stamps in single precision: their steps scatter by ~1e-4 of dt
# (the dSPACE and EMPS records in shared/data). A missing or repeated sample is still a
# deviation of 100 % and is rejected.
CLI_TIME_RTOL = 1e-3


def read_table_checked(path: str | os.PathLike[str], ts: float | None):
    """Read a CSV/NPZ/MAT file into a :class:`~stageid.data.io.Table` (``ts`` when no ``t`` column).

    The time axis must be uniform to ``CLI_TIME_RTOL`` of the sample time.
    """
    from ..data.io import read_table

    return read_table(path, ts=ts, time_rtol=CLI_TIME_RTOL)


def read_experiments(paths: Sequence[str], inputs: Sequence[str], outputs: Sequence[str], ts: float | None):
    """One :class:`~stageid.data.Experiment` per file, all checked to share dt and channels."""
    from ..data import as_experiments

    exps = []
    for p in paths:
        table = read_table_checked(p, ts)
        exps.append(table.experiment(inputs=list(inputs), outputs=list(outputs), name=Path(p).name))
    return as_experiments(exps)


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it into place only if the block succeeds.

    Example: ``with atomic_output(out) as tmp: write_csv(tmp, ...)``. Directories work too
    (the caller creates files inside the yielded folder).
    """
    target = Path(path)
    _check_parent(target)
    parent = target.parent if str(target.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=target.suffix or ".tmp", dir=parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        from ..models.serialization import _default_mode

        if tmp_path.exists():
            os.chmod(tmp_path, _default_mode())
        os.replace(tmp_path, target)
    finally:
        tmp_path.unlink(missing_ok=True)


def _check_parent(target: Path) -> None:
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise DataError(f"cannot write '{target}': directory '{parent}' does not exist.")


def check_output(path: str | os.PathLike[str], kind: str) -> Path:
    """Check an ``-o`` path before any work is done; returns it as a Path.

    Parameters
    ----------
    path : str or path-like
        The output file.
    kind : {"table", "model"}
        A table is written as CSV or NPZ by its extension (:data:`TABLE_SUFFIXES`); a model
        as JSON (:data:`MODEL_SUFFIXES`).

    Raises
    ------
    DataError
        ``-`` (standard output is not supported), an extension that does not match the
        kind, a missing directory, or a path that is an existing directory.

    Examples
    --------
    >>> from stageid.cli._common import check_output
    >>> check_output("fr.npz", "table").suffix
    '.npz'
    >>> check_output("fr.mat", "table")
    Traceback (most recent call last):
    ...
    stageid._errors.DataError: output 'fr.mat' has extension '.mat'; expected .csv or .npz for a table.
    """
    if kind not in ("table", "model"):
        raise ValueError(f"kind must be 'table' or 'model'; got {kind!r}.")
    allowed = TABLE_SUFFIXES if kind == "table" else MODEL_SUFFIXES
    if str(path) == "-":
        raise DataError(
            f"-o '-' (standard output) is not supported; expected a file name ending in {' or '.join(allowed)}."
        )
    target = Path(path)
    suffix = target.suffix.lower()
    if suffix not in allowed:
        shown = f"extension '{suffix}'" if suffix else "no extension"
        raise DataError(f"output '{target}' has {shown}; expected {' or '.join(allowed)} for a {kind}.")
    _check_parent(target)
    if target.is_dir():
        raise DataError(f"cannot write '{target}': it is a directory; expected a file name.")
    return target


def check_output_folder(path: str | os.PathLike[str]) -> Path:
    """Check a report folder (``--out``/``--report``) before any work: its parent must exist.

    Raises
    ------
    DataError
        A missing parent directory, ``-``, or an existing file at ``path``.
    """
    if str(path) == "-":
        raise DataError("a report folder cannot be '-' (standard output); expected a folder name.")
    target = Path(path)
    _check_parent(target)
    if target.exists() and not target.is_dir():
        raise DataError(f"cannot write a report into '{target}': it is a file; expected a folder.")
    return target


def write_table_output(path: str | os.PathLike[str], data, *, dt: float | None = None, t0: float | None = None) -> Path:
    """Write a table to ``path`` as CSV or NPZ, chosen by its extension, atomically.

    ``data`` and ``dt``/``t0`` as :func:`stageid.data.write_csv`.  Raises :class:`DataError`
    as :func:`check_output` and the writers.
    """
    from ..data.io import write_csv, write_npz

    target = check_output(path, "table")
    writer = write_npz if target.suffix.lower() == ".npz" else write_csv
    return writer(target, data, dt=dt, t0=t0)


def write_model_output(path: str | os.PathLike[str], model) -> Path:
    """Save a model as JSON at ``path`` atomically (checked as :func:`check_output` ``"model"``)."""
    from ..models.serialization import save_model

    target = check_output(path, "model")
    with atomic_output(target) as tmp:
        save_model(model, tmp)
    return target


def is_interactive() -> bool:
    """True when stderr is a terminal (progress bars only make sense there)."""
    import sys

    return sys.stderr.isatty()


def progress(total: int | None = None, desc: str = "", unit: str = "it"):
    """A tqdm progress bar on stderr, silent when stderr is not a terminal."""
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=not is_interactive(), leave=False)
