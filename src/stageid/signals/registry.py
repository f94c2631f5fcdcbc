"""Registry of signal kinds for the ``stageid signal KIND`` command.

``SIGNAL_KINDS`` maps the kebab-case kind names to the generator functions, and
:func:`generate` calls one by name with keyword parameters, checking the kind and the
parameter names first so that a command line gets one clear error line.
"""

from __future__ import annotations

import inspect
import typing
from collections.abc import Callable
from typing import Any

import numpy as np

from .._errors import SignalError
from .hysteresis import decaying_sine, decaying_triangle, forc_staircase
from .multisine import multisine
from .periodic import sine, triangle
from .random import band_limited_random, prbs
from .sweeps import chirp, log_chirp

__all__ = ["SIGNAL_KINDS", "generate", "signal_parameters"]

#: Kind name (kebab-case) -> generator.  The closed set accepted by :func:`generate`.
SIGNAL_KINDS: dict[str, Callable[..., np.ndarray]] = {
    "chirp": chirp,
    "log-chirp": log_chirp,
    "prbs": prbs,
    "random": band_limited_random,
    "multisine": multisine,
    "sine": sine,
    "triangle": triangle,
    "decaying-sine": decaying_sine,
    "decaying-triangle": decaying_triangle,
    "forc": forc_staircase,
}


def _lookup(kind: Any) -> Callable[..., np.ndarray]:
    if not isinstance(kind, str) or kind not in SIGNAL_KINDS:
        choices = ", ".join(SIGNAL_KINDS)
        raise SignalError(f"signal kind must be one of {choices}; got {kind!r}.")
    return SIGNAL_KINDS[kind]


def signal_parameters(kind: str) -> dict[str, inspect.Parameter]:
    """Parameters of the generator of ``kind``, in signature order.

    A command line can build its options from this: a parameter whose ``default`` is
    ``inspect.Parameter.empty`` is required.

    Parameters
    ----------
    kind : str
        One of the keys of :data:`SIGNAL_KINDS`.

    Returns
    -------
    dict of str to inspect.Parameter
        Parameter name -> parameter with its ``default`` and its ``annotation`` resolved
        to a type object (``float``, ``int | None``, ``tuple[float, float] | None``...).

    Raises
    ------
    SignalError
        If ``kind`` is unknown.

    Examples
    --------
    >>> from stageid.signals import signal_parameters
    >>> params = signal_parameters("sine")
    >>> list(params)
    ['freq', 'duration', 'dt', 'amplitude', 'offset', 'phase', 'limits']
    >>> params["freq"].annotation, params["amplitude"].default
    (<class 'float'>, 1.0)
    """
    func = _lookup(kind)
    hints = typing.get_type_hints(func)
    return {
        name: p.replace(annotation=hints.get(name, p.annotation))
        for name, p in inspect.signature(func).parameters.items()
    }


def generate(kind: str, /, **params: Any) -> np.ndarray:
    """Generate a signal of the named ``kind`` with keyword ``params``.

    Parameters
    ----------
    kind : str
        One of ``"chirp"``, ``"log-chirp"``, ``"prbs"``, ``"random"``,
        ``"multisine"``, ``"sine"``, ``"triangle"``, ``"decaying-sine"``,
        ``"decaying-triangle"``, ``"forc"`` (the keys of :data:`SIGNAL_KINDS`).
    **params
        Keyword arguments of the generator (see its docstring); ``kind`` is
        positional-only, so ``generate("multisine", ..., kind="schroeder")`` passes the
        multisine's own ``kind``.

    Returns
    -------
    ndarray of shape (n_samples,) or (n_samples, n_channels)
        What the generator returns.

    Raises
    ------
    SignalError
        If ``kind`` is unknown (the message lists the choices), a parameter name is
        unknown or a required one is missing (the message lists the accepted ones), or
        the generator rejects a value.

    Examples
    --------
    >>> from stageid.signals import generate
    >>> generate("sine", freq=1.0, duration=1.0, dt=0.25).round(6).tolist()
    [0.0, 1.0, 0.0, -1.0]
    >>> generate("square", freq=1.0)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    stageid._errors.SignalError: signal kind must be one of chirp, log-chirp, ..., forc; got 'square'.
    """
    func = _lookup(kind)
    sig = inspect.signature(func)
    accepted = list(sig.parameters)
    unknown = [p for p in params if p not in sig.parameters]
    if unknown:
        raise SignalError(
            f"signal {kind!r} accepts parameters {', '.join(accepted)}; got unknown {', '.join(unknown)}."
        )
    missing = [p.name for p in sig.parameters.values() if p.default is inspect.Parameter.empty and p.name not in params]
    if missing:
        raise SignalError(
            f"signal {kind!r} requires parameters "
            f"{', '.join(p for p in accepted if sig.parameters[p].default is inspect.Parameter.empty)}; "
            f"got no {', '.join(missing)}."
        )
    return func(**params)
