"""Memory and work guards: estimate what a request needs before doing it.

A request that would need more memory than the machine can give (a horizon of 2400 on a 3x3
record, an NPZ member that inflates to 16 GB) is refused up front with one line naming what it
would need and what is available, instead of being killed by the kernel half way.  Every
reader and estimator that allocates in proportion to a user's setting calls
:func:`require_memory` with its own estimate; the available memory is the least of the
kernel's ``MemAvailable``, the address-space limit (``ulimit -v``) and the
``STAGEID_MEMORY_LIMIT`` environment variable (bytes, or with a K/M/G suffix).
"""

from __future__ import annotations

import os
import resource

from .._errors import ResourceError

__all__ = ["available_memory", "require_memory", "format_bytes", "require_work"]

#: Share of the available memory one request may claim: numpy temporaries and the rest of the
#: process need the remainder.
MEMORY_SHARE = 0.8


def _env_limit() -> float:
    text = os.environ.get("STAGEID_MEMORY_LIMIT", "").strip().upper()
    if not text:
        return float("inf")
    scale = {"K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}.get(text[-1], 1)
    try:
        value = float(text[:-1] if text[-1] in "KMGT" else text) * scale
    except ValueError:
        return float("inf")
    return value if value > 0 else float("inf")


def available_memory() -> float:
    """Bytes this process may still allocate (an estimate; ``inf`` when nothing says)."""
    limits = [_env_limit()]
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    limits.append(float(line.split()[1]) * 1024)
                    break
    except OSError:
        pass
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft not in (resource.RLIM_INFINITY, -1):
        try:
            with open("/proc/self/statm") as fh:
                used = float(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        except (OSError, ValueError):
            used = 0.0
        limits.append(max(float(soft) - used, 0.0))
    return min(limits)


def format_bytes(n: float) -> str:
    """``1.5 GB``, ``320 MB``: sizes in messages."""
    for unit, size in (("TB", 2**40), ("GB", 2**30), ("MB", 2**20), ("kB", 2**10)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} bytes"


def require_memory(n_bytes: float, what: str) -> None:
    """Raise :class:`~stageid.ResourceError` when ``what`` would need more than is available.

    ``what`` completes "``what`` would need ..." (e.g. "the horizon 2400 on 3 inputs and 3
    outputs"); the message ends with a hint when the caller adds one after a semicolon.
    """
    available = available_memory() * MEMORY_SHARE
    if n_bytes > available:
        raise ResourceError(
            f"{what} would need about {format_bytes(n_bytes)} of memory; {format_bytes(available)} is available."
        )


def require_work(n_operations: float, limit: float, what: str, hint: str) -> None:
    """Raise :class:`~stageid.ResourceError` when ``what`` would take more than ``limit`` operations.

    For requests whose cost grows faster than their memory (a creep bank of 2000 time
    constants), where running for hours is no better than refusing; ``hint`` says what to ask
    for instead.
    """
    if n_operations > limit:
        raise ResourceError(f"{what} would take about {n_operations:.2g} operations (limit {limit:.2g}); {hint}.")
