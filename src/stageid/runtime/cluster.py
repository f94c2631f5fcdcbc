"""Dask clusters for work that outgrows one process: a batch of jobs, a record larger than memory.

:func:`dask_client` gives a ``dask.distributed.Client`` either on a running scheduler
(``tcp://HOST:PORT``, as ``--scheduler`` takes it) or on a local cluster of worker processes
started for the duration of a ``with`` block.  Everything distributed in stageid goes through
it, so the connection rules live in one place: an unreachable scheduler is a one-line
:class:`~stageid._errors.ClusterError` within ``timeout`` seconds, never a hang or a traceback.

Examples
--------
>>> from stageid.runtime.cluster import dask_client
>>> with dask_client(n_workers=1) as client:  # doctest: +SKIP
...     client.submit(sum, [1, 2]).result()
3
"""

from __future__ import annotations

import contextlib
import os
import re
import socket
import warnings
from collections.abc import Iterator
from typing import Any
from urllib.parse import urlsplit

from .._errors import ClusterError, ParameterError

__all__ = ["dask_client", "check_scheduler_address", "DEFAULT_TIMEOUT", "LOCAL_WORKER_CONFIG"]

#: Seconds to wait for a scheduler before giving up (the batch contract: an error within 10 s).
DEFAULT_TIMEOUT = 8.0

#: Dask settings of the local cluster's workers, for jobs of seconds of pure computation.  The
#: nanny sets ``MALLOC_TRIM_THRESHOLD_`` by default, and any explicit glibc threshold freezes
#: malloc's adaptive thresholds: every fit then faults its temporaries' pages in again; the
#: statistical profiler samples the running task every 10 ms; the event-loop health check (20 ms)
#: and memory monitor (100 ms) take the GIL from the fit, which on a loaded machine waits for a
#: CPU each time.  Together 1.5-3x slower fits on a worker than in-process, measured in
#: benchmarks/RESULTS-dask.md.  Workers started elsewhere should get the same settings
#: (``dask worker`` reads them from its YAML configuration).
LOCAL_WORKER_CONFIG = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.worker.memory.monitor-interval": "1s",
}

_ADDRESS = re.compile(r"^(tcp|tls|inproc|ucx|ws|wss)://[^\s/]+(:\d+)?/?$")


def check_scheduler_address(address: str) -> str:
    """The scheduler address, or a :class:`ParameterError` naming the expected form."""
    if not isinstance(address, str) or not _ADDRESS.match(address.strip()):
        raise ParameterError(f"a scheduler address must look like tcp://HOST:PORT; got {address!r}.")
    return address.strip()


@contextlib.contextmanager
def dask_client(
    scheduler: str | None = None,
    *,
    n_workers: int | None = None,
    timeout: float = DEFAULT_TIMEOUT,
) -> Iterator[Any]:
    """A ``dask.distributed.Client`` on ``scheduler``, or on a local cluster of processes.

    Parameters
    ----------
    scheduler : str, optional
        ``tcp://HOST:PORT`` of a running scheduler.  ``None`` starts a local cluster of
        ``n_workers`` single-threaded worker processes on 127.0.0.1 (closed on exit).
    n_workers : int, optional
        Local workers; default the machine's CPU count (at least 1).
    timeout : float
        Seconds to wait for the scheduler.

    Raises
    ------
    ClusterError
        The scheduler cannot be reached, or the local cluster cannot start.
    """
    # Imported here: dask.distributed takes ~0.5 s to import, and most commands never need it.
    import dask
    from distributed import Client, LocalCluster

    if scheduler is not None:
        address = check_scheduler_address(scheduler)
        _probe(address, timeout)
        try:
            client = Client(address, timeout=f"{timeout}s", set_as_default=False)
        # Anything can come back from an address that is not a Dask scheduler (a proxy's reply
        # parsed as a frame length once asked for exabytes), so every failure here is "unreachable".
        except Exception as exc:
            raise ClusterError(f"cannot reach the Dask scheduler at {address} within {timeout:g} s ({exc}).") from None
        try:
            yield client
        finally:
            client.close()
        return

    n = n_workers if n_workers is not None else max(1, os.cpu_count() or 1)
    try:
        with dask.config.set(LOCAL_WORKER_CONFIG), warnings.catch_warnings():
            # the scheduler's HTTP routes move off a busy 8787 by themselves; no dashboard is used
            warnings.filterwarnings("ignore", message="Port .* is already in use", category=UserWarning)
            cluster = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address=None,
                silence_logs=40,
            )
    except (OSError, TimeoutError, RuntimeError) as exc:
        raise ClusterError(f"cannot start a local Dask cluster of {n} workers ({exc}).") from None
    try:
        with Client(cluster, set_as_default=False) as client:
            yield client
    finally:
        cluster.close()


def _probe(address: str, timeout: float) -> None:
    """Fail fast on a refused or silent TCP address, before Dask's own retries (and a half-made
    ``Client`` whose finaliser prints to stderr) get involved."""
    parts = urlsplit(address)
    if parts.scheme != "tcp" or parts.port is None:
        return
    try:
        with socket.create_connection((parts.hostname, parts.port), timeout=timeout):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise ClusterError(f"cannot reach the Dask scheduler at {address} ({reason}).") from None
