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
import importlib.machinery
import sys
from types import ModuleType

__all__ = ["MOVED", "install_moved_paths"]

# old dotted path -> new dotted path
MOVED: dict[str, str] = {
    "stageid.frf.frd": "stageid.models.frequency_response",
    "stageid.frf.plotting": "stageid.plots.frf",
    "stageid.plots._style": "stageid.plots.style",
    "stageid.simd": "stageid.runtime.simd",
    "stageid.numba_cache": "stageid.runtime.numba_cache",
    "stageid._threads": "stageid.runtime.threads",
    "stageid._heap": "stageid.runtime.heap",
    "stageid.resources": "stageid.runtime.resources",
    "stageid.cluster": "stageid.runtime.cluster",
    "stageid.subspace.unroll": "stageid.runtime.unroll",
    "stageid.hysteresis.serialization": "stageid.hysteresis.models.serialization",
    "stageid.hysteresis.operators": "stageid.hysteresis.models.operators",
    "stageid.hysteresis.common": "stageid.hysteresis.models.common",
    "stageid.hysteresis.pi": "stageid.hysteresis.models.pi",
    "stageid.hysteresis.creep": "stageid.hysteresis.models.creep",
    "stageid.hysteresis.preisach": "stageid.hysteresis.models.preisach",
    "stageid.hysteresis.identification": "stageid.hysteresis.identify.pi",
    "stageid.hysteresis.weights": "stageid.hysteresis.identify.weights",
    "stageid.hysteresis.threshold_search": "stageid.hysteresis.identify.threshold_search",
    "stageid.hysteresis.records": "stageid.hysteresis.identify.records",
    "stageid.hysteresis.preisach_identification": "stageid.hysteresis.identify.preisach",
    "stageid.hysteresis.weight_uncertainty": "stageid.hysteresis.identify.weight_uncertainty",
    "stageid.hysteresis.closed_form": "stageid.hysteresis.inverse.closed_form",
    "stageid.hysteresis.compensator": "stageid.hysteresis.inverse.compensator",
    "stageid.hysteresis.preisach_inverse": "stageid.hysteresis.inverse.preisach",
    "stageid.hysteresis.stage_identification": "stageid.hysteresis.stage.identification",
    "stageid.hysteresis.stage_inverse": "stageid.hysteresis.stage.inverse",
    "stageid.hysteresis.stage_problem": "stageid.hysteresis.stage.problem",
    "stageid.hysteresis.stage_preisach": "stageid.hysteresis.stage.preisach",
    "stageid.hysteresis.stage_selection": "stageid.hysteresis.stage.selection",
    "stageid.hysteresis.stage_validation": "stageid.hysteresis.stage.validation",
    "stageid.hysteresis.dynamics": "stageid.hysteresis.stage.dynamics",
    "stageid.hysteresis.disturbance_modes": "stageid.hysteresis.stage.disturbance_modes",
    "stageid.subspace.hankel_toeplitz": "stageid.subspace.statistics.hankel_toeplitz",
    "stageid.subspace.correlations": "stageid.subspace.statistics.correlations",
    "stageid.subspace.window_covariance": "stageid.subspace.statistics.window_covariance",
    "stageid.subspace.chunked_statistics": "stageid.subspace.statistics.chunked_statistics",
    "stageid.subspace.map_estimator": "stageid.subspace.map.posterior",
    "stageid.subspace.recursion": "stageid.subspace.map.recursion",
    "stageid.subspace.map_kernels": "stageid.subspace.map.kernels",
    "stageid.subspace.realization": "stageid.subspace.realisation.era",
    "stageid.subspace.frequency_domain": "stageid.subspace.realisation.frequency_domain",
    "stageid.subspace.refinement": "stageid.subspace.realisation.refinement",
    "stageid.subspace.weighting": "stageid.subspace.realisation.weighting",
    "stageid.subspace.theta_response": "stageid.subspace.statistics.theta_response",
    "stageid.subspace.chunked_order": "stageid.subspace.selection.chunked_order",
    "stageid.subspace.nested_horizons": "stageid.subspace.selection.nested_horizons",
    "stageid.subspace.covariance_grid": "stageid.subspace.uncertainty.grid_placement",
    "stageid.subspace.realisation_bias": "stageid.subspace.uncertainty.realisation_bias",
    "stageid.subspace.chunked_fit": "stageid.subspace.chunked_source",
}


class _MovedModules:
    """Finds an old path in :data:`MOVED` and loads it as the module at its new path.

    A finder and loader by its methods alone: subclassing ``importlib.abc``'s bases would pull
    ``importlib.resources`` (and tempfile, zipfile...) into every command's start-up.
    """

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


def install_moved_paths() -> None:
    """Put the finder first on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _MovedModules) for f in sys.meta_path):
        sys.meta_path.insert(0, _MovedModules())
