"""Let glibc keep the fits' freed memory for reuse (private).

The fits allocate and free many numpy temporaries of 0.1-4 MB (normal-equation blocks,
FFT batches, frequency-response stacks).  glibc's malloc returns freed memory at the top of
its heap to the kernel once more than ``M_TRIM_THRESHOLD`` is free there, and serves blocks
above ``M_MMAP_THRESHOLD`` by fresh mappings; both thresholds start at 128 kB and adapt
upwards only after the process frees a large mapped block (to that block's size, at most
32 MB, and twice that for the trim threshold: glibc ``malloc.c``, ``__libc_free``).  Until then
every fit faults the same pages in again, a large share of a short fit's time (measured in
``benchmarks/RESULTS-subspace.md``, "Page faults").

:func:`prime_heap` allocates and frees one untouched 16 MB block at the first fit or table
read (:func:`stageid.data.read_table`) of a process, which moves glibc to the state any
process that has freed a 16 MB array is in (thresholds 16 MB / 32 MB); no page is touched and
nothing else changes.  It does nothing off glibc or when the environment variable
``STAGEID_HEAP_PRIMING`` is ``0``.
"""

from __future__ import annotations

import os
import sys

import numpy as np

__all__ = ["prime_heap"]

PRIME_BYTES = 16 << 20  # <= glibc's DEFAULT_MMAP_THRESHOLD_MAX (32 MB on 64-bit)
_primed = False


def _is_glibc() -> bool:
    try:
        return sys.platform.startswith("linux") and os.confstr("CS_GNU_LIBC_VERSION").startswith("glibc")
    except (ValueError, OSError, AttributeError):
        return False


def prime_heap() -> bool:
    """Once per process: raise glibc's adaptive malloc thresholds (see the module docstring).

    Returns
    -------
    bool
        Whether the block was allocated by this call.
    """
    global _primed
    if _primed:
        return False
    _primed = True
    if os.environ.get("STAGEID_HEAP_PRIMING", "1").strip() == "0" or not _is_glibc():
        return False
    np.empty(PRIME_BYTES, dtype=np.uint8)  # mapped, never touched, freed at once
    return True
