"""Old module paths of moved modules: ``import stageid.frf.frd`` still works after the move.

A module that moved to another package keeps its old dotted path through :data:`MOVED`, one
table for the whole library, instead of a stub file at the old place: a stub would hide the
move from git's rename detection, and it would be a second module object, so
``monkeypatch.setattr(old_module, ...)`` would patch the wrong one.  The finder answers an old
name with the very module object imported under the new name (lazily: nothing moved is
imported until its old name is asked for).  ``CHANGELOG.md`` lists the moves.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
from types import ModuleType

__all__ = ["MOVED", "install"]

# old dotted path -> new dotted path
MOVED: dict[str, str] = {
    "stageid.frf.frd": "stageid.models.frequency_response",
    "stageid.frf.plotting": "stageid.plots.frf",
    "stageid.simd": "stageid.runtime.simd",
    "stageid.numba_cache": "stageid.runtime.numba_cache",
    "stageid._threads": "stageid.runtime.threads",
    "stageid._heap": "stageid.runtime.heap",
    "stageid.resources": "stageid.runtime.resources",
    "stageid.cluster": "stageid.runtime.cluster",
    "stageid.subspace.unroll": "stageid.runtime.unroll",
}


class _MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds an old path in :data:`MOVED` and loads it as the module at its new path."""

    def find_spec(self, name: str, path: object = None, target: object = None) -> importlib.machinery.ModuleSpec | None:
        if name not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(name, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        module = importlib.import_module(MOVED[spec.name])
        # the import system sets __spec__ to this alias spec next; keep the real one to put back
        spec.loader_state = module.__spec__
        return module

    def exec_module(self, module: ModuleType) -> None:
        # the real spec back: relative imports inside the module compare it with __package__
        module.__spec__ = module.__spec__.loader_state


def install() -> None:
    """Put the finder first on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _MovedModules) for f in sys.meta_path):
        sys.meta_path.insert(0, _MovedModules())
