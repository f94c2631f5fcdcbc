"""A package's names loaded on first use (PEP 562), so that a command does not pay at start-up
for the modules behind names it never touches."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_names"]


def lazy_names(package: str, where: Mapping[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """A module ``__getattr__`` and ``__dir__`` for ``package``: name ``n`` is imported from module
    ``where[n]`` (relative to the package) when first asked for, and kept in the package's
    namespace; ``dir()`` lists the names before they are loaded.

    Examples
    --------
    >>> import stageid.models as models
    >>> models.c2d.__module__
    'stageid.models.discretization'
    >>> "save_model" in dir(models)
    True
    """

    def __getattr__(name: str) -> Any:
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(where[name], package), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted({*vars(sys.modules[package]), *where})

    return __getattr__, __dir__
