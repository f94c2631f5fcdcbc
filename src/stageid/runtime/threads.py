"""One BLAS thread inside the estimators' fits; independent pieces of work spread over the CPUs.

The fits solve many small and medium linear problems (a few hundred unknowns at most).
OpenBLAS's thread pool does not pay for itself there, and on a loaded machine its waiting
threads cost several times the work itself (figures in ``benchmarks/RESULTS-closedloop.md``,
"One BLAS thread inside the fits").  :func:`single_blas_thread` wraps a fit so that BLAS/LAPACK use one thread
while it runs and the caller's setting is restored afterwards.

Set the environment variable ``STAGEID_BLAS_THREADS`` to a positive number to use that
many threads instead, or to ``0`` to leave the pool as it is.

:func:`map_in_threads` runs independent pieces of work (e.g. the FFTs of a record's channels,
which numpy runs without the GIL) on several threads.  By default on one: the threads hand the
GIL back and forth between the pieces, and on a machine whose CPUs are busy with other work a
thread descheduled while holding it stalls the others, so two threads measured slower than one
there (``benchmarks/RESULTS-bla.md``).  Set ``STAGEID_THREADS`` to a positive number to use that
many where CPUs are idle.
"""

from __future__ import annotations

import functools
import itertools
import os
import sys
from collections.abc import Callable
from typing import Any, TypeVar

from .heap import prime_heap

__all__ = ["single_blas_thread", "map_in_threads", "default_threads"]

F = TypeVar("F", bound=Callable[..., Any])


def _limit() -> int | None:
    raw = os.environ.get("STAGEID_BLAS_THREADS", "1").strip()
    try:
        n = int(raw)
    except ValueError:
        return 1
    return None if n <= 0 else n


_controller: tuple[bool, Any] | None = None


def _blas_controller() -> Any:
    """A ``threadpoolctl.ThreadpoolController`` over the BLAS libraries loaded now.

    Building one scans the process's shared libraries, far slower than a limit through a kept
    controller, which matters for ``HankelMAPResult.update`` on short chunks; it is kept and
    built again once scipy (whose wheels bring their own OpenBLAS) has been imported since.
    """
    global _controller
    scipy_loaded = "scipy.linalg" in sys.modules
    if _controller is None or _controller[0] != scipy_loaded:
        from threadpoolctl import ThreadpoolController

        _controller = (scipy_loaded, ThreadpoolController())
    return _controller[1]


def single_blas_thread(fn: F) -> F:
    """Run ``fn`` with BLAS limited to ``STAGEID_BLAS_THREADS`` threads (default 1)."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        prime_heap()  # the other half of a fit's environment: see stageid.runtime.heap
        n = _limit()
        if n is None:
            return fn(*args, **kwargs)
        with _blas_controller().limit(limits=n, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


def default_threads() -> int:
    """``STAGEID_THREADS`` when it is a positive number, else 1 (see the module docstring)."""
    raw = os.environ.get("STAGEID_THREADS", "").strip()
    return int(raw) if raw.isdigit() and int(raw) > 0 else 1


def map_in_threads(fn: Callable[[int], Any], n_items: int, n_threads: int | None = None) -> list[Any]:
    """``[fn(i) for i in range(n_items)]`` on up to ``n_threads`` threads (this one included).

    ``n_threads`` None means :func:`default_threads`; 1 (or a single item) runs in this thread
    alone.  Items are handed out one at a time, so a thread the machine holds back takes fewer.
    Every item runs even when one fails; the exception of the first failing item (in item
    order) is raised after all threads have finished, so the caller sees what one thread would.
    """
    import threading

    n = min(n_items, default_threads() if n_threads is None else max(1, n_threads))
    results: list[Any] = [None] * n_items
    errors: dict[int, BaseException] = {}
    counter = itertools.count()  # next() on a count is atomic under the GIL: a lock-free queue

    def work() -> None:
        for i in iter(counter.__next__, None):
            if i >= n_items:
                return
            try:
                results[i] = fn(i)
            except BaseException as exc:  # re-raised in the caller's thread, in item order
                errors[i] = exc

    helpers = [threading.Thread(target=work, daemon=True) for _ in range(n - 1)]
    for t in helpers:
        t.start()
    work()
    for t in helpers:
        t.join()
    if errors:
        raise errors[min(errors)]
    return results
