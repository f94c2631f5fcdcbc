"""Chunked records on the command line: ``.h5``/``.hdf5``, Zarr folders and ``.npy`` inputs, and ``--scheduler``.

``identify statespace`` and ``frf`` hand a record that :func:`stageid.data.chunked.is_chunked_path`
recognises to the chunked estimators instead of reading it into memory; ``--scheduler
tcp://HOST:PORT`` computes its statistics on that Dask cluster (without it: here, chunk by chunk).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence

import click

__all__ = ["scheduler_option", "chunked_record", "statistics_client", "fit_on_chunks"]

scheduler_option = click.option(
    "--scheduler",
    default=None,
    metavar="tcp://HOST:PORT",
    help="Dask scheduler computing the statistics of a chunked record (.h5, .hdf5, .npy, Zarr folder) on its "
    "workers, which read the file at the same path; default: here, chunk by chunk.",
)


def chunked_record(
    paths: Sequence[str],
    inputs: Sequence[str],
    outputs: Sequence[str],
    ts: float | None,
    what: str,
    scheduler: str | None,
):
    """The :class:`~stageid.data.chunked.ChunkedRecord` when DATA is one chunked file or folder,
    else None.  UsageError: chunked inputs with others, an option ``what`` that needs the
    records in memory, or a ``scheduler`` for in-memory records (it would be ignored)."""
    from ..data.chunked import is_chunked_path, open_chunked
    from ..data.sampling import UNIFORM_RTOL

    chunked = [p for p in paths if is_chunked_path(p)]
    if not chunked:
        if scheduler is not None:
            raise click.UsageError(
                "--scheduler computes the statistics of a chunked record (.h5, .hdf5, .npy, Zarr); "
                "got records read into memory."
            )
        return None
    if len(paths) > 1:
        raise click.UsageError(
            f"a chunked record ({chunked[0]}) is identified on its own; got {len(paths)} DATA arguments, expected one."
        )
    from ._common import current_trim

    if current_trim() != (None, None):
        what = what or "--start/--stop"
    if what:
        raise click.UsageError(f"{what} needs the records in memory; chunked inputs (.h5, .hdf5, .npy, Zarr) do not.")
    return open_chunked(paths[0], inputs, outputs, ts, UNIFORM_RTOL)


@contextlib.contextmanager
def statistics_client(scheduler: str | None) -> Iterator[object]:
    """A Dask client on ``scheduler``, or None (statistics computed in this process)."""
    if scheduler is None:
        yield None
        return
    from ..runtime.cluster import dask_client

    with dask_client(scheduler) as client:
        yield client


def fit_on_chunks(est, record, scheduler: str | None):
    """``est`` (a HankelMAP) fitted to a chunked record, its statistics here or on ``scheduler``."""
    from ..subspace.chunked_source import fit_chunked

    with statistics_client(scheduler) as client:
        return fit_chunked(est, record, client)
