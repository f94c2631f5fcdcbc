"""Reference stages from the papers, used as ground truth in simulation.

Each module describes one stage and cites its equations. A plant module exposes

- ``model()`` returning the reference model (LTI or hysteresis model object), and
- ``EXPERIMENTS``: a dict mapping an experiment name to a function ``f(seed: int = 0)``
  returning a :class:`~stageid.data.Experiment` (or a :class:`~stageid.data.io.Table` for
  closed-loop records holding references, plant inputs and outputs); ``seed`` must be an
  integer >= 0, anything else raises :class:`~stageid.SignalError`.

``PLANTS`` maps the names used by ``stageid plants NAME`` to their modules.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from .._errors import SignalError, StageIdError
from ..checks import check_seed

PLANTS: dict[str, str] = {
    "p558": "stageid.plants.piezo_stage",
    "maglev": "stageid.plants.maglev",
    "piezo-actuator": "stageid.plants.piezo_actuator",
}


def plant_module(name: str) -> ModuleType:
    """The module of reference stage ``name`` (one of ``PLANTS``)."""
    if name not in PLANTS:
        raise StageIdError(f"unknown plant {name!r}; expected one of {', '.join(PLANTS)}.")
    return importlib.import_module(PLANTS[name])


def experiment_seed(seed: object, experiment: str) -> int:
    """``seed`` of plant experiment ``experiment`` as an int: an integer >= 0, else SignalError.

    The rule of :func:`stageid.checks.check_seed`, without a ``numpy.random.Generator`` (a
    plant record is reproducible from its integer seed alone) and without ``None``.
    """
    return check_seed(
        seed, "seed", f"plant experiment '{experiment}'", allow_generator=False, allow_none=False, error=SignalError
    )


def noise_entropy(seed: int, experiment: str) -> list[int]:
    """The entropy of an experiment's measurement noise (for ``numpy.random.default_rng``): its
    seed and its name, so that the experiments of one seed never share a noise sequence (pooled
    records with one noise would make a true model fail the residual tests)."""
    import zlib

    return [seed, zlib.crc32(experiment.encode())]


__all__ = ["PLANTS", "plant_module", "experiment_seed", "noise_entropy"]
