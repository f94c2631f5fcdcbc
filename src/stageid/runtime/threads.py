"""One BLAS thread inside the estimators' fits.

The fits solve many small and medium linear problems (a few hundred unknowns at most).
OpenBLAS's thread pool does not pay for itself there, and on a loaded machine its waiting
threads cost several times the work itself (figures in ``benchmarks/RESULTS-closedloop.md``,
"One BLAS thread inside the fits").  :func:`single_blas_thread` wraps a fit so that BLAS/LAPACK use one thread
while it runs and the caller's setting is restored afterwards.

Set the environment variable ``STAGEID_BLAS_THREADS`` to a positive number to use that
many threads instead, or to ``0`` to leave the pool as it is.
"""

from __future__ import annotations

import functools
import os
import sys
from collections.abc import Callable
from typing import Any, TypeVar

from .heap import prime_heap

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
