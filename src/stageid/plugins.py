"""Loaders that packages higher up register by name, so lower packages never import them.

A model file names its format (``"stageid.hysteresis/1"``) and, for hysteresis files, its
kind (``"piezo-actuator"``); the loader for it may live in a package above the one that reads
the file (``stageid.plants`` above ``stageid.hysteresis`` above ``stageid.models``).  Such
loaders are declared as package entry points in ``pyproject.toml`` — the groups
:data:`MODEL_FORMATS` and :data:`HYSTERESIS_KINDS`, value ``"module:attribute"`` — and are
imported only when a file of that format or kind is read.  Another installed package can add
its own formats the same way.
"""

from __future__ import annotations

import importlib
from functools import cache
from typing import Any

__all__ = ["MODEL_FORMATS", "HYSTERESIS_KINDS", "declared", "load_object"]

#: Entry-point group: model file ``format`` -> ``"module:function"`` building the model from the dict.
MODEL_FORMATS = "stageid.model_formats"
#: Entry-point group: hysteresis file ``kind`` -> ``"module:attribute"`` building the model.
HYSTERESIS_KINDS = "stageid.hysteresis_kinds"


@cache
def declared(group: str) -> dict[str, str]:
    """The ``name -> "module:attribute"`` entries installed packages declare in ``group``."""
    from importlib.metadata import entry_points  # a costly import: only when a file is read

    return {ep.name: ep.value for ep in entry_points(group=group)}


def load_object(spec: str) -> Any:
    """The object ``"package.module:Class.attribute"`` names (the module imported on demand)."""
    module, _, attribute = spec.partition(":")
    obj: Any = importlib.import_module(module)
    for part in attribute.split("."):
        obj = getattr(obj, part)
    return obj
