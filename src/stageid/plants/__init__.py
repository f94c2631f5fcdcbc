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
import numbers
from types import ModuleType

from .._errors import SignalError, StageIdError

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


def _check_seed(seed: object, experiment: str) -> int:
    """``seed`` as an int, or SignalError unless it is an integer >= 0.

    The experiment functions seed their excitation and noise with it (the CLI's
    ``--seed`` is ``IntRange(min=0)``); the same rule and message shape as
    :func:`stageid.signals` seeds, but a ``numpy.random.Generator`` is not accepted:
    a plant record is reproducible from its integer seed alone.
    """
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise SignalError(f"`seed` of plant experiment '{experiment}' must be an integer >= 0; got {seed!r}.")
    return int(seed)


__all__ = ["PLANTS", "plant_module"]
