"""Helpers shared by the ``stageid`` commands: name lists, reading experiments, safe outputs.

Rules every command follows: bad input raises a :class:`~stageid.StageIdError` (or
``click.UsageError``); ``main`` turns it into one line on stderr and exit code 2. Outputs
are written through :func:`atomic_output` so a failed command never leaves a file behind.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator, Sequence

import click

from .._errors import DataError

__all__ = ["split_names", "read_experiments", "read_table_checked", "atomic_output", "progress", "is_interactive"]


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
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise DataError(f"cannot write '{target}': folder '{parent}' does not exist.")
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


def is_interactive() -> bool:
    """True when stderr is a terminal (progress bars only make sense there)."""
    import sys

    return sys.stderr.isatty()


def progress(total: int | None = None, desc: str = "", unit: str = "it"):
    """A tqdm progress bar on stderr, silent when stderr is not a terminal."""
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=not is_interactive(), leave=False)
