"""Where numba keeps the compiled kernels: somewhere writable, or nowhere.

Every kernel of stageid is compiled with ``cache=True``.  numba stores the machine code next
to the source (``__pycache__``) or in the user's cache folder (``~/.cache/numba``); when
neither is writable — a system-wide install used by another user, a read-only container — it
refuses to define the kernel at all ("cannot cache function ...: no locator available").

:func:`configure` runs once when :mod:`stageid` is imported, before any kernel is defined:

1. ``NUMBA_CACHE_DIR`` set by the user, or a writable package folder or user cache: nothing
   to do (numba's own choice);
2. otherwise a private folder in the system's temporary directory, if it can be written;
3. otherwise kernels compile on every run, uncached: numba's dispatcher is told to use its
   null cache when no location is found, instead of failing.

Nothing is printed in any case.  The check costs one temporary file per import.
"""

from __future__ import annotations

import os
import sys
import tempfile

__all__ = ["configure", "writable"]

_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))


def writable(folder: str) -> bool:
    """True when ``folder`` exists or can be made, and a file can be created in it."""
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def _user_cache() -> str:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "numba")


def _run_uncached_when_no_location() -> None:
    from numba.core import caching, dispatcher

    original = dispatcher.Dispatcher.enable_caching
    if getattr(original, "stageid_fallback", False):
        return

    def enable_caching(self: dispatcher.Dispatcher) -> None:
        try:
            original(self)
        except RuntimeError as exc:
            if "no locator available" not in str(exc):
                raise
            self._cache = caching.NullCache()

    enable_caching.stageid_fallback = True  # type: ignore[attr-defined]
    dispatcher.Dispatcher.enable_caching = enable_caching


def configure() -> str:
    """Make numba's kernel cache work here; return where it goes ("package", "user", a folder, or "none")."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return os.environ["NUMBA_CACHE_DIR"]
    if writable(os.path.join(_PACKAGE_DIR, "__pycache__")):
        return "package"
    if writable(_user_cache()):
        return "user"
    try:
        temp = tempfile.gettempdir()
    except OSError:  # no usable temporary directory at all
        temp = None
    fallback = os.path.join(temp or "", f"stageid-numba-{os.getuid() if hasattr(os, 'getuid') else 0}")
    if temp is not None and writable(fallback):
        os.environ["NUMBA_CACHE_DIR"] = fallback
        if "numba" in sys.modules:  # numba read its configuration already
            sys.modules["numba"].config.CACHE_DIR = fallback
        return fallback
    _run_uncached_when_no_location()
    return "none"
